//! Big scenes (issue 16): the frame cost against the number of objects —
//! 10, 100, 1000, 10 000 cubes sharing one mesh over the box-over-plane
//! scene, under one fin-shadowed `SpotLight` — static and with one object
//! moving every frame, split into the main world's and the render world's
//! time (`shadow-fins-render-lab scaling`).
//!
//! The app renders sequentially (no pipelined rendering), so each frame is
//! the main schedule, then extraction and the render world's schedule, timed
//! apart (wall time: the render world's includes what it waits on the GPU
//! for); last, the same app with `FinShadows` removed, Bevy's own map back,
//! is timed static as the baseline (still with the `FinShadowView` camera's
//! depth, normal and deferred prepasses, which the plugin's tests need). Static, the plugin's per-frame main-world work must not grow with
//! the object count (change detection, no walk of the meshes,
//! [`bevy_shadow_fins::FinCasterScans`] unchanged); what still grows is
//! Bevy's own per-entity work (visibility, extraction, draws).

use std::time::Instant;

use bevy::prelude::*;
use bevy_shadow_fins::{FinCasterScans, FinCasterUpdates, FinShadowSettings, FinShadows};
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
    /// The same app static with `FinShadows` removed (Bevy's own spot shadow
    /// map back): what Bevy alone costs at this object count.
    pub bevy_main_ms: f64,
    pub bevy_render_ms: f64,
}

/// Marks the cubes the run adds.
#[derive(Component)]
struct ScalingCube;

/// `n` cubes of one shared mesh on a grid over the ground, each floating
/// its own size above it (so each casts), within the spot light's cone.
fn spawn_cubes(world: &mut World, n: usize) {
    let side = (n as f32).sqrt().ceil().max(1.0);
    let spacing = 6.0 / side;
    let size = spacing * 0.4;
    let mesh = world.resource_mut::<Assets<Mesh>>().add(Cuboid::from_length(size));
    let material = world.resource_mut::<Assets<StandardMaterial>>().add(StandardMaterial::default());
    for k in 0..n {
        let (i, j) = ((k as f32 % side), (k as f32 / side).floor());
        let at = Vec3::new(-3.0 + (i + 0.5) * spacing, size * 1.5, -3.0 + (j + 0.5) * spacing);
        world.spawn((
            Mesh3d(mesh.clone()),
            MeshMaterial3d(material.clone()),
            Transform::from_translation(at),
            ScalingCube,
        ));
    }
}

/// One frame, main world and render world timed apart (ms of wall time on
/// this thread: the render world's is its CPU side, with GPU work it waits on).
fn split_frame(app: &mut App) -> (f64, f64) {
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

/// Median (main, render, frame) ms over `frames` frames; when `moving`, the
/// first cube moves a hair every frame.
fn time(session: &mut Session, frames: u32, moving: bool) -> (f64, f64, f64) {
    let (mut main, mut render, mut frame) = (vec![], vec![], vec![]);
    let mover = {
        let world = session.app.world_mut();
        world.query_filtered::<Entity, With<ScalingCube>>().iter(world).min()
    };
    for k in 0..frames {
        if moving && let Some(e) = mover {
            // One way (1 mm a frame): no pose repeats, so no cache can hide the cost.
            if let Some(mut t) = session.app.world_mut().get_mut::<Transform>(e) {
                t.translation.x += 1e-3 * (k + 1) as f32 / frames as f32;
            }
        }
        let (m, r) = split_frame(&mut session.app);
        main.push(m);
        render.push(r);
        frame.push(m + r);
    }
    let median = |v: &[f64]| Spread::of(v).median;
    (median(&main), median(&render), median(&frame))
}

/// One row per object count, each in its own app.
pub fn run(run: &ScalingRun) -> Result<Vec<ScalingRow>, String> {
    let mut rows = vec![];
    for &n in &run.counts {
        let built = SceneId::BoxOverPlane.build();
        let settings = FinShadowSettings { map_resolution: run.map_resolution, ..default() };
        let mut setup = Setup::new(built.scene, built.light, built.camera, settings, (run.width, run.height));
        setup.spot = true;
        setup.sequential_rendering = true;
        let mut session = Session::new(&setup);
        spawn_cubes(session.app.world_mut(), n);
        session.settle(6)?;
        let scans = |s: &Session| s.app.world().resource::<FinCasterScans>().0;
        let before = scans(&session);
        let (static_main_ms, static_render_ms, static_frame_ms) = time(&mut session, run.frames, false);
        let static_scans = scans(&session) - before;
        let (scans_before, records_before) =
            (scans(&session), session.app.world().resource::<FinCasterUpdates>().records);
        let (moving_main_ms, moving_render_ms, moving_frame_ms) = time(&mut session, run.frames, true);
        let moving_scans = scans(&session) - scans_before;
        let moving_records = session.app.world().resource::<FinCasterUpdates>().records - records_before;
        let world = session.app.world_mut();
        let fin_lights: Vec<Entity> = world.query_filtered::<Entity, With<FinShadows>>().iter(world).collect();
        for e in fin_lights {
            world.entity_mut(e).remove::<FinShadows>();
        }
        session.settle(6)?;
        let (bevy_main_ms, bevy_render_ms, _) = time(&mut session, run.frames, false);
        rows.push(ScalingRow {
            objects: n,
            static_main_ms,
            static_render_ms,
            static_frame_ms,
            static_scans,
            moving_main_ms,
            moving_render_ms,
            moving_frame_ms,
            moving_scans,
            moving_records,
            bevy_main_ms,
            bevy_render_ms,
        });
    }
    Ok(rows)
}

/// The rows as a markdown table.
pub fn markdown(rows: &[ScalingRow]) -> String {
    let mut out = String::from(
        "| objects | static main ms | static render ms | static frame ms | mesh walks while static | \
         one moving: main ms | render ms | frame ms | mesh walks | records rebuilt | \
         FinShadows removed (Bevy's map), static: main ms | render ms |\n\
         |---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        out += &format!(
            "| {} | {:.1} | {:.1} | {:.1} | {} | {:.1} | {:.1} | {:.1} | {} | {} | {:.1} | {:.1} |\n",
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
            r.bevy_main_ms,
            r.bevy_render_ms,
        );
    }
    out
}
