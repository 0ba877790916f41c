//! # bevy_shadow_fins
//!
//! Soft shadows from a light with a size, by multi-layered shadow fins (Cai et
//! al. 2006) with this project's measured improvements (see `CHANGELOG.md`).
//!
//! ```no_run
//! use bevy::prelude::*;
//! use bevy_shadow_fins::{FinShadowView, FinShadows, ShadowFinsPlugin};
//!
//! fn main() {
//!     App::new()
//!         // Forward (Bevy's default) and deferred materials alike get fin shadows.
//!         .add_plugins((DefaultPlugins, ShadowFinsPlugin))
//!         .add_systems(Startup, setup)
//!         .run();
//! }
//!
//! fn setup(mut commands: Commands) {
//!     // Bevy's own spot light; `FinShadows` gives it soft shadows sized by its radius.
//!     commands.spawn((
//!         SpotLight { radius: 0.5, outer_angle: 1.0, ..default() },
//!         FinShadows,
//!         Transform::from_xyz(0.0, 5.0, 0.0).looking_at(Vec3::ZERO, Vec3::Z),
//!     ));
//!     commands.spawn((Camera3d::default(), FinShadowView::default()));
//! }
//! ```
//!
//! ## Lights
//!
//! [`FinShadows`] goes on a light Bevy already has:
//! - `SpotLight`: a disk of the spot's `radius`, facing along its axis;
//! - `DirectionalLight`: the sun, as wide as its `SunDisk`'s angular size,
//!   through orthographic maps fitted to what the cameras see;
//! - `RectLight`: its rectangle (Bevy itself gives it no shadow at all);
//! - `PointLight`: a sphere of its `radius`, by six cube-face frames.
//!
//! The plugin's own [`FinLight`] is a disk lighting the half-space it faces
//! (shaded by the plugin, deferred materials only). Up to [`MAX_FIN_LIGHTS`]
//! lights at once, any mix, each with its own [`FinShadowSettings`] (method,
//! layers, sub-layers, map resolution, refinement, falloff, overlap) and its own
//! [`FinLightStats`]. A light that sees no caster runs no extraction or map
//! pass (its visibility is 1). Past [`MAX_FIN_LIGHTS`], the lights that bring
//! the most light to the [`FinShadowView`] cameras keep fins (suns first, then
//! power over squared distance, a tenth for a light whose range is out of
//! every view; a light with fins keeps them against one up to 1.5× brighter);
//! the rest keep Bevy's shadows and report
//! [`FinDegradation::TooManyLights`].
//!
//! ## Cameras and meshes
//!
//! 3D cameras that show fin shadows carry [`FinShadowView`], which adds the
//! depth, normal and deferred prepasses the passes read; a camera without it
//! renders exactly as without the plugin. Forward (Bevy's default) and
//! deferred materials both get fin shadows, shaded by Bevy's own per-light
//! functions (how: `docs/ARCHITECTURE.md`). Every drawn mesh with a `Mesh3d`
//! casts and receives: opt out with [`NotFinShadowCaster`] or Bevy's
//! `NotShadowCaster`, and [`NotFinShadowReceiver`]. A hidden mesh casts
//! nothing, and a mesh casts only for lights whose `RenderLayers` it shares,
//! as in Bevy's own shadow maps. Skinned and morphed meshes cast in their
//! current pose (posed on the GPU, [`FinGpuPosing`]); alpha-masked ones are
//! cut out by their mask. Meshes fin shadows cannot reach (alpha-blended or
//! transmissive `StandardMaterial`s) are counted in [`FinReceivers`], said
//! once, and get Bevy's own hard shadow of the light ([`BevyShadowMapsKept`]).
//!
//! ## glTF scenes
//!
//! [`spawn_gltf_scene`] spawns one with Bevy's loader, its cameras off;
//! [`give_gltf_lights_fin_shadows`] gives its spot and directional lights fin
//! shadows with a physical radius from their `extras`. [`scene_snapshot`]
//! hands the casters as the plugin sees them to the core crate as a `Scene`,
//! for a CPU oracle or a ground truth of the same triangles.
//!
//! ## Methods
//!
//! - [`FinMethod::MultiLayer`] (the default): the paper's multi-layered
//!   shadow fins, extracted and rasterised on the GPU ([`FinExtraction::Cpu`]
//!   runs the core crate's extraction instead, as the paper does);
//!   `SingleLayer`, `OuterFins` and `Hard` are its simpler steps.
//! - [`FinMethod::Coverage`]: exact coverage with occluder fusion, within
//!   MAE 0.01 of ground truth where fins are not (overlapping occluders), at
//!   a cost that grows with the edges per pixel (`BENCHMARKS.md`).
//! - [`FinMethod::Convolution`] (Annen et al. 2008) and
//!   [`FinMethod::Plateaus`] (Haines 2001): peers, for comparison.
//!
//! ## Cost and memory
//!
//! A light's frame is rebuilt only when it, a caster, a setting or the budget
//! changed: a still scene's meshes are not walked ([`FinCasterScans`]), a
//! moved caster costs one record ([`FinCasterUpdates`]), only the casters
//! that moved are re-extracted ([`FinIncrementalExtraction`]) and only the
//! maps under them redrawn ([`FinPartialRedraw`]). The penumbra maps are
//! sparse (only the 8×8 tiles a caster or fin touches are stored), and the
//! budget ([`FinShadowBudget::map_bytes`]) is split between the lights' frames by
//! what their maps need. The GPU's output buffers start at a size guessed
//! from the scene and are resized when a read-back says a frame needed more
//! (or far less). Past it a light's maps lose resolution, then layers,
//! with every reason in its stats ([`FinFrameStats`], [`FinShadowStats`]).
//!
//! GPU time per pass is recorded under the diagnostic paths
//! `render/fin_shadows/extraction`, `render/fin_shadows/penumbra_maps`,
//! `render/fin_shadows/visibility` (the coverage method's per-pixel passes too),
//! `render/fin_shadows/coverage_lists` and `render/fin_shadows/composite` (add
//! Bevy's `RenderDiagnosticsPlugin`); extraction and maps only on frames where
//! something changed. [`FinShadowView::visibility_target`] (the first light)
//! and [`FinShadowView::light_visibility_targets`] (any light) copy the
//! visibility into images, for tests and the editor.
//!
//! How a frame flows through the plugin, stage by stage, and where each of
//! the paper's equations lives: `docs/ARCHITECTURE.md`.

mod bevy_shadow_maps;
mod budget;
mod casters;
mod forward_hook;
mod frame;
mod gltf;
mod gpu_layout;
mod hashing;
mod receivers;
mod render;
mod settings;
mod stats;

pub use bevy_shadow_maps::BevyShadowMapsKept;
pub use budget::{ByteSize, FinDegradation, FinDegradations, FinShadowBudget};
pub use casters::{
    FinCasterUpdates,
    cutout::{FinDefaultImageSampler, image_of_mask, mask_of_image},
    pose::FinGpuPosing,
    snapshot::{FinSceneSnapshot, FinSnapshotApproximation, FinSnapshotSkip, scene_snapshot},
};
pub use forward_hook::FinForwardShading;
pub use frame::{FinFrames, FinLightFrame, MAX_FIN_LIGHTS, update::FinCasterScans};
pub use gltf::{
    GltfLightsAdopted, GltfSceneLoading, descendants_with, first_line, give_gltf_lights_fin_shadows, gltf_light_radius,
    gltf_light_radius_or, spawn_gltf_scene,
};
pub use receivers::FinReceivers;
pub use settings::{
    FinIncrementalExtraction, FinLight, FinMethod, FinPartialRedraw, FinShadowSettings, FinShadowView, FinShadows,
    NotFinShadowCaster, NotFinShadowReceiver,
};
pub use shadow_fins;
pub use stats::{FinExtraction, FinFrameStats, FinLightStats, FinSceneError, FinShadowStats};

use bevy::prelude::*;

/// A flat-shaded Bevy mesh of a core-crate mesh (each triangle its own
/// vertices and face normal, so the normal prepass holds the facets the fins
/// are built from). For showing the core's scenes and glTF imports.
pub fn mesh_from_core(mesh: &shadow_fins::mesh::Mesh) -> Mesh {
    mesh_from_core_with_uvs(mesh, None)
}

/// [`mesh_from_core`] with one UV per vertex as `ATTRIBUTE_UV_0` (an
/// alpha-masked object's: `shadow_fins::cutout::Cutout::vertex_uvs`, its
/// material from [`image_of_mask`]).
pub fn mesh_from_core_with_uvs(mesh: &shadow_fins::mesh::Mesh, uvs: Option<&[shadow_fins::glam::Vec2]>) -> Mesh {
    use bevy::{
        asset::RenderAssetUsages,
        mesh::{Indices, PrimitiveTopology},
    };
    let mut out = Mesh::new(PrimitiveTopology::TriangleList, RenderAssetUsages::default()).with_inserted_attribute(
        Mesh::ATTRIBUTE_POSITION,
        mesh.positions().iter().map(|p| p.to_array()).collect::<Vec<_>>(),
    );
    if let Some(uvs) = uvs.filter(|uvs| uvs.len() == mesh.positions().len()) {
        out.insert_attribute(Mesh::ATTRIBUTE_UV_0, uvs.iter().map(|uv| uv.to_array()).collect::<Vec<_>>());
    }
    out.with_inserted_indices(Indices::U32(mesh.indices().to_vec()))
        .with_duplicated_vertices()
        .with_computed_flat_normals()
}

/// Adds fin shadows. See the crate docs.
#[derive(Default)]
pub struct ShadowFinsPlugin;

impl Plugin for ShadowFinsPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<FinLight>()
            .register_type::<FinShadows>()
            .register_type::<FinShadowSettings>()
            .register_type::<FinShadowView>()
            .register_type::<NotFinShadowCaster>()
            .register_type::<NotFinShadowReceiver>()
            .register_type::<FinShadowBudget>()
            .register_type::<FinGpuPosing>()
            .init_resource::<FinShadowBudget>()
            .init_resource::<FinGpuPosing>()
            .init_resource::<budget::FinDeviceLimits>()
            .add_systems(PostUpdate, turn_off_msaa_on_fin_views)
            .add_systems(PreUpdate, gltf::spawn_loaded_gltf_scenes)
            .add_observer(add_not_shadow_receiver)
            .add_observer(remove_not_shadow_receiver);
        frame::update::build(app);
        receivers::build(app);
        bevy_shadow_maps::build(app);
        render::build(app);
    }

    fn finish(&self, app: &mut App) {
        casters::cutout::finish(app);
        render::finish(app);
    }
}

/// Marks a `NotShadowReceiver` that [`NotFinShadowReceiver`] added, so that
/// removing the marker never removes one the user put there.
#[derive(Component)]
struct AddedForNotFinShadowReceiver;

fn add_not_shadow_receiver(
    add: On<Add, NotFinShadowReceiver>,
    has: Query<Has<bevy::light::NotShadowReceiver>>,
    mut commands: Commands,
) {
    if has.get(add.entity).is_ok_and(|has| !has) {
        commands.entity(add.entity).try_insert((bevy::light::NotShadowReceiver, AddedForNotFinShadowReceiver));
    }
}

fn remove_not_shadow_receiver(
    remove: On<Remove, NotFinShadowReceiver>,
    added: Query<(), With<AddedForNotFinShadowReceiver>>,
    mut commands: Commands,
) {
    if added.contains(remove.entity) {
        commands.entity(remove.entity).try_remove::<(bevy::light::NotShadowReceiver, AddedForNotFinShadowReceiver)>();
    }
}

/// Deferred rendering has no MSAA: turn it off on fin-shadowed cameras rather
/// than fail (told once).
fn turn_off_msaa_on_fin_views(mut views: Query<&mut Msaa, (With<FinShadowView>, Changed<Msaa>)>) {
    for mut msaa in &mut views {
        if *msaa != Msaa::Off {
            warn_once!("fin shadows: MSAA turned off on a FinShadowView camera (deferred rendering needs Msaa::Off)");
            *msaa = Msaa::Off;
        }
    }
}
