//! Several lights at once: the frame cost of N fin-shadowed `SpotLight`s
//! (1, 2, 4, 8, …) beside Bevy's own shadow maps for the same N lights, in
//! one app, side by side (`shadow-fins-render-lab lights`).
//!
//! Per N the lights sit on a ring above the scene's own light. Each row
//! times the same app twice: with `FinShadows` on every light, then with it
//! removed (each light's Bevy shadow map back, `DirectionalLightShadowMap`
//! at the same resolution as the fins' maps), static and with every light
//! moving a hair each frame (the fins redo extraction and maps; Bevy
//! re-renders its maps every frame either way).

use bevy::{light::DirectionalLightShadowMap, prelude::*};
use bevy_shadow_fins::{FinShadowSettings, FinShadows};
use shadow_fins::{
    light::{DiskLight, Light},
    scenes::SceneId,
};

use shadow_fins_lab::results::Spread;

use crate::harness::{Session, Setup};

/// One light count's frame times, medians in ms.
#[derive(Debug, Clone, Copy)]
pub struct LightsRow {
    pub lights: usize,
    pub fins_static_ms: f64,
    pub fins_moving_ms: f64,
    pub bevy_static_ms: f64,
    pub bevy_moving_ms: f64,
}

/// What to render.
#[derive(Debug, Clone)]
pub struct LightsRun {
    pub scene: SceneId,
    pub counts: Vec<usize>,
    pub frames: u32,
    pub width: u32,
    pub height: u32,
    pub map_resolution: u32,
}

/// The scene's light plus `n − 1` more on a ring around it.
fn setup_for(run: &LightsRun, n: usize) -> Result<Setup, String> {
    let built = run.scene.build();
    let Light::Disk(d) = built.light else { return Err("the lights run needs a scene with a disk light".into()) };
    let settings = FinShadowSettings { map_resolution: run.map_resolution, ..default() };
    let mut setup = Setup::new(built.scene, built.light, built.camera, settings, (run.width, run.height));
    setup.spot = true;
    let reach = setup.scene.bounds().map_or(1.0, |(lo, hi)| (hi - lo).length() * 0.15);
    setup.extra_lights = (1..n)
        .map(|k| {
            let a = k as f32 * std::f32::consts::TAU / (n - 1).max(1) as f32;
            let (u, v) = d.normal.any_orthonormal_pair();
            Light::Disk(DiskLight { center: d.center + (u * a.cos() + v * a.sin()) * reach, ..d })
        })
        .collect();
    Ok(setup)
}

/// Times `frames` frames, the lights moving a hair each frame when `moving`.
fn time(session: &mut Session, frames: u32, moving: bool) -> f64 {
    let timing = session.timed_with(frames, |world, frame| {
        if moving {
            let step = if frame % 2 == 0 { 1e-4 } else { -1e-4 };
            for mut t in world.query_filtered::<&mut Transform, With<SpotLight>>().iter_mut(world) {
                t.translation.x += step;
            }
        }
    });
    Spread::of(&timing.frame_ms).median
}

/// One row per light count.
pub fn run(run: &LightsRun) -> Result<Vec<LightsRow>, String> {
    let mut rows = vec![];
    for &n in &run.counts {
        let setup = setup_for(run, n.max(1))?;
        let mut session = Session::new(&setup);
        session.app.world_mut().insert_resource(DirectionalLightShadowMap { size: run.map_resolution as usize });
        session.settle(6)?;
        let fins_static_ms = time(&mut session, run.frames, false);
        let fins_moving_ms = time(&mut session, run.frames, true);
        let world = session.app.world_mut();
        let spots: Vec<Entity> = world.query_filtered::<Entity, With<FinShadows>>().iter(world).collect();
        for e in spots {
            world.entity_mut(e).remove::<FinShadows>();
        }
        session.settle(6)?;
        let bevy_static_ms = time(&mut session, run.frames, false);
        let bevy_moving_ms = time(&mut session, run.frames, true);
        rows.push(LightsRow { lights: n.max(1), fins_static_ms, fins_moving_ms, bevy_static_ms, bevy_moving_ms });
    }
    Ok(rows)
}

/// The rows as a markdown table.
pub fn markdown(rows: &[LightsRow]) -> String {
    let mut out = String::from(
        "| lights | fins static ms | Bevy maps static ms | ratio | fins moving ms | Bevy maps moving ms | ratio |\n\
         |---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        out += &format!(
            "| {} | {:.1} | {:.1} | {:.2} | {:.1} | {:.1} | {:.2} |\n",
            r.lights,
            r.fins_static_ms,
            r.bevy_static_ms,
            r.fins_static_ms / r.bevy_static_ms,
            r.fins_moving_ms,
            r.bevy_moving_ms,
            r.fins_moving_ms / r.bevy_moving_ms,
        );
    }
    out
}
