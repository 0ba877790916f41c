//! `stability`: the numerical extremes, each rendered by Bevy with the plugin
//! (16-layer fins unless the case says otherwise, or another of its methods:
//! coverage, convolution, plateaus) and read back. Per case:
//! NaN/Inf and out-of-range counts over the whole visibility buffer, and the
//! error against the ground truth over the scored pixels (hit surfaces the
//! light's centre faces).

use bevy::{
    asset::RenderAssetUsages,
    mesh::{Indices, Mesh as BevyMesh, PrimitiveTopology},
    prelude::Vec3,
};
use bevy_shadow_fins::{FinMethod, FinShadowSettings};
use shadow_fins::{
    camera::Camera as CoreCamera,
    coverage::{CoverageModel, CoverageSettings, DEPTH_LIST_LENGTH, ReferenceCount},
    glam::Affine3A,
    light::{DiskLight, Light, SunLight},
    mesh::Mesh,
    metrics::ErrorMetrics,
    oracle::{FinSettings, FinShadowModel, Method, Receiver},
    peers::{
        PlateauModel,
        convolution::{ConvolutionModel, ConvolutionSettings},
    },
    scene::{LightSpaceScene, Scene, SceneObject},
    scenes::SceneId,
    shapes,
};
use shadow_fins_lab::{
    eval::camera_receivers,
    results::{cell, percent},
    setup::Measured,
};

use crate::harness::{Session, Setup};

/// One extreme.
pub struct Case {
    pub name: &'static str,
    /// What is extreme about it, for the report.
    pub what: String,
    pub kind: CaseKind,
}

pub enum CaseKind {
    /// Rendered by Bevy with the plugin.
    Rendered(Box<Setup>),
    /// Receivers the plugin cannot be given (it puts the reference plane at
    /// the deepest receiver it sees), so the CPU oracle evaluates them: the
    /// GPU runs the same formulas.
    Oracle { scene: Scene, light: Light, receivers: Vec<Receiver> },
}

/// What one case measured.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub name: &'static str,
    pub what: String,
    /// Values checked (the whole visibility buffer, or the oracle's receivers).
    pub values: usize,
    pub non_finite: usize,
    pub out_of_range: usize,
    /// Against the ground truth over the scored pixels.
    pub metrics: Option<ErrorMetrics>,
    /// Silhouettes, fins, layers the plugin modelled.
    pub modelled: Option<(usize, usize, usize)>,
    /// A render that failed (no adapter, no read-back).
    pub error: Option<String>,
}

const SIZE: (u32, u32) = (128, 96);

/// A built-in scene at the stability resolution, 16-layer fins on 512² maps.
fn setup_of(id: SceneId) -> Setup {
    let b = id.build();
    Setup::new(b.scene, b.light, b.camera, FinShadowSettings { map_resolution: 512, ..Default::default() }, SIZE)
}

fn base() -> Setup {
    setup_of(SceneId::BoxOverPlane)
}

fn disk(setup: &Setup) -> DiskLight {
    match setup.light {
        Light::Disk(d) => d,
        Light::Rect(_) | Light::Sun(_) | Light::Sphere(_) => unreachable!("the stability scenes are lit by disks"),
    }
}

fn object(name: &str, mesh: Mesh, at: Vec3) -> SceneObject {
    SceneObject::new(name, mesh, Affine3A::from_translation(at)).expect("finite translation")
}

/// The box of box-over-plane moved to height `bottom` above the ground.
fn box_at(bottom: f32) -> Setup {
    let mut s = base();
    s.scene.objects[1].transform = Affine3A::from_translation(Vec3::new(0.0, bottom + 0.5, 0.0));
    s
}

fn rendered(name: &'static str, what: impl Into<String>, setup: Setup) -> Case {
    Case { name, what: what.into(), kind: CaseKind::Rendered(Box::new(setup)) }
}

/// Every case, in report order.
pub fn cases() -> Vec<Case> {
    let extent = {
        let (lo, hi) = base().scene.bounds().expect("non-empty");
        (hi - lo).length()
    };
    let mut out = vec![];
    let mut s = base();
    s.light = Light::Disk(DiskLight { radius: 0.0, ..disk(&s) });
    out.push(rendered("radius-0", "light radius 0: must be the hard shadow", s));
    let mut s = base();
    s.light = Light::Disk(DiskLight { radius: 1e-5, ..disk(&s) });
    out.push(rendered("radius-1e-5", "light radius 1e-5", s));
    let mut s = base();
    s.light = Light::Disk(DiskLight { radius: 100.0 * extent, ..disk(&s) });
    out.push(rendered(
        "radius-100x-scene",
        format!("light radius {:.0} = 100× the scene's diagonal", 100.0 * extent),
        s,
    ));
    out.push(rendered("touching", "box resting on the ground (contact: Br → 0)", box_at(0.0)));
    out.push(rendered("nearly-touching", "box 1e-4 above the ground", box_at(1e-4)));

    let mut s = base();
    s.scene.objects[0] = object("ground", shapes::plane(2e6, 4), Vec3::ZERO);
    s.far = Some(1e6);
    out.push(rendered("far-plane-1e6", "ground 2e6 wide, camera far plane 1e6", s));

    let offset = Vec3::splat(1e5);
    let mut s = base();
    s.scene = s.scene.translated(offset);
    s.light = Light::Disk(DiskLight { center: disk(&s).center + offset, ..disk(&s) });
    s.camera = CoreCamera { position: s.camera.position + offset, target: s.camera.target + offset, ..s.camera };
    out.push(rendered("offset-1e5", "every coordinate offset by (1e5, 1e5, 1e5)", s));

    let k = 1e-4;
    let mut s = base();
    for o in &mut s.scene.objects {
        o.transform = Affine3A::from_scale(Vec3::splat(k)) * o.transform;
    }
    let d = disk(&s);
    s.light = Light::Disk(DiskLight { center: d.center * k, radius: d.radius * k, ..d });
    s.camera = CoreCamera { position: s.camera.position * k, target: s.camera.target * k, ..s.camera };
    s.near = Some(1e-6);
    s.far = Some(1.0);
    out.push(rendered("scale-1e-4", "the whole scene scaled by 1e-4 (camera near plane 1e-6)", s));

    for layers in [1, 64] {
        let mut s = setup_of(SceneId::SphereGrid);
        s.settings.layers = layers;
        let name = if layers == 1 { "layers-1" } else { "layers-64" };
        let what = format!("sphere grid, {layers} layers (effective {})", s.settings.clamped().layers);
        out.push(rendered(name, what, s));
    }
    let mut s = setup_of(SceneId::SphereGrid);
    s.settings.sub_layers = 1;
    out.push(rendered("one-sub-layer", "sphere grid, 1 sub-layer: every silhouette in it", s));

    let mut s = base();
    // Zero-area slivers, a repeated triangle and a collapsed vertex on a box.
    let cube = shapes::cuboid(Vec3::splat(0.3));
    let mut positions = cube.positions().to_vec();
    let mut indices = cube.indices().to_vec();
    let n = positions.len() as u32;
    positions.extend([Vec3::new(-0.3, 0.31, 0.0), Vec3::new(0.0, 0.31, 0.0), Vec3::new(0.3, 0.31, 0.0)]);
    indices.extend([n, n + 1, n + 2, 0, 1, 2, 0, 1, 2, 0, 0, 1]);
    let degenerate = Mesh::new(positions, indices).expect("valid with some degenerate triangles");
    s.scene.objects.push(object("degenerate", degenerate, Vec3::new(1.5, 1.2, 0.5)));
    out.push(rendered("degenerate-mesh", "a box with zero-area, repeated and collapsed triangles", s));

    let mut s = base();
    // Three quads ("pages") sharing one edge: an edge with three faces.
    let spine = [Vec3::new(0.0, 0.0, -0.4), Vec3::new(0.0, 0.0, 0.4)];
    let mut positions = spine.to_vec();
    let mut indices = vec![];
    for (i, angle) in [0.3f32, 1.6, 2.8].into_iter().enumerate() {
        let out = Vec3::new(angle.cos(), angle.sin(), 0.0) * 0.6;
        positions.extend([spine[0] + out, spine[1] + out]);
        let (a, b) = (2 + 2 * i as u32, 3 + 2 * i as u32);
        indices.extend([0, 1, b, 0, b, a]);
    }
    let book = Mesh::new(positions, indices).expect("valid non-manifold mesh");
    s.scene.objects.push(object("book", book, Vec3::new(-1.6, 1.0, 0.8)));
    out.push(rendered("non-manifold-mesh", "three faces on one edge, boundary edges", s));

    let mut s = base();
    let mesh = |positions: Vec<[f32; 3]>, indices: Vec<u32>| {
        BevyMesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default())
            .with_inserted_attribute(BevyMesh::ATTRIBUTE_POSITION, positions)
            .with_inserted_indices(Indices::U32(indices))
    };
    s.extra_meshes = vec![
        (mesh(vec![], vec![]), Vec3::new(2.0, 1.0, 0.0)),
        (
            mesh(vec![[f32::NAN, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, f32::INFINITY, 1.0]], vec![0, 1, 2]),
            Vec3::new(-2.0, 1.0, 0.0),
        ),
    ];
    out.push(rendered(
        "nan-and-empty-meshes",
        "Bevy meshes with NaN/Inf positions and with 0 triangles (not in the truth)",
        s,
    ));

    let mut s = base();
    s.light = Light::Disk(DiskLight { center: Vec3::new(0.0, 1.5, 0.0), ..disk(&s) });
    out.push(rendered("light-inside-caster", "the light's centre inside the box", s));

    // The sun (a `DirectionalLight` with `FinShadows`, orthographic maps).
    let sun = |direction: Vec3, angle: f32| {
        let direction = direction.normalize();
        Light::Sun(SunLight::new(direction, angle).expect("a valid sun"))
    };
    let slanted = Vec3::new(0.3, -1.0, 0.2);
    let mut s = base();
    s.light = sun(slanted, 0.0);
    out.push(rendered("sun-0", "the sun at θ = 0: must be the hard shadow", s));
    let mut s = base();
    s.light = sun(slanted, 1.4);
    out.push(rendered("sun-80deg", "the sun 80° wide (θ = 1.4 rad, the most there is)", s));
    let mut s = base();
    s.light = sun(Vec3::new(1.0, -0.035, 0.1), 0.05);
    out.push(rendered(
        "sun-grazing",
        "the sun 2° above the horizon: the ground lit at a glancing angle (its shadows fall out of view; no acne)",
        s,
    ));
    let mut s = base();
    s.scene = s.scene.translated(offset);
    s.camera = CoreCamera { position: s.camera.position + offset, target: s.camera.target + offset, ..s.camera };
    s.light = sun(slanted, 0.1);
    out.push(rendered("sun-offset-1e5", "the sun over the scene offset by (1e5, 1e5, 1e5)", s));
    for (name, size) in [("sun-ground-2e4", 2e4f32), ("sun-ground-2e6", 2e6)] {
        let mut s = base();
        s.scene.objects[0] = object("ground", shapes::plane(size, 4), Vec3::ZERO);
        s.far = Some(size);
        s.light = sun(slanted, 0.1);
        let what =
            format!("the sun over a ground {size:.0e} wide, camera far plane {size:.0e} (maps fitted to the view)");
        out.push(rendered(name, what, s));
    }

    // Receivers 1.5×, 10× and 1000× deeper than the reference plane, in the
    // box's shadow; without the ground, which would put them in its umbra.
    let mut s = base();
    s.scene.objects.retain(|o| o.name != "ground");
    let ls = LightSpaceScene::new(&s.scene, s.light);
    let l0 = ls.reference_depth;
    let mut receivers = vec![];
    for depth in [1.5f32, 10.0, 1000.0] {
        for i in 0..64 {
            let (x, y) = ((i % 8) as f32 / 7.0 - 0.5, (i / 8) as f32 / 7.0 - 0.5);
            let d = depth * l0;
            let p = Vec3::new(x * d * 0.6, y * d * 0.6, d);
            receivers.push(Receiver { position: p, normal: Vec3::NEG_Z });
        }
    }
    out.push(Case {
        name: "receiver-beyond-reference",
        what: format!("receivers at 1.5, 10 and 1000 × L0 = {l0:.2} (CPU oracle, light frame)"),
        kind: CaseKind::Oracle { scene: s.scene, light: s.light, receivers },
    });
    out
}

/// The scene as the ground truth traces it. A sun's core frame puts its origin
/// in front of the whole scene, so over a ground 2e6 wide every point lies
/// ~1.4e6 from it and the truth's receiver lift (1e-5 of that) is 14 units:
/// the truth itself read every pixel lit. Its rays need no positive depths,
/// so the truth of a sun works in a frame at the camera's target instead.
fn truth_frame(setup: &Setup) -> LightSpaceScene {
    match setup.light {
        Light::Sun(sun) => {
            let frame = shadow_fins::light::LightFrame::sun_at(&sun, setup.camera.target.as_dvec3());
            let extent = setup.scene.bounds().map_or(1.0, |(lo, hi)| (hi - lo).length());
            LightSpaceScene::in_frame(&setup.scene, setup.light, frame, extent)
        }
        Light::Disk(_) | Light::Rect(_) | Light::Sphere(_) => LightSpaceScene::new(&setup.scene, setup.light),
    }
}

/// The plugin's methods `stability` runs: the case's own fins, or another.
pub const METHODS: [(&str, Option<FinMethod>); 4] = [
    ("fins", None),
    ("coverage", Some(FinMethod::Coverage)),
    ("convolution", Some(FinMethod::Convolution)),
    ("plateaus", Some(FinMethod::Plateaus)),
];

/// Runs one case with `samples` ground-truth samples (0: no truth), by the
/// fins (`None`: the case's own settings) or another of the plugin's methods
/// (coverage: 256 light samples, depth lists at the case's map size, its row
/// showing potential silhouette edges / 0 / 0). The oracle cases run the
/// core's model of that method (convolution: the CPU peer, summed-area
/// tables; plateaus: the CPU peer; any other method: the fins' oracle, so
/// pass one of [`METHODS`]).
pub fn run(case: &Case, samples: u32, method: Option<FinMethod>) -> Outcome {
    let mut outcome = Outcome {
        name: case.name,
        what: case.what.clone(),
        values: 0,
        non_finite: 0,
        out_of_range: 0,
        metrics: None,
        modelled: None,
        error: None,
    };
    let count = |values: &[f32], o: &mut Outcome| {
        o.values = values.len();
        o.non_finite = values.iter().filter(|v| !v.is_finite()).count();
        o.out_of_range = values.iter().filter(|v| **v < -1e-4 || **v > 1.0 + 1e-4).count();
    };
    match &case.kind {
        CaseKind::Rendered(setup) => {
            let mut setup = setup.clone();
            if let Some(m) = method {
                setup.settings.method = m;
            }
            let setup = &setup;
            let shot = match Session::new(setup).settle(6) {
                Ok(s) => s,
                Err(e) => {
                    outcome.error = Some(e);
                    return outcome;
                }
            };
            count(&shot.visibility, &mut outcome);
            outcome.modelled = Some((shot.stats.silhouettes, shot.stats.fins, shot.stats.layers));
            if samples > 0 {
                let ls = truth_frame(setup);
                let receivers = camera_receivers(&setup.camera, setup.width, setup.height, &ls);
                let (mut method, mut hits) = (vec![], vec![]);
                for (i, r) in receivers.iter().enumerate() {
                    if let Some(r) = r.filter(|r| r.faces_light(&ls.frame)) {
                        method.push(shot.visibility[i]);
                        hits.push(r);
                    }
                }
                let truth = shadow_fins_lab::eval::evaluate(
                    &setup.scene,
                    &ls,
                    Measured::GroundTruth,
                    FinSettings::default(),
                    None,
                    samples,
                    &hits,
                );
                outcome.metrics = Some(ErrorMetrics::compute(&method, &truth.values));
            }
        }
        CaseKind::Oracle { scene, light, receivers } => {
            let mut ls = LightSpaceScene::new(scene, *light);
            // The plugin's L0 covers every surface it draws; given points must be covered too.
            ls.cover_receivers(receivers.iter().map(|r| r.position));
            let values: Vec<f32> = match method {
                Some(FinMethod::Coverage) => {
                    let reference = ReferenceCount::Raster { resolution: 512, depths: DEPTH_LIST_LENGTH };
                    let model = CoverageModel::new(scene, &ls, CoverageSettings { reference, ..Default::default() });
                    outcome.modelled = Some((model.edges.len(), 0, 0));
                    receivers.iter().map(|r| model.visibility(*r)).collect()
                }
                Some(FinMethod::Convolution) => {
                    let model = ConvolutionModel::new(&ls, ConvolutionSettings::default());
                    receivers.iter().map(|r| model.visibility(*r)).collect()
                }
                Some(FinMethod::Plateaus) => {
                    let model = PlateauModel::new(scene, &ls);
                    outcome.modelled = Some((model.sheet_count(), 0, 0));
                    receivers.iter().map(|r| model.visibility(*r)).collect()
                }
                _ => {
                    let model = FinShadowModel::new(scene, &ls, Method::MultiLayer, FinSettings::default());
                    let maps = model.raster(512);
                    outcome.modelled = Some((model.silhouettes.len(), model.fins.len(), model.plan.len()));
                    receivers.iter().map(|r| maps.visibility(*r)).collect()
                }
            };
            count(&values, &mut outcome);
            if samples > 0 {
                let gt = shadow_fins::ground_truth::GroundTruth::new(&ls, samples);
                let truth: Vec<f32> = receivers.iter().map(|r| gt.visibility(*r)).collect();
                outcome.metrics = Some(ErrorMetrics::compute(&values, &truth));
            }
        }
    }
    outcome
}

/// The report table.
pub fn markdown(outcomes: &[Outcome]) -> String {
    let mut s = String::from(
        "| case | what | values | NaN/Inf | out of [0,1] | scored px | MAE | p99 | umbra over | leak | silhouettes / fins / layers |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for o in outcomes {
        let m = o.metrics;
        let modelled = o.modelled.map_or("–".into(), |(a, b, c)| format!("{a} / {b} / {c}"));
        let what = match &o.error {
            Some(e) => format!("{} — **failed: {e}**", o.what),
            None => o.what.clone(),
        };
        s += &format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
            o.name,
            what,
            o.values,
            o.non_finite,
            o.out_of_range,
            m.map_or("–".into(), |m| m.count.to_string()),
            cell(m.map(|m| m.mae), 4),
            cell(m.map(|m| m.p99), 4),
            percent(m.map(|m| m.umbra_over)),
            percent(m.map(|m| m.leak)),
            modelled
        );
    }
    s
}
