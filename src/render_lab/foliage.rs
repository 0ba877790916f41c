//! Alpha-masked casters at scale (issue 16, item 2): N leaf cards of one
//! masked mesh and material over the box-over-plane scene, under its
//! fin-shadowed `SpotLight`, static and with one card moving every frame —
//! extracted on the GPU from the cards' outlines (only the moved card, when
//! the kept depth range allows) against the same app extracting on the CPU
//! (`FinExtraction::Cpu`, the core crate: what every frame with a masked
//! caster did before the GPU packed outlines). Main and render world timed
//! apart, as in `scaling` (`shadow-fins-render-lab foliage`).

use bevy::prelude::*;
use bevy_shadow_fins::{FinExtraction, FinShadowSettings, FinShadowStats};
use shadow_fins::scenes::SceneId;
use shadow_fins_lab::results::Spread;

use super::scaling::{ScalingRun, split_frame, spot_session};
use crate::harness::Session;

/// One card count's medians, ms.
#[derive(Debug, Clone, Copy)]
pub struct FoliageRow {
    pub cards: usize,
    pub static_main_ms: f64,
    pub static_render_ms: f64,
    pub gpu_main_ms: f64,
    pub gpu_render_ms: f64,
    /// The last move's update extracted the moved card alone.
    pub gpu_incremental: bool,
    pub cpu_main_ms: f64,
    pub cpu_render_ms: f64,
    /// Silhouettes of the last update (both extractions agree).
    pub silhouettes: usize,
}

/// `n` leaf cards (the core's `SceneId::LeafCards` card: its mesh, UVs and
/// mask) sharing one mesh and one masked material, on a grid over the ground
/// within the spot's cone, each tilted its own way; their entities.
pub fn spawn_cards(world: &mut World, n: usize) -> Vec<Entity> {
    let built = SceneId::LeafCards.build();
    let card = built.scene.objects.iter().find(|o| o.cutout.is_some()).expect("a masked card");
    let cutout = card.cutout.as_ref().expect("its cut-out");
    let mesh = bevy_shadow_fins::mesh_from_core_with_uvs(&card.mesh, Some(&cutout.vertex_uvs));
    let mesh = world.resource_mut::<Assets<Mesh>>().add(mesh);
    let material = crate::harness::masked_material(world, &cutout.mask);
    let side = (n as f32).sqrt().ceil().max(1.0);
    let spacing = 6.0 / side;
    let scale = spacing * 0.8;
    (0..n)
        .map(|k| {
            let (i, j) = ((k as f32 % side), (k as f32 / side).floor());
            let at = Vec3::new(-3.0 + (i + 0.5) * spacing, scale * 0.5, -3.0 + (j + 0.5) * spacing);
            let tilt = Quat::from_rotation_y(0.7 * k as f32) * Quat::from_rotation_x(-0.6 - 0.1 * (k % 5) as f32);
            let transform = Transform::from_translation(at).with_rotation(tilt).with_scale(Vec3::splat(scale));
            world.spawn((Mesh3d(mesh.clone()), MeshMaterial3d(material.clone()), transform)).id()
        })
        .collect()
}

/// Medians of `frames` frames, `mover` (if any) nudged 1 mm a frame one
/// way; then, after a few still frames, the last update's stats.
fn time(session: &mut Session, frames: u32, mover: Option<Entity>) -> (f64, f64, bevy_shadow_fins::FinFrameStats) {
    let (mut main, mut render) = (vec![], vec![]);
    for _ in 0..frames {
        if let Some(mut t) = mover.and_then(|e| session.app.world_mut().get_mut::<Transform>(e)) {
            t.translation.x += 1e-3;
        }
        let (m, r) = split_frame(&mut session.app);
        main.push(m);
        render.push(r);
    }
    // A frame's counts come back a frame or two late.
    for _ in 0..4 {
        split_frame(&mut session.app);
    }
    let stats = session.app.world().resource::<FinShadowStats>().0;
    (Spread::of(&main).median, Spread::of(&render).median, stats)
}

/// Sets every fin light's extraction.
fn extract_with(session: &mut Session, extraction: FinExtraction) {
    let world = session.app.world_mut();
    let mut lights = world.query::<&mut FinShadowSettings>();
    for mut s in lights.iter_mut(world) {
        s.extraction = extraction;
    }
}

/// One row per card count, each in its own app.
pub fn run(run: &ScalingRun) -> Result<Vec<FoliageRow>, String> {
    let mut rows = vec![];
    for &n in &run.counts {
        let mut session = spot_session(run);
        let Some(&mover) = spawn_cards(session.app.world_mut(), n).get(n / 2) else {
            return Err("the foliage run needs at least one card".into());
        };
        session.settle(6)?;
        let (static_main_ms, static_render_ms, _) = time(&mut session, run.frames, None);
        let (gpu_main_ms, gpu_render_ms, gpu) = time(&mut session, run.frames, Some(mover));
        extract_with(&mut session, FinExtraction::Cpu);
        session.settle(6)?;
        let (cpu_main_ms, cpu_render_ms, cpu) = time(&mut session, run.frames, Some(mover));
        // Each half timed what it says it timed.
        if (gpu.extraction, cpu.extraction) != (FinExtraction::Gpu, FinExtraction::Cpu) {
            return Err(format!("{n} cards: extracted on {:?} and {:?}", gpu.extraction, cpu.extraction));
        }
        rows.push(FoliageRow {
            cards: n,
            static_main_ms,
            static_render_ms,
            gpu_main_ms,
            gpu_render_ms,
            gpu_incremental: gpu.incremental_extraction,
            cpu_main_ms,
            cpu_render_ms,
            silhouettes: cpu.silhouettes,
        });
    }
    Ok(rows)
}

/// The rows as a markdown table.
pub fn markdown(rows: &[FoliageRow]) -> String {
    let mut out = String::from(
        "| leaf cards | silhouettes | static: main ms | render ms | \
         one moving, GPU extraction: main ms | render ms | frame ms | only it extracted | \
         one moving, CPU extraction: main ms | render ms | frame ms |\n\
         |---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for r in rows {
        out += &format!(
            "| {} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {:.1} | {:.1} | {:.1} |\n",
            r.cards,
            r.silhouettes,
            r.static_main_ms,
            r.static_render_ms,
            r.gpu_main_ms,
            r.gpu_render_ms,
            r.gpu_main_ms + r.gpu_render_ms,
            if r.gpu_incremental { "yes" } else { "no" },
            r.cpu_main_ms,
            r.cpu_render_ms,
            r.cpu_main_ms + r.cpu_render_ms,
        );
    }
    out
}
