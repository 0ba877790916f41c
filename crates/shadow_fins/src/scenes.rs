//! Built-in procedural scenes that mirror the paper's figures.

use glam::{Affine3A, Quat, Vec3};

use crate::{
    camera::Camera,
    light::{DiskLight, Light, SphereLight},
    mesh::Mesh,
    scene::{Scene, SceneObject},
    shapes,
};

/// A scene with the light and camera it is meant to be seen with.
#[derive(Debug, Clone)]
pub struct BuiltinScene {
    pub id: SceneId,
    pub scene: Scene,
    pub light: Light,
    pub camera: Camera,
}

/// A light and a camera for an arbitrary scene (an imported glTF): the light
/// and camera of [`crate::default_view::default_view_of`], which finds the
/// subject without its ground, sees a room from inside and scales with the
/// scene; use that for the light's power distance and the clip planes.
/// `None` for an empty scene.
pub fn default_view(scene: &Scene) -> Option<(Light, Camera)> {
    crate::default_view::default_view_of(scene).map(|view| (view.light, view.camera))
}

/// The built-in scenes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SceneId {
    /// A box above a ground plane: the basic case.
    BoxOverPlane,
    /// Two boxes almost touching each other and the ground (paper fig. 10).
    NearContact,
    /// A ring above a plate above the ground (fig. 7): needs more than one layer.
    RingPlate,
    /// A light much larger than its occluder (fig. 8): no umbra at all.
    LargeLight,
    /// A box over a receiver tilted 25° (fig. 9).
    TiltedReceiver,
    /// A five-pointed star prism with sharp silhouette angles (fig. 13).
    StarPrism,
    /// A 4×4 grid of spheres: overlapping penumbrae.
    SphereGrid,
    /// A ≥100k-triangle bumpy blob over the ground: scaling.
    DenseBlob,
    /// The demo: the hard cases together under one large light — boxes in near
    /// contact, a ramp (tilted receiver), spheres with overlapping penumbrae, a
    /// ring over a star prism. Exported as `assets/demo.gltf`.
    Demo,
    /// Like a real asset: interpenetrating closed and open parts — a box
    /// through a sphere, bent open sheets, thin straps through both, a hose of
    /// overlapping rings. Where fins fail: the union's outline is none of the
    /// parts' outlines (occluder fusion). `assets/kitbash.gltf`.
    Kitbash,
    /// A character-like figure of separate overlapping limbs (ellipsoids and
    /// boxes that interpenetrate at every joint), standing on the ground.
    /// `assets/figure.gltf`.
    Figure,
    /// A dense object over the ground under a large light: a tower of 160
    /// small overlapping boxes and balls on a block. `assets/greeble-tower.gltf`.
    GreebleTower,
    /// A room lit by a sphere light (a lamp: Bevy's point light with a
    /// radius) above a table, seen from inside: shadows on the floor and on
    /// two walls, across the cube faces the sphere light is modelled by.
    LampRoom,
    /// Five alpha-masked leaf cards (a leaf with three round holes cut from
    /// a square card by its texture's alpha) standing and tilted over the
    /// ground: light through the holes and around the blade, not the
    /// card's square. `assets/leaf-cards.gltf` in the core's terms.
    LeafCards,
}

impl SceneId {
    pub const ALL: [SceneId; 14] = [
        SceneId::BoxOverPlane,
        SceneId::NearContact,
        SceneId::RingPlate,
        SceneId::LargeLight,
        SceneId::TiltedReceiver,
        SceneId::StarPrism,
        SceneId::SphereGrid,
        SceneId::DenseBlob,
        SceneId::Demo,
        SceneId::Kitbash,
        SceneId::Figure,
        SceneId::GreebleTower,
        SceneId::LampRoom,
        SceneId::LeafCards,
    ];

    /// The scenes lit by a light whose maps are one frame (every light but a
    /// sphere, whose six faces shade receivers in their own frusta): what a
    /// test that evaluates a whole view in one frame can take.
    pub fn single_frame() -> impl Iterator<Item = SceneId> {
        Self::ALL.into_iter().filter(|id| *id != SceneId::LampRoom)
    }

    /// The scenes made to look like real assets (many overlapping parts).
    pub const REAL_ASSET_LIKE: [SceneId; 3] = [SceneId::Kitbash, SceneId::Figure, SceneId::GreebleTower];

    pub fn name(self) -> &'static str {
        match self {
            SceneId::BoxOverPlane => "box-over-plane",
            SceneId::NearContact => "near-contact",
            SceneId::RingPlate => "ring-plate",
            SceneId::LargeLight => "large-light",
            SceneId::TiltedReceiver => "tilted-receiver",
            SceneId::StarPrism => "star-prism",
            SceneId::SphereGrid => "sphere-grid",
            SceneId::DenseBlob => "dense-blob",
            SceneId::Demo => "demo",
            SceneId::Kitbash => "kitbash",
            SceneId::Figure => "figure",
            SceneId::GreebleTower => "greeble-tower",
            SceneId::LampRoom => "lamp-room",
            SceneId::LeafCards => "leaf-cards",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|id| id.name() == s)
    }

    pub fn build(self) -> BuiltinScene {
        build(self)
    }
}

fn object(name: &str, mesh: Mesh, transform: Affine3A) -> SceneObject {
    SceneObject::new(name, mesh, transform).expect("built-in transforms are valid")
}

fn at(p: Vec3) -> Affine3A {
    Affine3A::from_translation(p)
}

fn ground(size: f32) -> SceneObject {
    object("ground", shapes::plane(size, 4), Affine3A::IDENTITY)
}

fn disk(center: Vec3, radius: f32) -> Light {
    Light::Disk(DiskLight::new(center, Vec3::NEG_Y, radius).expect("built-in lights are valid"))
}

fn build(id: SceneId) -> BuiltinScene {
    let cam = Camera::looking_at;
    let (objects, light, camera) = match id {
        SceneId::BoxOverPlane => (
            vec![ground(10.0), object("box", shapes::cuboid(Vec3::splat(0.5)), at(Vec3::new(0.0, 1.5, 0.0)))],
            disk(Vec3::new(0.3, 4.5, 0.2), 0.5),
            cam(Vec3::new(3.0, 4.0, 4.5), Vec3::new(0.0, 0.3, 0.0)),
        ),
        SceneId::NearContact => {
            let half = Vec3::new(0.5, 0.4, 0.5);
            (
                vec![
                    ground(10.0),
                    object("box-a", shapes::cuboid(half), at(Vec3::new(-0.525, 0.41, 0.0))),
                    object("box-b", shapes::cuboid(half), at(Vec3::new(0.525, 0.41, 0.0))),
                ],
                disk(Vec3::new(0.8, 4.0, 0.6), 0.6),
                cam(Vec3::new(-2.5, 3.5, 4.0), Vec3::new(0.0, 0.2, -0.5)),
            )
        }
        SceneId::RingPlate => (
            vec![
                ground(12.0),
                object("plate", shapes::cuboid(Vec3::new(2.1, 0.03, 2.1)), at(Vec3::new(0.0, 1.0, 0.0))),
                object("ring", shapes::torus(1.2, 0.15, 96, 16), at(Vec3::new(0.0, 2.0, 0.0))),
            ],
            disk(Vec3::new(0.0, 5.0, 0.0), 1.0),
            cam(Vec3::new(0.0, 5.5, 4.5), Vec3::new(0.0, 0.8, 0.0)),
        ),
        SceneId::LargeLight => (
            vec![ground(10.0), object("ball", shapes::uv_sphere(0.3, 24, 48), at(Vec3::new(0.0, 1.0, 0.0)))],
            disk(Vec3::new(0.0, 3.0, 0.0), 1.5),
            cam(Vec3::new(0.0, 3.0, 3.5), Vec3::new(0.0, 0.2, 0.0)),
        ),
        SceneId::TiltedReceiver => (
            vec![
                object(
                    "tilted-ground",
                    shapes::plane(8.0, 4),
                    Affine3A::from_rotation_translation(Quat::from_rotation_z(25f32.to_radians()), Vec3::ZERO),
                ),
                object("box", shapes::cuboid(Vec3::new(0.6, 0.3, 0.4)), at(Vec3::new(0.0, 1.6, 0.0))),
            ],
            disk(Vec3::new(0.5, 4.5, 0.0), 0.6),
            cam(Vec3::new(0.0, 4.5, 5.0), Vec3::new(0.0, 0.3, 0.0)),
        ),
        SceneId::StarPrism => (
            vec![ground(10.0), object("star", shapes::star_prism(5, 0.35, 1.2, 0.2), at(Vec3::new(0.0, 1.0, 0.0)))],
            disk(Vec3::new(0.0, 4.0, 0.0), 0.5),
            cam(Vec3::new(0.0, 5.0, 3.5), Vec3::new(0.0, 0.3, 0.0)),
        ),
        SceneId::SphereGrid => {
            let sphere = std::sync::Arc::new(shapes::uv_sphere(0.3, 16, 32));
            let topology = std::sync::Arc::new(crate::mesh::Topology::build(&sphere));
            let mut objects = vec![ground(10.0)];
            for i in 0..4 {
                for j in 0..4 {
                    let p = Vec3::new((i as f32 - 1.5) * 0.75, 1.0, (j as f32 - 1.5) * 0.75);
                    objects.push(
                        SceneObject::shared(format!("sphere-{i}-{j}"), sphere.clone(), topology.clone(), at(p))
                            .expect("valid"),
                    );
                }
            }
            (objects, disk(Vec3::new(0.0, 4.5, 0.0), 0.8), cam(Vec3::new(0.0, 5.0, 4.5), Vec3::new(0.0, 0.0, 0.0)))
        }
        SceneId::DenseBlob => (
            vec![ground(10.0), object("blob", shapes::bumpy_blob(100_000), at(Vec3::new(0.0, 1.5, 0.0)))],
            disk(Vec3::new(0.4, 5.0, 0.0), 0.5),
            cam(Vec3::new(3.0, 4.0, 4.5), Vec3::new(0.0, 0.5, 0.0)),
        ),
        SceneId::Demo => demo(),
        SceneId::Kitbash => kitbash(),
        SceneId::Figure => figure(),
        SceneId::GreebleTower => greeble_tower(),
        SceneId::LampRoom => lamp_room(),
        SceneId::LeafCards => leaf_cards(),
    };
    BuiltinScene { id, scene: Scene::new(objects), light, camera }
}

fn demo() -> (Vec<SceneObject>, Light, Camera) {
    let half = Vec3::new(0.45, 0.35, 0.45);
    let sphere = shapes::uv_sphere(0.35, 16, 32);
    let mut objects = vec![
        ground(12.0),
        object("box-a", shapes::cuboid(half), at(Vec3::new(-2.2 - 0.47, 0.36, 0.6))),
        object("box-b", shapes::cuboid(half), at(Vec3::new(-2.2 + 0.47, 0.36, 0.6))),
        object(
            "ramp",
            shapes::cuboid(Vec3::new(1.3, 0.05, 1.0)),
            Affine3A::from_rotation_translation(Quat::from_rotation_z(-20f32.to_radians()), Vec3::new(2.3, 0.5, 0.8)),
        ),
        object("post", shapes::cuboid(Vec3::new(0.12, 0.6, 0.12)), at(Vec3::new(2.0, 1.6, 0.8))),
        object("ring", shapes::torus(0.7, 0.1, 64, 12), at(Vec3::new(0.0, 1.9, -1.6))),
        object("star", shapes::star_prism(5, 0.25, 0.8, 0.15), at(Vec3::new(0.0, 0.6, -1.6))),
    ];
    for (i, x) in [-0.75f32, 0.0, 0.75].iter().enumerate() {
        objects.push(object(&format!("sphere-{i}"), sphere.clone(), at(Vec3::new(*x, 1.2, 1.6))));
    }
    let camera = Camera::looking_at(Vec3::new(0.5, 6.5, 7.5), Vec3::new(0.0, 0.2, 0.0));
    (objects, disk(Vec3::new(0.2, 5.0, 0.3), 0.8), camera)
}

/// A lamp (a sphere light of radius 0.2) 1.2 above a table, in the corner
/// of two walls: the table, its legs, two stools, a shelf with a ball and a
/// cabinet cast on the floor (−Y face), on the walls (−X, −Z faces) and
/// across the faces' borders.
fn lamp_room() -> (Vec<SceneObject>, Light, Camera) {
    let wall = |name: &str, rotation: Quat, p: Vec3| {
        object(name, shapes::plane(8.0, 4), Affine3A::from_rotation_translation(rotation, p))
    };
    let cuboid = |name: &str, half: Vec3, p: Vec3| object(name, shapes::cuboid(half), at(p));
    let mut objects = vec![
        ground(8.0),
        wall("wall-back", Quat::from_rotation_x(std::f32::consts::FRAC_PI_2), Vec3::new(0.0, 4.0, -4.0)),
        wall("wall-left", Quat::from_rotation_z(-std::f32::consts::FRAC_PI_2), Vec3::new(-4.0, 4.0, 0.0)),
        cuboid("table-top", Vec3::new(0.8, 0.05, 0.5), Vec3::new(0.0, 0.75, 0.0)),
        cuboid("stool-a", Vec3::splat(0.25), Vec3::new(1.6, 0.25, 0.2)),
        cuboid("stool-b", Vec3::splat(0.25), Vec3::new(-2.4, 0.25, 0.9)),
        cuboid("shelf", Vec3::new(0.15, 0.04, 0.8), Vec3::new(-3.8, 1.8, -0.5)),
        object("ball", shapes::uv_sphere(0.2, 12, 24), at(Vec3::new(-3.75, 2.04, -0.3))),
        cuboid("cabinet", Vec3::new(0.5, 1.0, 0.3), Vec3::new(-1.2, 1.0, -2.6)),
    ];
    for (i, (x, z)) in [(-0.7, -0.4), (0.7, -0.4), (-0.7, 0.4), (0.7, 0.4)].into_iter().enumerate() {
        objects.push(cuboid(&format!("leg-{i}"), Vec3::new(0.05, 0.35, 0.05), Vec3::new(x, 0.35, z)));
    }
    let light = Light::Sphere(SphereLight::new(Vec3::new(0.0, 2.0, 0.0), 0.2).expect("a valid lamp"));
    (objects, light, Camera::looking_at(Vec3::new(5.0, 3.6, 5.5), Vec3::new(-1.4, 1.0, -1.6)))
}

/// The cards of `assets/leaf-cards.gltf` (`shadow-fins-lab make-assets`):
/// 0.6 × 0.9 m, their stems at the nodes' translations, turned by the
/// nodes' rotations, the leaf mask at 128² with glTF's default cutoff 0.5.
fn leaf_cards() -> (Vec<SceneObject>, Light, Camera) {
    use crate::cutout::{AlphaMask, Cutout};
    let (card, uvs) = shapes::card(0.6, 0.9);
    let card = std::sync::Arc::new(card);
    let topology = std::sync::Arc::new(crate::mesh::Topology::build(&card));
    let mask = AlphaMask::new(128, 128, shapes::leaf_alpha(128), 1.0, 0.5).expect("the leaf mask is valid");
    let cutout = Cutout::new(std::sync::Arc::new(mask), &uvs, &card, &topology).expect("one UV per corner");
    let mut objects = vec![ground(8.0)];
    let cards: [(Vec3, [f32; 4]); 5] = [
        (Vec3::new(0.0, 0.3, 0.0), [0.0, 0.2, 0.0, 1.0]),
        (Vec3::new(0.7, 0.5, 0.3), [-0.3, 0.5, 0.0, 1.0]),
        (Vec3::new(-0.6, 0.25, 0.5), [0.2, -0.6, 0.1, 1.0]),
        (Vec3::new(0.2, 0.9, -0.6), [-0.6, 0.1, 0.2, 1.0]),
        (Vec3::new(-0.3, 1.2, -0.2), [-0.9, 0.3, 0.0, 1.0]),
    ];
    for (i, (p, q)) in cards.into_iter().enumerate() {
        let rotation = Quat::from_array(q).normalize();
        let mut o = SceneObject::shared(
            format!("card-{i}"),
            card.clone(),
            topology.clone(),
            Affine3A::from_rotation_translation(rotation, p),
        )
        .expect("valid");
        o.cutout = Some(cutout.clone());
        objects.push(o);
    }
    let camera = Camera::looking_at(Vec3::new(2.5, 2.2, 3.5), Vec3::new(0.0, 0.6, 0.0));
    (objects, disk(Vec3::new(0.5, 4.0, 0.6), 0.4), camera)
}

fn placed(p: Vec3, rotation: Quat, scale: Vec3) -> Affine3A {
    Affine3A::from_scale_rotation_translation(scale, rotation, p)
}

fn kitbash() -> (Vec<SceneObject>, Light, Camera) {
    let q = |x: f32, y: f32, z: f32| Quat::from_euler(glam::EulerRot::YXZ, x, y, z);
    let mut objects = vec![
        ground(10.0),
        object(
            "block",
            shapes::cuboid(Vec3::new(0.45, 0.35, 0.4)),
            placed(Vec3::new(-0.2, 1.1, 0.0), q(0.5, 0.2, 0.1), Vec3::ONE),
        ),
        object("ball", shapes::uv_sphere(0.42, 16, 32), at(Vec3::new(0.3, 1.25, 0.15))),
        object(
            "sheet-a",
            shapes::open_sheet(1.4, 0.7, 1.2, 6),
            placed(Vec3::new(-0.6, 1.55, 0.45), q(0.3, -1.1, 0.2), Vec3::ONE),
        ),
        object(
            "sheet-b",
            shapes::open_sheet(0.9, 0.9, -0.8, 5),
            placed(Vec3::new(0.8, 1.0, -0.4), q(-0.7, 0.9, 0.0), Vec3::ONE),
        ),
    ];
    for (i, (p, r)) in [
        (Vec3::new(0.0, 1.2, 0.0), q(0.2, 0.0, 0.3)),
        (Vec3::new(0.1, 1.35, -0.1), q(1.3, 0.1, -0.2)),
        (Vec3::new(-0.3, 1.0, 0.2), q(-0.6, 0.4, 0.1)),
    ]
    .into_iter()
    .enumerate()
    {
        objects.push(object(
            &format!("strap-{i}"),
            shapes::cuboid(Vec3::new(0.95, 0.02, 0.05)),
            placed(p, r, Vec3::ONE),
        ));
    }
    // A hose: rings along an arc, each overlapping the next.
    for i in 0..9 {
        let a = i as f32 * 0.16;
        let p = Vec3::new(-1.2 + 0.9 * a.sin() * 1.6, 0.9 + 0.45 * a, -0.9 + 0.2 * a);
        objects.push(object(
            &format!("hose-{i}"),
            shapes::torus(0.2, 0.06, 24, 8),
            placed(p, q(a * 2.0, 1.2, 0.3), Vec3::ONE),
        ));
    }
    let camera = Camera::looking_at(Vec3::new(2.6, 3.6, 3.4), Vec3::new(0.0, 0.4, 0.0));
    (objects, disk(Vec3::new(0.4, 4.6, 0.3), 0.8), camera)
}

fn figure() -> (Vec<SceneObject>, Light, Camera) {
    let ball = shapes::uv_sphere(1.0, 12, 24);
    let limb = |name: &str, from: Vec3, to: Vec3, thickness: f32| {
        let d = to - from;
        let rotation = Quat::from_rotation_arc(Vec3::Y, d.normalize());
        let scale = Vec3::new(thickness, d.length() * 0.5 + thickness * 0.5, thickness);
        object(name, ball.clone(), placed((from + to) * 0.5, rotation, scale))
    };
    let (hip, neck) = (Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.0, 1.75, 0.0));
    let objects = vec![
        ground(10.0),
        object("torso", shapes::cuboid(Vec3::new(0.24, 0.38, 0.13)), at((hip + neck) * 0.5)),
        object("head", ball.clone(), placed(Vec3::new(0.0, 1.98, 0.02), Quat::IDENTITY, Vec3::new(0.15, 0.18, 0.16))),
        limb("neck", Vec3::new(0.0, 1.7, 0.0), Vec3::new(0.0, 1.86, 0.01), 0.06),
        limb("upper-arm-l", Vec3::new(0.27, 1.68, 0.0), Vec3::new(0.5, 1.4, 0.15), 0.08),
        limb("forearm-l", Vec3::new(0.5, 1.4, 0.15), Vec3::new(0.45, 1.15, 0.45), 0.065),
        object(
            "hand-l",
            shapes::cuboid(Vec3::new(0.05, 0.08, 0.03)),
            placed(Vec3::new(0.44, 1.08, 0.5), Quat::from_rotation_x(0.6), Vec3::ONE),
        ),
        limb("upper-arm-r", Vec3::new(-0.27, 1.68, 0.0), Vec3::new(-0.45, 1.35, -0.1), 0.08),
        limb("forearm-r", Vec3::new(-0.45, 1.35, -0.1), Vec3::new(-0.62, 1.1, 0.1), 0.065),
        limb("thigh-l", Vec3::new(0.12, 1.02, 0.0), Vec3::new(0.16, 0.52, 0.12), 0.1),
        limb("shin-l", Vec3::new(0.16, 0.52, 0.12), Vec3::new(0.17, 0.06, 0.0), 0.075),
        object("foot-l", shapes::cuboid(Vec3::new(0.06, 0.04, 0.13)), at(Vec3::new(0.17, 0.04, 0.07))),
        limb("thigh-r", Vec3::new(-0.12, 1.02, 0.0), Vec3::new(-0.18, 0.55, -0.2), 0.1),
        limb("shin-r", Vec3::new(-0.18, 0.55, -0.2), Vec3::new(-0.2, 0.06, -0.15), 0.075),
        object("foot-r", shapes::cuboid(Vec3::new(0.06, 0.04, 0.13)), at(Vec3::new(-0.2, 0.04, -0.1))),
    ];
    let camera = Camera::looking_at(Vec3::new(1.8, 3.2, 3.0), Vec3::new(-0.3, 0.5, -0.6));
    (objects, disk(Vec3::new(0.9, 4.0, 1.4), 0.6), camera)
}

fn greeble_tower() -> (Vec<SceneObject>, Light, Camera) {
    let cube = std::sync::Arc::new(shapes::cuboid(Vec3::splat(0.5)));
    let cube_topology = std::sync::Arc::new(crate::mesh::Topology::build(&cube));
    let ball = std::sync::Arc::new(shapes::uv_sphere(0.5, 8, 16));
    let ball_topology = std::sync::Arc::new(crate::mesh::Topology::build(&ball));
    let mut objects =
        vec![ground(12.0), object("block", shapes::cuboid(Vec3::new(0.5, 0.25, 0.5)), at(Vec3::new(0.0, 0.25, 0.0)))];
    // A deterministic cloud of parts, denser near the axis, stacked to 2.2 high.
    let mut s = 0x9e37_79b9u32;
    let mut rnd = move || {
        s ^= s << 13;
        s ^= s >> 17;
        s ^= s << 5;
        s as f32 / u32::MAX as f32
    };
    for i in 0..160 {
        let h = 0.5 + 1.7 * rnd();
        let spread = 0.55 * (1.0 - 0.6 * (h - 0.5) / 1.7);
        let p = Vec3::new((rnd() - 0.5) * 2.0 * spread, h, (rnd() - 0.5) * 2.0 * spread);
        let size = Vec3::new(0.08 + 0.25 * rnd(), 0.05 + 0.2 * rnd(), 0.08 + 0.25 * rnd());
        let rotation = Quat::from_euler(glam::EulerRot::YXZ, rnd() * 3.0, rnd() - 0.5, rnd() - 0.5);
        let (mesh, topology) = if i % 3 == 0 { (&ball, &ball_topology) } else { (&cube, &cube_topology) };
        objects.push(
            SceneObject::shared(format!("part-{i}"), mesh.clone(), topology.clone(), placed(p, rotation, size))
                .expect("valid"),
        );
    }
    let camera = Camera::looking_at(Vec3::new(3.2, 3.4, 3.8), Vec3::new(0.0, 0.6, 0.0));
    (objects, disk(Vec3::new(0.3, 4.5, 0.2), 1.5), camera)
}
