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
//! [`FinShadows`] on a Bevy `SpotLight` (a disk of the spot's `radius` facing
//! along its axis), `DirectionalLight` (the sun, as wide as its `SunDisk`'s
//! angular size, through orthographic maps), `RectLight` (its rectangle:
//! Bevy itself gives it no shadow at all) or `PointLight` (a sphere of its
//! `radius`, by six cube-face frames that fill one visibility layer), or the plugin's own
//! [`FinLight`] (a disk lighting the half-space it faces). Up to [`MAX_FIN_LIGHTS`] at once, any mix, each with
//! its own [`FinShadowSettings`] (method, layers, maps), its own frame
//! rebuilt only when it, a caster, the budget or the set of lights changed
//! (casters by Bevy's change detection: a still scene's meshes are not
//! walked and hashed, [`FinCasterScans`]; a caster that moved or was posed
//! again is rebuilt in its slot and only its instance record (with its
//! pose: a skinned or morphed caster is posed on the GPU from its joint
//! matrices and morph weights, `shaders/pose.wgsl`, [`FinFrameStats::posed_on_gpu`];
//! or its new geometry) goes up to the GPU, [`FinCasterUpdates`]; the GPU then
//! extracts only the casters that moved, keeping every other's records, when
//! the reference depth and the silhouettes' depth range stayed,
//! [`FinIncrementalExtraction`], and redraws its maps only under the casters
//! that moved when their plan stayed, [`FinPartialRedraw`]; a still scene
//! runs no read-back),
//! its own visibility layer per camera and its own [`FinLightStats`]. A light
//! only sees the casters in its range and in front of its disk: a light that
//! sees none runs no extraction or map pass (its visibility pass writes 1). The
//! penumbra-map budget ([`FinShadowBudget::map_bytes`]) is shared equally
//! between the frames (a point light's six faces take six shares); past it a
//! light's maps lose resolution, then layers, with the reason in its
//! stats. Meshes fin shadows cannot reach (alpha-blended or transmissive
//! `StandardMaterial`s) are counted in [`FinReceivers`], said once, and get
//! Bevy's hard shadow (below).
//!
//! ## Where fin shadows enter Bevy's lighting, and why there
//!
//! A fin-shadowed Bevy light stays in Bevy's light lists — Bevy shades it,
//! with its own colour, intensity, range, cone and BRDF — with its shadow
//! map turned off in the render world only (`render/bevy_lights.rs`; the
//! user's `shadow_maps_enabled` is untouched and comes back with the map
//! when `FinShadows` goes). Its visibility V then enters Bevy's shading of
//! it in two places, one per material path, both evaluated by *Bevy's own*
//! per-light functions, so the shading is Bevy's by construction:
//! - **deferred materials** (the G-buffer): the compositing pass, which
//!   replaces Bevy's deferred lighting pass on a [`FinShadowView`] camera,
//!   runs Bevy's `apply_pbr_lighting` and takes `(1 − V)` of the light's
//!   contribution away per pixel (`bevy_pbr::lighting::spot_light` /
//!   `point_light`, found by the light's index in Bevy's clustered list,
//!   `lighting::directional_light` or `lighting::rect_light`, found in the
//!   view's directional or rectangle lights by what Bevy uploaded for it),
//!   only where Bevy added it (the pixel's cluster list holds the light; the
//!   view's list holds the sun, which it does not on render layers the view
//!   does not see);
//! - **forward materials** (Bevy's default; opaque and alpha-masked
//!   `StandardMaterial`s, `render/forward.rs`): inside Bevy's forward
//!   fragment shader, naga_oil overrides of those same per-light functions
//!   multiply the light's contribution by V at the fragment's pixel, and of
//!   `shadows::fetch_*_shadow` make Bevy's own shadow of it 1. The override
//!   module is one import added to Bevy's `pbr_fragment` shader asset at run
//!   time, empty unless a pipeline asks for it; `StandardMaterial`'s
//!   main-pass pipelines get it, with bind group 4 (the visibility layers),
//!   through their specialisation and draw functions — a camera without
//!   fin shadows binds a group of no light and shades exactly as Bevy does.
//!
//! Why these hooks: shading the light ourselves (as [`FinLight`] still is)
//! drifts from Bevy's BRDF with every upgrade; a screen-space pass after
//! Bevy's lighting has no BRDF inputs for a forward material; Bevy 0.19 gives
//! a plugin no binding in its mesh view group. What a Bevy upgrade can break
//! is named in `render/forward.rs` and pinned by `tests/render/forward.rs`
//! and `bevy_renderer.rs`. The plugin does not make deferred (or anything)
//! the app's default. Meshes fin shadows cannot reach ([`FinReceivers`]:
//! alpha-blended and transmissive ones, drawn over pixels the visibility
//! pass shaded for the surface behind) get Bevy's own hard shadow of the
//! light instead of none (a `RectLight` has none in Bevy), and a camera
//! without [`FinShadowView`] renders exactly as without the plugin: while
//! either exists, Bevy's shadow map of a fin-shadowed light stays on
//! ([`BevyShadowMapsKept`]) and both hooks replace Bevy's shadow `S` of the
//! light by `V` on the pixels they reach — the compositing pass gives the
//! light `(V − S)` of Bevy's contribution (`S` being Bevy's own
//! `shadows::fetch_*_shadow`, contact shadows too), the forward hook makes
//! `S` 1 — so a fin camera shows the same fin shadow either way.

//! Every drawn mesh with a `Mesh3d` casts and receives (opt out with
//! [`NotFinShadowCaster`] or Bevy's `NotShadowCaster`, and
//! [`NotFinShadowReceiver`]; a mesh hidden by `Visibility` casts nothing;
//! a mesh casts only for lights whose `RenderLayers` it shares, as in Bevy's
//! own shadow maps — without the component both are on layer 0); materials are
//! unchanged. [`scene_snapshot`] hands that set to the core crate as a
//! `Scene` (what a CPU oracle or ground truth of the world must trace: a
//! glTF as Bevy spawned it, say), and [`give_gltf_lights_fin_shadows`] gives
//! a spawned glTF's spot and directional lights fin shadows with a physical
//! radius from their `extras` (Bevy 0.19's loader sets a spot's to its range).
//! [`spawn_gltf_scene`] spawns one with Bevy's loader, its cameras off. 3D cameras that show fin-shadowed scenes carry
//! [`FinShadowView`], which adds the depth, normal and deferred prepasses the
//! visibility and compositing passes read. Forward materials are not lit by
//! a [`FinLight`] (it has no Bevy counterpart whose shading to hook).
//!
//! Stages, per light, per frame and only when something moved or a setting changed:
//! 1. **fin extraction and layer assignment** in compute passes
//!    (`shaders/extract_*.wgsl`): per-face facing test, patches (connected
//!    light-facing regions) by a lock-free union-find, per-edge silhouette test
//!    appending oriented edges, fins and fans appended per silhouette edge and
//!    vertex, the sub-layer histogram of edge depths (atomics), its prefix sum
//!    cut at the k/N quantiles, every fin and caster given its patch's layer,
//!    and the indirect dispatch arguments of the map passes — all on the GPU.
//!    An alpha-masked caster is packed with the outline of its opaque region
//!    (its silhouettes) and its faces' UVs (its map casters' cut-outs).
//!    Caster geometry is uploaded once per mesh; when something moves only the
//!    instance transforms go up. The counts come back a few frames later in
//!    [`FinShadowStats`]; output buffers start at a size guessed from the
//!    scene and grow (the frame is redone) when a read-back says a frame
//!    needed more. [`FinExtraction::Cpu`] runs the core crate instead, as the
//!    paper does, and is what the GPU path is tested against;
//! 2. **penumbra maps** on the GPU: compute passes rasterise every layer's slab
//!    depth and its inner and outer fin extremes into one storage buffer, texel
//!    for texel the core's raster oracle;
//! 3. **visibility** per camera and light: a compute pass reads the depth and
//!    normal prepass and combines the layers (refinement, overlap rule,
//!    falloff) into that light's layer of the camera's illuminance buffer,
//!    which [`FinShadowView::visibility_target`] (first light) and
//!    [`FinShadowView::light_visibility_targets`] (any light) copy into images
//!    (tests, the editor);
//! 4. **compositing** per camera: Bevy's deferred lighting of the G-buffer,
//!    then per light `V` applied to its direct light (see above), in one pass
//!    that replaces Bevy's deferred lighting pass; forward materials apply
//!    `V` in Bevy's forward pass itself (the forward hook, above).
//!
//! [`FinMethod::Coverage`] replaces stages 1–3 by exact coverage with occluder
//! fusion (`shadow_fins::coverage`): on the CPU, when something moved, the
//! potential silhouette edges of the light's disk, binned into light-space
//! cells by penumbra footprint and culled where no receiver of the cell can
//! see them as a silhouette, plus a short per-cell list for the reference
//! count (`frame/coverage.rs`, `shadow_fins::coverage::index`); on the GPU
//! (`shaders/coverage_lists.wgsl`) per-texel depth lists of every caster (24
//! near, 6 far depths, the total), then per camera pixel one dispatch
//! (`shaders/coverage.wgsl`): the reference count from those lists and the
//! per-sample count changes of the cell's edges over up to 256 light samples
//! in 32-sample words, in one walk over each list (llvmpipe stops a shader
//! after 65535 loop iterations; GPU watchdogs stop long ones). The same
//! visibility buffer and compositing follow. It is within 0.001 MAE of its
//! CPU oracle and meets MAE ≤ 0.01 against ground truth where fins cannot
//! (assets of many overlapping parts), at a cost that grows with the edges
//! per pixel (2.5–37× the fins' frame on lavapipe, `BENCHMARKS.md`): fins
//! stay the default.
//!
//! [`FinMethod::Convolution`] (Annen et al. 2008, the filtering peer) keeps
//! stages 1–2 of the hard shadow map and replaces 3: after the map passes
//! draw the map, `shaders/convolution_maps.wgsl` finds its nearest depth,
//! expands each texel's normalised depth into `1 + 4M` Fourier basis images
//! (`convolution_order` `M`) and builds their mip chain (the finest levels
//! dropped, with a warning, past the device's storage limit); per camera
//! pixel `shaders/convolution.wgsl` averages the blockers' depth over the
//! light's footprint (CSM-Z), sizes the penumbra from it and filters the
//! reconstructed shadow test over that footprint — as
//! `shadow_fins::peers::convolution` with mipmaps, which its tests hold it
//! to. Its cost does not grow with the casters, and it sees one depth per
//! texel (stacked casters fuse, contact shadows lift: `BENCHMARKS.md`).
//!
//! With no caster at all, neither extraction nor map passes run, and the
//! visibility pass writes 1 without reading the prepass.
//!
//! GPU time per pass is recorded under the diagnostic paths
//! `render/fin_shadows/extraction`, `render/fin_shadows/penumbra_maps`,
//! `render/fin_shadows/visibility` (the coverage method's per-pixel passes too),
//! `render/fin_shadows/coverage_lists` and `render/fin_shadows/composite` (add
//! Bevy's `RenderDiagnosticsPlugin`); extraction and maps only on frames where
//! something changed.

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
