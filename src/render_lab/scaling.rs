//! Big scenes (issue 16): the frame cost against the number of objects —
//! 10, 100, 1000, 10 000 cubes sharing one mesh over the box-over-plane
//! scene, under one fin-shadowed `SpotLight` — static and with one object
//! moving every frame (only it extracted and its part of the maps redrawn;
//! then every caster extracted, [`FinIncrementalExtraction`] off; then the
//! maps redrawn whole too, [`FinPartialRedraw`] off), then with a skinned bar among them bent
//! a little further every frame (a new pose each frame), split into the
//! main world's and the render world's time (`shadow-fins-render-lab
//! scaling`).
//!
//! The app renders sequentially (no pipelined rendering), so each frame is
//! the main schedule, then extraction and the render world's schedule, timed
//! apart (wall time: the render world's includes what it waits on the GPU
//! for); last, the same app with `FinShadows` removed, Bevy's own map back,
//! is timed static as the baseline (still with the `FinShadowView` camera's
//! depth, normal and deferred prepasses, which the plugin's tests need).
//! Static, the plugin's per-frame main-world work must not grow with
//! the object count (change detection, no walk of the meshes,
//! [`bevy_shadow_fins::FinCasterScans`] unchanged); what still grows is
//! Bevy's own per-entity work (visibility, extraction, draws).

use std::time::Instant;

use bevy::prelude::*;
use bevy_shadow_fins::{
    FinCasterScans, FinCasterUpdates, FinGpuPosing, FinIncrementalExtraction, FinPartialRedraw, FinShadowSettings,
    FinShadowStats, FinShadows,
};
use shadow_fins::scenes::SceneId;
use shadow_fins_lab::results::Spread;

use crate::harness::{Session, Setup};

/// What to render.
#[derive(Debug, Clone)]
pub struct ScalingRun {
    pub counts: Vec<usize>,
    pub frames: u32,
    pub width: u32,
    pub height: u32,
    pub map_resolution: u32,
}

/// One object count's medians, ms, and how many times the plugin walked the
/// meshes while static (should be 0).
#[derive(Debug, Clone, Copy)]
pub struct ScalingRow {
    pub objects: usize,
    pub static_main_ms: f64,
    pub static_render_ms: f64,
    pub static_frame_ms: f64,
    pub static_scans: u64,
    pub moving_main_ms: f64,
    pub moving_render_ms: f64,
    pub moving_frame_ms: f64,
    /// Mesh walks and caster records rebuilt in place while one cube moved
    /// (walks should be 0, records one per frame).
    pub moving_scans: u64,
    pub moving_records: u64,
    /// The last move's update (read once the GPU's counts of it came back,
    /// a few still frames later): only the moved cube extracted
    /// (`FinFrameStats::incremental_extraction`), a partial redraw
    /// (`FinFrameStats::partial_redraw`), and the share of the maps' texels
    /// it redrew.
    pub moving_incremental: bool,
    pub moving_partial: bool,
    pub moving_redrawn: f64,
    /// One moving again with [`FinIncrementalExtraction`] off (every caster
    /// extracted each update, the maps still redrawn in part): main, render
    /// world ms.
    pub all_extracted_main_ms: f64,
    pub all_extracted_render_ms: f64,
    /// One moving again with [`FinPartialRedraw`] off (every update redraws
    /// the maps whole): main, render world ms.
    pub whole_main_ms: f64,
    pub whole_render_ms: f64,
    /// A skinned bar among the cubes, bent a little further every frame
    /// (a new pose each frame): main, render world ms, in how many frames
    /// its caster was rebuilt in place (no re-collected scene), whether the
    /// GPU posed it (`FinFrameStats::posed_on_gpu`), and the last bend's
    /// map update: partial or whole, and the share of texels redrawn.
    pub posed_main_ms: f64,
    pub posed_render_ms: f64,
    pub posed_in_place: u64,
    pub posed_on_gpu: usize,
    pub posed_partial: bool,
    pub posed_redrawn: f64,
    /// The bar bending again with [`FinGpuPosing`] off (posed on the CPU: new
    /// geometry each pose): main, render world ms.
    pub cpu_posed_main_ms: f64,
    pub cpu_posed_render_ms: f64,
    /// The same app static with `FinShadows` removed (Bevy's own spot shadow
    /// map back): what Bevy alone costs at this object count.
    pub bevy_main_ms: f64,
    pub bevy_render_ms: f64,
}

/// `n` cubes of one shared mesh on a grid over the ground, each floating
/// its own size above it (so each casts), within the spot light's cone, row
/// by row from (−3, −3); their entities in that order.
pub fn spawn_cubes(world: &mut World, n: usize) -> Vec<Entity> {
    let side = (n as f32).sqrt().ceil().max(1.0);
    let spacing = 6.0 / side;
    let size = spacing * 0.4;
    let mesh = world.resource_mut::<Assets<Mesh>>().add(Cuboid::from_length(size));
    let material = world.resource_mut::<Assets<StandardMaterial>>().add(StandardMaterial::default());
    (0..n)
        .map(|k| {
            let (i, j) = ((k as f32 % side), (k as f32 / side).floor());
            let at = Vec3::new(-3.0 + (i + 0.5) * spacing, size * 1.5, -3.0 + (j + 0.5) * spacing);
            world.spawn((Mesh3d(mesh.clone()), MeshMaterial3d(material.clone()), Transform::from_translation(at))).id()
        })
        .collect()
}

/// One frame, main world and render world timed apart (ms of wall time on
/// this thread: the render world's is its CPU side, with GPU work it waits on).
pub(crate) fn split_frame(app: &mut App) -> (f64, f64) {
    let apps = app.sub_apps_mut();
    let start = Instant::now();
    apps.main.run_default_schedule();
    let main = start.elapsed().as_secs_f64() * 1e3;
    let start = Instant::now();
    for (_, sub) in apps.sub_apps.iter_mut() {
        sub.extract(apps.main.world_mut());
        sub.update();
    }
    apps.main.world_mut().clear_trackers();
    (main, start.elapsed().as_secs_f64() * 1e3)
}

/// What changes from frame to frame while timing.
#[derive(Debug, Clone, Copy)]
enum Motion {
    Still,
    /// This cube moves a hair every frame.
    Cube(Entity),
    /// This joint turns a little further every frame.
    Joint(Entity),
}

/// A bar (of one size whatever the cube count) skinned to two joints — the root at `at`,
/// the second (its child, at the same place) bending the bar's far half —,
/// with its mesh's positions in the joints' space (inverse bind poses the
/// identity). Returns the bending joint.
pub fn spawn_skinned_bar(world: &mut World, at: Vec3) -> Entity {
    spawn_skinned_bar_weighted(world, at, |_, p| 0.5 + p.x / 1.2)
}

/// [`spawn_skinned_bar`] with the bending joint's weight of each of the
/// cuboid's 24 vertices (4 per face: each corner three times, once per
/// face) given by `bend_weight(vertex, position)`, the root's the rest.
pub fn spawn_skinned_bar_weighted(world: &mut World, at: Vec3, bend_weight: impl Fn(usize, Vec3) -> f32) -> Entity {
    spawn_skinned_mesh(world, Mesh::from(Cuboid::new(1.2, 0.15, 0.15)), at, bend_weight)
}

/// `mesh` skinned as [`spawn_skinned_bar_weighted`] skins its bar: two
/// joints at `at`, the second's weight of each vertex `bend_weight(vertex,
/// position)`. Returns the bending joint.
pub fn spawn_skinned_mesh(
    world: &mut World,
    mut mesh: Mesh,
    at: Vec3,
    bend_weight: impl Fn(usize, Vec3) -> f32,
) -> Entity {
    use bevy::mesh::{
        VertexAttributeValues,
        skinning::{SkinnedMesh, SkinnedMeshInverseBindposes},
    };
    // A mesh without float positions gets no joint weights (and casts nothing).
    let positions = match mesh.attribute(Mesh::ATTRIBUTE_POSITION) {
        Some(VertexAttributeValues::Float32x3(positions)) => positions.clone(),
        _ => vec![],
    };
    let weights: Vec<[f32; 4]> = (positions.iter().enumerate())
        .map(|(i, p)| {
            let w = bend_weight(i, Vec3::from_array(*p));
            [1.0 - w, w, 0.0, 0.0]
        })
        .collect();
    let joints = vec![[0u16, 1, 0, 0]; weights.len()];
    mesh.insert_attribute(Mesh::ATTRIBUTE_JOINT_INDEX, VertexAttributeValues::Uint16x4(joints));
    mesh.insert_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, weights);
    let mesh = world.resource_mut::<Assets<Mesh>>().add(mesh);
    let bindposes = world
        .resource_mut::<Assets<SkinnedMeshInverseBindposes>>()
        .add(SkinnedMeshInverseBindposes::from(vec![Mat4::IDENTITY; 2]));
    let material = world.resource_mut::<Assets<StandardMaterial>>().add(StandardMaterial::default());
    let root = world.spawn(Transform::from_translation(at)).id();
    let bend = world.spawn((Transform::default(), ChildOf(root))).id();
    world.spawn((
        Mesh3d(mesh),
        MeshMaterial3d(material),
        SkinnedMesh { inverse_bindposes: bindposes, joints: vec![root, bend] },
    ));
    bend
}

/// Median ms of frames (main world, render world, whole frame), and, for a
/// moving cube, the last map update: partial or not, the share of texels redrawn.
#[derive(Debug, Clone, Copy, Default)]
struct Medians {
    main: f64,
    render: f64,
    frame: f64,
    incremental: bool,
    partial: bool,
    redrawn: f64,
    posed_on_gpu: usize,
}

/// Medians over `frames` frames with `motion`.
fn time(session: &mut Session, frames: u32, motion: Motion) -> Medians {
    let (mut main, mut render, mut frame) = (vec![], vec![], vec![]);
    for k in 0..frames {
        // One way (1 mm, or a few mrad, a frame): no pose repeats, so no cache can hide the cost.
        let step = (k + 1) as f32 / frames as f32;
        let world = session.app.world_mut();
        match motion {
            Motion::Cube(cube) => world.get_mut::<Transform>(cube).map(|mut t| t.translation.x += 1e-3 * step),
            Motion::Joint(joint) => world.get_mut::<Transform>(joint).map(|mut t| t.rotate_z(0.01 * step)),
            Motion::Still => None,
        };
        let (m, r) = split_frame(&mut session.app);
        main.push(m);
        render.push(r);
        frame.push(m + r);
    }
    let median = |v: &[f64]| Spread::of(v).median;
    let mut medians =
        Medians { main: median(&main), render: median(&render), frame: median(&frame), ..Default::default() };
    if !matches!(motion, Motion::Still) {
        // A frame's counts come back a frame or two late, and only count for
        // the frame still current: a few still frames, then the last move's.
        for _ in 0..4 {
            split_frame(&mut session.app);
        }
        let stats = session.app.world().resource::<FinShadowStats>().0;
        let whole = stats.map_texels() as f64;
        medians.incremental = stats.incremental_extraction;
        medians.partial = stats.partial_redraw;
        medians.posed_on_gpu = stats.posed_on_gpu;
        medians.redrawn = if whole > 0.0 { stats.redrawn_texels as f64 / whole } else { 0.0 };
    }
    medians
}

/// The box-over-plane scene under its fin-shadowed `SpotLight`, rendered
/// sequentially (the main and render worlds timed apart): what the timed
/// runs spawn their objects into.
pub(crate) fn spot_session(run: &ScalingRun) -> Session {
    let built = SceneId::BoxOverPlane.build();
    let settings = FinShadowSettings { map_resolution: run.map_resolution, ..default() };
    let mut setup = Setup::new(built.scene, built.light, built.camera, settings, (run.width, run.height));
    setup.spot = true;
    setup.sequential_rendering = true;
    Session::new(&setup)
}

/// One row per object count, each in its own app.
pub fn run(run: &ScalingRun) -> Result<Vec<ScalingRow>, String> {
    let mut rows = vec![];
    for &n in &run.counts {
        let mut session = spot_session(run);
        let Some(&mover) = spawn_cubes(session.app.world_mut(), n).first() else {
            return Err("the scaling run needs at least one object".into());
        };
        session.settle(6)?;
        let scans = |s: &Session| s.app.world().resource::<FinCasterScans>().0;
        let updates = |s: &Session| *s.app.world().resource::<FinCasterUpdates>();
        let before = scans(&session);
        let still = time(&mut session, run.frames, Motion::Still);
        let static_scans = scans(&session) - before;
        let (scans_before, records_before) = (scans(&session), updates(&session).records);
        let moving = time(&mut session, run.frames, Motion::Cube(mover));
        let moving_scans = scans(&session) - scans_before;
        let moving_records = updates(&session).records - records_before;
        session.app.insert_resource(FinIncrementalExtraction(false));
        let all_extracted = time(&mut session, run.frames, Motion::Cube(mover));
        session.app.insert_resource(FinIncrementalExtraction(true));
        session.app.insert_resource(FinPartialRedraw(false));
        let whole = time(&mut session, run.frames, Motion::Cube(mover));
        session.app.insert_resource(FinPartialRedraw(true));
        let bend = spawn_skinned_bar(session.app.world_mut(), Vec3::new(1.2, 0.9, 1.2));
        session.settle(6)?;
        let in_place_before = updates(&session).frames;
        let posed = time(&mut session, run.frames, Motion::Joint(bend));
        let posed_in_place = updates(&session).frames - in_place_before;
        session.app.insert_resource(FinGpuPosing(false));
        session.settle(6)?;
        let posed_on_cpu = time(&mut session, run.frames, Motion::Joint(bend));
        session.app.insert_resource(FinGpuPosing(true));
        let world = session.app.world_mut();
        let fin_lights: Vec<Entity> = world.query_filtered::<Entity, With<FinShadows>>().iter(world).collect();
        for e in fin_lights {
            world.entity_mut(e).remove::<FinShadows>();
        }
        session.settle(6)?;
        let bevy = time(&mut session, run.frames, Motion::Still);
        rows.push(ScalingRow {
            objects: n,
            static_main_ms: still.main,
            static_render_ms: still.render,
            static_frame_ms: still.frame,
            static_scans,
            moving_main_ms: moving.main,
            moving_render_ms: moving.render,
            moving_frame_ms: moving.frame,
            moving_scans,
            moving_records,
            moving_incremental: moving.incremental,
            moving_partial: moving.partial,
            moving_redrawn: moving.redrawn,
            all_extracted_main_ms: all_extracted.main,
            all_extracted_render_ms: all_extracted.render,
            whole_main_ms: whole.main,
            whole_render_ms: whole.render,
            posed_main_ms: posed.main,
            posed_render_ms: posed.render,
            posed_in_place,
            posed_on_gpu: posed.posed_on_gpu,
            posed_partial: posed.partial,
            posed_redrawn: posed.redrawn,
            cpu_posed_main_ms: posed_on_cpu.main,
            cpu_posed_render_ms: posed_on_cpu.render,
            bevy_main_ms: bevy.main,
            bevy_render_ms: bevy.render,
        });
    }
    Ok(rows)
}

/// The rows as a markdown table.
pub fn markdown(rows: &[ScalingRow]) -> String {
    let mut out = String::from(
        "| objects | static main ms | static render ms | static frame ms | mesh walks while static | \
         one moving: main ms | render ms | frame ms | mesh walks | records rebuilt | \
         only it extracted | last update partial | texels it redrew | \
         one moving, every caster extracted: main ms | render ms | \
         one moving, every caster extracted, maps redrawn whole: main ms | render ms | \
         a skinned bar bending: main ms | render ms | frames updated in place | posed on the GPU | \
         last update partial | texels it redrew | \
         the bar posed on the CPU (FinGpuPosing off): main ms | render ms | \
         FinShadows removed (Bevy's map), static: main ms | render ms |\n\
         |---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        out += &format!(
            "| {} | {:.1} | {:.1} | {:.1} | {} | {:.1} | {:.1} | {:.1} | {} | {} | {} | {} | {:.2}% | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {} | {} | {:.2}% | {:.1} | {:.1} | {:.1} | {:.1} |\n",
            r.objects,
            r.static_main_ms,
            r.static_render_ms,
            r.static_frame_ms,
            r.static_scans,
            r.moving_main_ms,
            r.moving_render_ms,
            r.moving_frame_ms,
            r.moving_scans,
            r.moving_records,
            r.moving_incremental,
            r.moving_partial,
            r.moving_redrawn * 100.0,
            r.all_extracted_main_ms,
            r.all_extracted_render_ms,
            r.whole_main_ms,
            r.whole_render_ms,
            r.posed_main_ms,
            r.posed_render_ms,
            r.posed_in_place,
            r.posed_on_gpu,
            r.posed_partial,
            r.posed_redrawn * 100.0,
            r.cpu_posed_main_ms,
            r.cpu_posed_render_ms,
            r.bevy_main_ms,
            r.bevy_render_ms,
        );
    }
    out
}

/// One skinned mesh's size and what its poses cost (`shadow-fins-render-lab
/// posing`): ms per frame, main and render world, still and bent a little
/// further every frame, posed on the GPU (the default) and on the CPU.
#[derive(Debug, Clone, Copy)]
pub struct PosingRow {
    pub vertices: usize,
    pub triangles: usize,
    pub static_main_ms: f64,
    pub static_render_ms: f64,
    pub gpu_posed_main_ms: f64,
    pub gpu_posed_render_ms: f64,
    pub posed_on_gpu: usize,
    pub cpu_posed_main_ms: f64,
    pub cpu_posed_render_ms: f64,
}

/// A skinned arm of about 33 × `segments` + 328 vertices: a capsule along x
/// (`Capsule3d`, 32 longitudes), bent by the second joint with a weight
/// that ramps along its whole length ([`posing`]; the seams' split vertices,
/// at one position, move as one: the pose keeps the topology at rest).
pub fn skinned_arm(segments: u32) -> Mesh {
    let mut mesh = Capsule3d::new(0.08, 1.1).mesh().rings(segments.max(1)).latitudes(8).longitudes(32).build();
    mesh.rotate_by(Quat::from_rotation_z(-std::f32::consts::FRAC_PI_2));
    mesh
}

/// The box-over-plane scene under its fin-shadowed spot light with one
/// skinned arm per size in `segments` (each in its own app): what a new pose
/// costs the main world (the CPU) and the render world.
pub fn posing(run: &ScalingRun, segments: &[u32]) -> Result<Vec<PosingRow>, String> {
    let mut rows = vec![];
    for &n in segments {
        let mut session = spot_session(run);
        let mesh = skinned_arm(n);
        let vertices = mesh.count_vertices();
        let triangles = mesh.indices().map_or(vertices / 3, |i| i.len() / 3);
        // Just under the box (its bottom at y = 1): `time` turns the joint by about
        // 0.005 rad × frames in all, lifting the far end towards it (20 frames: 0.1 rad).
        let joint = spawn_skinned_mesh(session.app.world_mut(), mesh, Vec3::new(-0.5, 0.9, 0.0), |_, p| {
            ((p.x + 0.55) / 1.1).clamp(0.0, 1.0)
        });
        session.settle(6)?;
        let still = time(&mut session, run.frames, Motion::Still);
        let gpu = time(&mut session, run.frames, Motion::Joint(joint));
        session.app.insert_resource(FinGpuPosing(false));
        session.settle(6)?;
        let cpu = time(&mut session, run.frames, Motion::Joint(joint));
        rows.push(PosingRow {
            vertices,
            triangles,
            static_main_ms: still.main,
            static_render_ms: still.render,
            gpu_posed_main_ms: gpu.main,
            gpu_posed_render_ms: gpu.render,
            posed_on_gpu: gpu.posed_on_gpu,
            cpu_posed_main_ms: cpu.main,
            cpu_posed_render_ms: cpu.render,
        });
    }
    Ok(rows)
}

/// The posing rows as a markdown table.
pub fn posing_markdown(rows: &[PosingRow]) -> String {
    let mut out = String::from(
        "| vertices | triangles | static: main ms | render ms | bent every frame, posed on the GPU: main ms | \
         render ms | posed on the GPU | posed on the CPU (FinGpuPosing off): main ms | render ms |\n\
         |---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        out += &format!(
            "| {} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {:.1} | {:.1} |\n",
            r.vertices,
            r.triangles,
            r.static_main_ms,
            r.static_render_ms,
            r.gpu_posed_main_ms,
            r.gpu_posed_render_ms,
            r.posed_on_gpu,
            r.cpu_posed_main_ms,
            r.cpu_posed_render_ms,
        );
    }
    out
}
