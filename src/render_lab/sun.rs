//! The sun (`shadow-fins-render-lab sun`): a Bevy `DirectionalLight` with
//! `FinShadows` on built-in scenes, its error against the ray-traced truth
//! and its frame time beside Bevy's own cascaded shadow maps for the same
//! light, in one app.
//!
//! Per scene and angular size, four rows: fins with their maps fitted to the
//! view (the default), fins over the whole scene, the coverage method, and
//! Bevy's cascades (`FinShadows` removed: Bevy's own map back, PCF). Bevy's
//! visibility is the colour ratio shadowed / unshadowed of the same light,
//! ambient off and tonemapping off (as `measure` does for Bevy's point
//! lights); the plugin's is its visibility buffer. Errors are over the
//! shadowed region (`shadow_fins::metrics`), against 1024 samples of the sun's
//! disk per pixel.

use bevy::{light::DirectionalLightShadowMap, prelude::*};
use bevy_shadow_fins::{FinMethod, FinShadowSettings, FinShadows};
use shadow_fins::{
    ground_truth::GroundTruth,
    light::{DiskLight, Light, SunLight},
    metrics::ErrorMetrics,
    scene::LightSpaceScene,
    scenes::SceneId,
};
use shadow_fins_lab::{eval::camera_receivers, results::Spread};

use crate::harness::{Session, Setup};

/// The sun the lab and the tests put over a built-in scene: from about where
/// its disk light is, tilted so that shadows fall sideways, as soft as the disk
/// seen from the scene's origin (`tan θ = R / |c|`) unless `angle` (radians,
/// angular radius) says otherwise.
pub fn sun_over(disk: &DiskLight, angle: Option<f32>) -> SunLight {
    let direction = (disk.normal + Vec3::new(0.6, 0.0, 0.35)).normalize();
    let angle = angle.unwrap_or_else(|| (disk.radius / disk.center.length().max(1e-3)).atan());
    SunLight::new(direction, angle.clamp(0.0, 1.4)).expect("a normalised direction and a clamped angle")
}

/// What one row measured.
#[derive(Debug, Clone)]
pub struct SunRow {
    pub scene: &'static str,
    /// Angular radius, radians.
    pub angle: f32,
    pub method: &'static str,
    pub error: ErrorMetrics,
    /// Median frame time, ms.
    pub frame_ms: f64,
}

/// What to render.
#[derive(Debug, Clone)]
pub struct SunRun {
    pub scenes: Vec<SceneId>,
    /// Angular radii (radians); `None`: each scene's own (`sun_over`).
    pub angles: Vec<Option<f32>>,
    pub frames: u32,
    pub width: u32,
    pub height: u32,
    pub map_resolution: u32,
    /// Layers of the fins' maps (`FinShadowSettings::layers`).
    pub layers: u32,
    pub samples: u32,
}

fn energy(c: &[f32; 3]) -> f32 {
    c[0] + c[1] + c[2]
}

/// Every row, scene by scene.
pub fn run(run: &SunRun) -> Result<Vec<SunRow>, String> {
    let mut rows = vec![];
    for &id in &run.scenes {
        let built = id.build();
        let Light::Disk(disk) = built.light else {
            return Err(format!("{}: no disk light to place a sun by", id.name()));
        };
        for &angle in &run.angles {
            let sun = sun_over(&disk, angle);
            let light = Light::Sun(sun);
            let settings = FinShadowSettings { map_resolution: run.map_resolution, layers: run.layers, ..default() };
            let mut setup = Setup::new(built.scene.clone(), light, built.camera, settings, (run.width, run.height));
            setup.linear_color = true;
            setup.ambient = Some(0.0);
            let ls = LightSpaceScene::new(&setup.scene, light);
            let receivers = camera_receivers(&setup.camera, run.width, run.height, &ls);
            let truth = GroundTruth::new(&ls, run.samples);
            // Pixels that see a receiver facing the sun: where the light can shine.
            let scored: Vec<usize> = receivers
                .iter()
                .enumerate()
                .filter_map(|(i, r)| r.filter(|r| r.faces_light(&ls.frame)).map(|_| i))
                .collect();
            let reference: Vec<f32> = scored.iter().map(|&i| truth.visibility(receivers[i].unwrap())).collect();
            let pick = |v: &[f32]| -> Vec<f32> { scored.iter().map(|&i| v[i]).collect() };

            let mut session = Session::new(&setup);
            session.app.world_mut().insert_resource(DirectionalLightShadowMap { size: run.map_resolution as usize });
            let sun_entity = {
                let world = session.app.world_mut();
                world.query_filtered::<Entity, With<DirectionalLight>>().single(world).map_err(|e| e.to_string())?
            };
            let mut row = |session: &mut Session, method: &'static str, visibility: &[f32]| {
                let timing = session.timed_with(run.frames, |_, _| {});
                rows.push(SunRow {
                    scene: id.name(),
                    angle: sun.angular_radius,
                    method,
                    error: ErrorMetrics::compute(&pick(visibility), &reference),
                    frame_ms: Spread::of(&timing.frame_ms).median,
                });
            };
            let variants: [(&'static str, FinShadowSettings); 3] = [
                ("fins, fitted to the view", settings),
                ("fins, whole scene", FinShadowSettings { fit_sun_to_views: false, ..settings }),
                ("coverage (256 samples)", FinShadowSettings { method: FinMethod::Coverage, ..settings }),
            ];
            for (method, s) in variants {
                session.app.world_mut().entity_mut(sun_entity).insert(s);
                let shot = session.settle(16)?;
                row(&mut session, method, &shot.visibility);
            }
            // Bevy's cascades: its own shadow map back, then the light unshadowed.
            session.app.world_mut().entity_mut(sun_entity).remove::<FinShadows>();
            let shadowed = session.settle(16)?;
            session.app.world_mut().get_mut::<DirectionalLight>(sun_entity).expect("the sun").shadow_maps_enabled =
                false;
            let unshadowed = session.settle(16)?;
            let ratio: Vec<f32> = shadowed
                .linear
                .iter()
                .zip(&unshadowed.linear)
                .map(|(s, u)| if energy(u) > 0.0 { (energy(s) / energy(u)).clamp(0.0, 1.0) } else { 1.0 })
                .collect();
            session.app.world_mut().get_mut::<DirectionalLight>(sun_entity).expect("the sun").shadow_maps_enabled =
                true;
            session.settle(16)?;
            row(&mut session, "Bevy cascades (PCF)", &ratio);
        }
    }
    Ok(rows)
}

/// The rows as a markdown table; frame times also as a ratio to Bevy's
/// cascades of the same scene and angle.
pub fn markdown(rows: &[SunRow]) -> String {
    let mut out = String::from(
        "| scene | θ (mrad) | method | MAE | RMSE | p99 | umbra over | leak | frame ms | ÷ Bevy |\n\
         |---|---:|---|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        let bevy = rows
            .iter()
            .find(|b| b.scene == r.scene && b.angle == r.angle && b.method.starts_with("Bevy"))
            .map_or(f64::NAN, |b| b.frame_ms);
        let e = &r.error;
        out += &format!(
            "| {} | {:.1} | {} | {:.4} | {:.4} | {:.3} | {:.2}% | {:.2}% | {:.1} | {:.2} |\n",
            r.scene,
            r.angle * 1e3,
            r.method,
            e.mae,
            e.rmse,
            e.p99,
            e.umbra_over * 100.0,
            e.leak * 100.0,
            r.frame_ms,
            r.frame_ms / bevy,
        );
    }
    out
}
