//! Main world: the fin-shadowed lights and their casters, turned into one
//! [`FinLightFrame`] per light, each rebuilt only when a caster, that light or
//! its settings changed.
//!
//! With [`FinExtraction::Gpu`] (the default) the frame holds the packed caster
//! geometry (built once per mesh) and one transform per caster instance; the
//! render world's compute passes do the rest. With [`FinExtraction::Cpu`] the
//! core crate extracts silhouettes, patches, fins and layers here and the frame
//! holds the map-space casters and fins.

use std::{
    collections::{HashMap, HashSet},
    f32::consts::FRAC_PI_2,
    hash::{Hash, Hasher},
    sync::Arc,
};

use bevy::{
    asset::AssetId,
    camera::{primitives::Aabb, visibility::RenderLayers},
    light::SunDisk,
    math::DVec3,
    mesh::{Indices, Mesh, PrimitiveTopology, VertexAttributeValues},
    prelude::*,
    render::{extract_resource::ExtractResource, sync_world::RenderEntity},
};
use shadow_fins::{
    fins::{Fin, FinShape, FinSide},
    light::{Aperture, CubeFace, DiskLight, Light, LightFrame, RectLight as RectArea, SphereLight, SunLight},
    mesh::{Mesh as CoreMesh, Topology},
    oracle::{FinShadowModel, MapRegion, MapTriangle},
    scene::{LightSpaceScene, Scene, SceneObject},
};

use crate::{
    budget::{FinDegradation, FinDeviceLimits, FinShadowBudget, FinShadowsUnsupported, allocate_maps},
    casters::{CasterScene, CasterSignature, FinCasterUpdates, SlotSources},
    coverage_frame::{CoverageFrame, coverage_frame},
    gpu_scene::{GpuCapacity, GpuMeshGeometry, GpuPose, GpuScene, GpuSceneBuilder},
    light::{FinExtraction, FinLight, FinMethod, FinShadowSettings, FinShadowView, FinShadows, NotFinShadowCaster},
    sun_fit,
};

/// Why a mesh could not be used as a caster (logged once per mesh).
#[derive(Debug, Clone, PartialEq)]
pub enum FinSceneError {
    /// The mesh is not a triangle list (lines, points) — it casts nothing.
    NotTriangles,
    /// The mesh's data was sent to the GPU only (`RenderAssetUsages::RENDER_WORLD`).
    NoMainWorldData,
    /// Invalid geometry (NaN positions, bad indices, no area): the core's error.
    Invalid(shadow_fins::MeshError),
}

/// Counts of what the current frame models.
///
/// With GPU extraction, silhouettes, fins and layers are read back from the
/// GPU a few frames later; `up_to_date` says whether they belong to the latest
/// frame. Read them from the [`FinShadowStats`] resource.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FinFrameStats {
    pub casters: usize,
    pub triangles: usize,
    pub silhouettes: usize,
    pub fins: usize,
    pub layers: usize,
    /// Main-world CPU time of building the frame, ms: the whole extraction on
    /// the CPU path; packing instance transforms on the GPU path.
    pub extract_ms: f32,
    /// The counts describe the current frame (always true on the CPU path).
    pub up_to_date: bool,
    /// Why the frame models less than the settings ask for (a GPU limit or the
    /// [`FinShadowBudget`](crate::FinShadowBudget)); `None` when nothing was cut.
    pub degraded: Option<FinDegradation>,
    /// The penumbra maps' resolution as allocated.
    pub map_resolution: u32,
    /// Where the fins were extracted: the settings' choice, or the CPU when
    /// the scene's geometry did not fit a GPU buffer (see `degraded`).
    pub extraction: FinExtraction,
    /// The GPU extraction's last map update redrew only the texels under the
    /// casters that moved (their old and new footprints): a few casters of
    /// many moved, and the maps' plan (region, reference depth, layer
    /// planes) stayed. `false`: redrawn whole, or extracted on the CPU.
    pub partial_redraw: bool,
    /// Texels (all layers) of the penumbra maps the last update cleared and
    /// drew again: all of them on a full redraw (every update of the CPU
    /// extraction), a partial redraw's few; 0 for the coverage method (no
    /// penumbra maps).
    pub redrawn_texels: u64,
    /// The GPU extraction's last update extracted only the casters that
    /// moved, and kept every other caster's silhouettes, fins and map
    /// triangles from before (`extract.wgsl`): a few moved, and the
    /// reference depth and the silhouettes' depth range stayed. `false`:
    /// everything extracted anew, or on the CPU.
    pub incremental_extraction: bool,
    /// Skinned or morphed casters the GPU posed itself (`pose.wgsl`): a new
    /// pose of one of them is a changed instance, like a moved caster. The
    /// others posed are posed on the CPU (the CPU extraction, or a pose that
    /// changes the mesh's topology; see `extract::posed_mesh`). Counted per
    /// light frame, with those out of the light's reach (their vertices
    /// still bound the receivers' depth); a point light's faces: the most.
    pub posed_on_gpu: usize,
}

/// What the first fin-shadowed light's shadows currently model (see
/// [`FinFrameStats`]); every light's are in its [`FinLightStats`].
#[derive(Resource, Debug, Clone, Copy, Default, PartialEq)]
pub struct FinShadowStats(pub FinFrameStats);

/// One caster triangle in light-map space (see the core's `MapTriangle`).
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct GpuCaster {
    pub corners: [f32; 6],
    pub normal: [f32; 3],
    pub offset: f32,
    pub min_depth: f32,
    pub max_depth: f32,
    pub layer: u32,
    /// 0: solid; else 1 + its index in the frame's [`GpuCutout`]s.
    pub cutout: u32,
    /// The GPU extraction's patch of the caster (`extract.wgsl`); 0 here.
    pub patch_id: u32,
}

/// An alpha-masked map triangle's cut-out (the core's `MapCutout`;
/// `cutout.wgsl`): UVs at its corners, the corners' depths, and where its
/// mask starts in the frame's mask words.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct GpuCutout {
    pub uvs: [f32; 6],
    pub depths: [f32; 3],
    pub mask: u32,
}

/// The cut-outs and masks of a frame, or none when they do not fit one GPU
/// buffer (every caster then solid, and said so): the masks a frame's
/// instances share are packed once, so only thousands of distinct masks
/// get here.
pub(crate) fn fit_cutouts(
    casters: &mut [GpuCaster],
    cutouts: &mut Vec<GpuCutout>,
    mask_words: &mut Vec<u32>,
    max_buffer: u64,
) -> Option<FinDegradation> {
    let bytes = (size_of_val(cutouts.as_slice()) as u64).max(size_of_val(mask_words.as_slice()) as u64);
    if bytes <= max_buffer {
        return None;
    }
    let wanted = cutouts.len() as u32;
    casters.iter_mut().for_each(|c| c.cutout = 0);
    cutouts.clear();
    mask_words.clear();
    Some(FinDegradation::Capacity {
        buffer: "alpha masks (casters made solid)",
        kept: 0,
        wanted,
        limit_bytes: max_buffer,
    })
}

/// Appends `m` to `words` as `cutout.wgsl` reads a mask: a header (width,
/// height, threshold bits, wrap modes and filter), then four 8-bit alphas a
/// word. Returns the word it starts at.
pub(crate) fn pack_mask(m: &shadow_fins::cutout::AlphaMask, words: &mut Vec<u32>) -> u32 {
    let at = words.len() as u32;
    let code = |a: shadow_fins::cutout::Address| match a {
        shadow_fins::cutout::Address::Repeat => 0u32,
        shadow_fins::cutout::Address::MirroredRepeat => 1,
        shadow_fins::cutout::Address::ClampToEdge => 2,
    };
    let [u, v] = m.address();
    let nearest = (m.filter() == shadow_fins::cutout::Filter::Nearest) as u32;
    words.extend([m.width(), m.height(), m.threshold().to_bits(), code(u) | code(v) << 8 | nearest << 16]);
    words.extend(m.alpha().chunks(4).map(|q| q.iter().enumerate().fold(0u32, |w, (k, &a)| w | (a as u32) << (8 * k))));
    at
}

/// Map triangles as the GPU reads them, with their cut-outs and the masks
/// those index, packed as `cutout.wgsl` reads them (`layers`: each
/// triangle's layer, or layer 0).
pub(crate) fn gpu_casters(
    triangles: &[MapTriangle],
    layers: Option<&[u32]>,
    masks: &[std::sync::Arc<shadow_fins::cutout::AlphaMask>],
) -> (Vec<GpuCaster>, Vec<GpuCutout>, Vec<u32>) {
    // Each mask once (`pack_mask`).
    let mut mask_words: Vec<u32> = Vec::new();
    let mut mask_at: Vec<Option<u32>> = vec![None; masks.len()];
    let mut cutouts = Vec::new();
    let casters = triangles
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let cutout = match t.cutout {
                None => 0,
                Some(c) => {
                    let at = *mask_at[c.mask as usize]
                        .get_or_insert_with(|| pack_mask(&masks[c.mask as usize], &mut mask_words));
                    cutouts.push(GpuCutout {
                        uvs: [c.uvs[0].x, c.uvs[0].y, c.uvs[1].x, c.uvs[1].y, c.uvs[2].x, c.uvs[2].y],
                        depths: c.depths,
                        mask: at,
                    });
                    cutouts.len() as u32
                }
            };
            GpuCaster {
                corners: [
                    t.corners[0].x,
                    t.corners[0].y,
                    t.corners[1].x,
                    t.corners[1].y,
                    t.corners[2].x,
                    t.corners[2].y,
                ],
                normal: t.normal.to_array(),
                offset: t.offset,
                min_depth: t.min_depth,
                max_depth: t.max_depth,
                layer: layers.map_or(0, |l| l[i]),
                cutout,
                patch_id: 0,
            }
        })
        .collect();
    (casters, cutouts, mask_words)
}

/// One fin: `header = [kind (0 quad, 1 sector), side (0 inner, 1 outer), layer,
/// the GPU extraction's patch (0 here)]`,
/// then the shape's numbers (see `maps.wgsl`).
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct GpuFin {
    pub header: [u32; 4],
    pub data: [f32; 12],
}

/// Everything the GPU passes need for one frame, shared with the render world.
#[derive(Debug)]
pub struct FinFrameData {
    /// Bumped whenever the content changed, so the GPU re-uploads only then.
    pub generation: u64,
    pub stats: FinFrameStats,
    pub(crate) casters: Vec<GpuCaster>,
    /// The casters' cut-outs and the alpha masks they read (`cutout.wgsl`).
    pub(crate) cutouts: Vec<GpuCutout>,
    pub(crate) mask_words: Vec<u32>,
    pub(crate) fins: Vec<GpuFin>,
    pub(crate) region: MapRegion,
    /// Map layers allocated (what fits the budget; the GPU merges the deepest
    /// layers beyond it).
    pub(crate) map_layers: u32,
    /// The largest buffer this frame was built for, bytes.
    pub(crate) limit_bytes: u64,
    /// The most the penumbra maps may take, bytes (`FinShadowBudget::map_bytes`).
    pub(crate) map_limit_bytes: u64,
    /// World → light frame: origin and axes (u, v, n), in f64 so that each
    /// camera's view → light transform is composed without losing precision far
    /// from the world origin.
    pub(crate) origin: DVec3,
    pub(crate) axes: [DVec3; 3],
    /// The light's size: the disk's radius `R` (a rectangle's bounding
    /// circle's), or the sun's `tan θ`.
    pub(crate) size: f32,
    /// Where in that circle the light is: a rectangle's fins are as wide as
    /// its support function across them (`extract.wgsl`'s `support`).
    pub(crate) aperture: Aperture,
    /// The sun's orthographic maps (`x, y` in world units); else perspective
    /// maps from the disk's centre (`x/L, y/L`).
    pub(crate) orthographic: bool,
    pub(crate) reference_depth: f32,
    pub(crate) near: f32,
    pub(crate) scene_extent: f32,
    pub(crate) settings: FinShadowSettings,
    /// GPU extraction: geometry, instances and buffer capacities (`None` on the CPU path).
    pub(crate) gpu: Option<GpuScene>,
    /// The coverage method's edges, grid, casters and samples (`None` for fins).
    pub(crate) coverage: Option<CoverageFrame>,
    /// The plateaus method's plane, cones and sheets (`None` for other methods).
    pub(crate) plateaus: Option<crate::plateau_frame::PlateauFrame>,
    /// The convolution method's basis chain as the budget allows it (`None`
    /// for other methods, or when it does not fit).
    pub(crate) convolution: Option<crate::budget::BasisLayout>,
    /// The maps are a window onto casters that go on past it (a sun fitted
    /// to the views), not a cover of every caster.
    pub(crate) windowed: bool,
}

impl FinFrameData {
    /// A point light's sphere radius (the frame's `size` is the circle
    /// around its outline over the face, `stretch` times it); `None` for
    /// any other light.
    pub(crate) fn sphere_radius(&self) -> Option<f32> {
        match self.aperture {
            Aperture::Sphere { stretch, .. } => Some(self.size / stretch),
            _ => None,
        }
    }
}

/// The most lights with fin shadows at once. Lights past it (by entity
/// order) keep Bevy's own shadow map, with [`FinDegradation::TooManyLights`]
/// in their [`FinLightStats`].
pub const MAX_FIN_LIGHTS: usize = 16;

/// The most frames (map sets) at once: a `PointLight` has one per cube face.
pub(crate) const MAX_FIN_FRAMES: usize = 6 * MAX_FIN_LIGHTS;

/// How a fin-shadowed light is shaded by the compositing pass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum LightShading {
    /// The plugin's own [`FinLight`]: shaded by the compositing pass (Bevy's
    /// point-light BRDF in the half-space the disk faces), times `V`.
    Own { light: FinLight, transform: GlobalTransform },
    /// A Bevy light: Bevy shades it (its shadow map is off, see
    /// `render/bevy_lights.rs`); the compositing pass takes `(1 − V)` of
    /// Bevy's own contribution of it away again. The render-world entity
    /// finds its index in Bevy's clustered light list.
    Bevy { render_entity: Entity },
}

/// One frame of a fin-shadowed light: a light's maps, extraction and
/// visibility pass. A `PointLight` has six, one per cube face, which shade
/// the receivers in their own frusta into the light's one visibility layer.
#[derive(Debug, Clone)]
pub struct FinLightFrame {
    /// The light's (main-world) entity.
    pub light: Entity,
    /// The cube face of a point light's frame (`None` for any other light).
    pub face: Option<CubeFace>,
    /// The light's visibility layer in every camera's illuminance buffer
    /// (its index among the fin-shadowed lights, by entity order).
    pub layer: usize,
    /// The light as the core crate models it (its disk, rectangle, sun or
    /// sphere): what an oracle or a ground truth of this light should be given.
    pub shape: Light,
    pub(crate) shading: LightShading,
    pub data: Arc<FinFrameData>,
}

impl FinLightFrame {
    pub(crate) fn key(&self) -> FrameKey {
        (self.light, self.face)
    }
}

/// A frame's identity: its light, and its cube face for a point light.
pub(crate) type FrameKey = (Entity, Option<CubeFace>);

/// Every fin-shadowed light's frames, by entity order (at most
/// [`MAX_FIN_LIGHTS`] lights; a point light's six faces one after another).
/// Each frame has its own maps and layers, each light its own visibility
/// layer; the penumbra-map budget is shared equally between the frames.
#[derive(Resource, Clone, Default, ExtractResource)]
pub struct FinFrames(pub Vec<FinLightFrame>);

impl FinFrames {
    /// How many visibility layers the frames fill: one per light.
    pub fn light_count(&self) -> usize {
        self.0.last().map_or(0, |f| f.layer + 1)
    }

    /// The frames of visibility layer `layer`.
    pub(crate) fn of_layer(&self, layer: usize) -> impl Iterator<Item = (usize, &FinLightFrame)> {
        self.0.iter().enumerate().filter(move |(_, f)| f.layer == layer)
    }

    /// True when `slot` is the last frame of its light (its layer is complete
    /// once that frame's visibility pass ran).
    pub(crate) fn ends_layer(&self, slot: usize) -> bool {
        self.0.get(slot).is_some_and(|f| self.0.get(slot + 1).is_none_or(|n| n.layer != f.layer))
    }

    /// The lights on the coverage method (`true`) or on a fin method (`false`):
    /// each set has its own GPU resources (`render/coverage.rs`, `render/mod.rs`).
    pub(crate) fn on_coverage(&self, coverage: bool) -> impl Iterator<Item = &FinLightFrame> {
        self.0.iter().filter(move |f| f.data.coverage.is_some() == coverage)
    }
}

/// What one light's fin shadows currently model: on every light with
/// [`FinShadowSettings`] (the first light's is also the [`FinShadowStats`]
/// resource).
#[derive(Component, Debug, Clone, Copy, Default, PartialEq)]
pub struct FinLightStats(pub FinFrameStats);

pub(crate) type CachedMesh = Result<(Arc<CoreMesh>, Arc<Topology>, Arc<GpuMeshGeometry>), FinSceneError>;

/// Per light: what its frame was built from and the GPU extraction's state.
#[derive(Default)]
pub(crate) struct LightState {
    signature: u64,
    gpu: GpuSceneBuilder,
    /// GPU buffer sizes, grown when a read-back says a frame overflowed them.
    pub(crate) capacity: Option<GpuCapacity>,
    pub(crate) capacity_epoch: u64,
    /// What the latest GPU read-back said did not fit (kept into new frames).
    pub(crate) shortfall: Option<FinDegradation>,
    /// The degradation last warned about.
    pub(crate) warned: Option<FinDegradation>,
    /// A sun's map window in its last frame (`sun_fit::sun_window` keeps it
    /// while it still fits).
    window: Option<[f32; 4]>,
    /// What this frame models now (a light's stats combine its frames').
    pub(crate) stats: FinFrameStats,
    /// The objects as this light saw them in its last frame.
    built: Option<LightBuild>,
}

/// The objects one light's last frame was built from, kept so that the next
/// frame recomputes only the slots the scene's update changed.
struct LightBuild {
    /// The [`CasterScene::version`] they were seen from.
    scene_version: u64,
    /// The light's own part of the signature they were seen with.
    light_part: u64,
    /// The frame they were culled in, and the one the GPU records were made
    /// in (a sun fitted to the views moves it; `None`: not on the GPU).
    seen_frame: LightFrame,
    gpu_frame: Option<LightFrame>,
    objects: Vec<SceneObject>,
}

/// What one light's frame is asked for.
struct FrameAsked<'a> {
    light: Light,
    face: Option<CubeFace>,
    window: Option<[f32; 4]>,
    sees: LightSees<'a>,
    settings: FinShadowSettings,
    /// The light's own part of its frame's signature (not the casters').
    light_part: u64,
}

/// How many times the frame builder has walked every mesh to sign the
/// casters. Only what may change every caster at once walks: a mesh asset
/// loading, edited or removed, a material's cut-out changing, a skin's bind
/// poses loading, a sun starting or stopping to fit the views. A caster that
/// moved, appeared, went, was hidden or shown, or changed its layers, shadow
/// flags or material is signed alone ([`FinCasterUpdates`](crate::FinCasterUpdates)
/// counts the ones rebuilt in place), so a still scene — or one where a few
/// casters move — costs no walk however many entities it holds (Bevy's change
/// ticks are still checked per entity; issue 16's "big scenes that move"; a
/// diagnostic).
#[derive(Resource, Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FinCasterScans(pub u64);

/// What tells the frame builder that a caster changed since the last frame.
#[derive(bevy::ecs::system::SystemParam)]
struct CasterChanges<'w, 's> {
    #[allow(clippy::type_complexity)]
    changed: Query<
        'w,
        's,
        Entity,
        (
            With<Mesh3d>,
            Or<(
                Changed<GlobalTransform>,
                Changed<Mesh3d>,
                Changed<InheritedVisibility>,
                Changed<RenderLayers>,
                // Bevy rewrites a skinned mesh's box every frame; its pose
                // (`poses`) says whether the caster changed.
                (Changed<Aabb>, Without<bevy::camera::visibility::DynamicSkinnedMeshBounds>),
                Added<bevy::light::NotShadowCaster>,
                Added<NotFinShadowCaster>,
                // What poses it (a skin or morph weights arriving or swapped).
                Changed<bevy::mesh::skinning::SkinnedMesh>,
                Changed<bevy::mesh::morph::MeshMorphWeights>,
                // What it casts with (its material id is in its signature).
                Changed<MeshMaterial3d<StandardMaterial>>,
            )>,
        ),
    >,
    removed_meshes: RemovedComponents<'w, 's, Mesh3d>,
    removed_not_shadow: RemovedComponents<'w, 's, bevy::light::NotShadowCaster>,
    removed_not_fin: RemovedComponents<'w, 's, NotFinShadowCaster>,
    removed_layers: RemovedComponents<'w, 's, RenderLayers>,
    removed_boxes: RemovedComponents<'w, 's, Aabb>,
    removed_transforms: RemovedComponents<'w, 's, GlobalTransform>,
    removed_visibility: RemovedComponents<'w, 's, InheritedVisibility>,
    removed_materials: RemovedComponents<'w, 's, MeshMaterial3d<StandardMaterial>>,
    scans: ResMut<'w, FinCasterScans>,
    updates: ResMut<'w, FinCasterUpdates>,
    kept: Local<'s, CasterSignature>,
    /// Skinned and morphed casters, posed as Bevy draws them.
    poses: crate::pose::Poses<'w, 's>,
}

impl CasterChanges<'_, '_> {
    /// The mesh entities that changed since the last call: changed or
    /// removed components, and the posed casters whose pose may have changed
    /// (the removal readers are drained either way).
    fn take_changed(&mut self) -> HashSet<Entity> {
        let mut changed: HashSet<Entity> = self.changed.iter().collect();
        changed.extend(self.removed_meshes.read());
        changed.extend(self.removed_not_shadow.read());
        changed.extend(self.removed_not_fin.read());
        changed.extend(self.removed_layers.read());
        changed.extend(self.removed_boxes.read());
        changed.extend(self.removed_transforms.read());
        changed.extend(self.removed_visibility.read());
        changed.extend(self.removed_materials.read());
        changed.extend(self.poses.changed_poses());
        changed
    }
}

#[derive(Resource, Default)]
pub(crate) struct MeshCache {
    meshes: HashMap<AssetId<Mesh>, CachedMesh>,
    /// Bumped for every frame built, for every light: a read-back's
    /// generation names one light's one frame.
    generation: u64,
    /// Posed casters (skinned, morphed), per entity with its pose's hash:
    /// rebuilt when the pose changed.
    posed: HashMap<Entity, PosedCaster>,
    /// Per skinned or morphed mesh, its topology at rest packed with what
    /// poses it on the GPU (`None`: it cannot be posed there).
    posable: HashMap<AssetId<Mesh>, Option<Arc<GpuMeshGeometry>>>,
    /// [`FinGpuPosing`](crate::FinGpuPosing) as the posed casters were posed.
    gpu_posing: bool,
    pub(crate) lights: HashMap<FrameKey, LightState>,
    /// The `CutoutCache` generation the frames were built with.
    cutout_generation: u64,
    /// The casters as the last frames were built from (`casters.rs`):
    /// updated in place when only some casters changed.
    scene: Option<CasterScene>,
}

pub(crate) fn build(app: &mut App) {
    app.init_resource::<FinFrames>()
        .init_resource::<MeshCache>()
        .init_resource::<crate::cutout::CutoutCache>()
        .init_resource::<FinShadowStats>()
        .init_resource::<FinCasterScans>()
        .init_resource::<FinCasterUpdates>()
        .add_systems(
            PostUpdate,
            (update_fin_frames, mirror_first_light_stats)
                .chain()
                .in_set(FinFramesUpdate)
                .after(TransformSystems::Propagate)
                // A sun's window reads this frame's boxes and camera projections.
                .after(bevy::camera::visibility::VisibilitySystems::CalculateBounds)
                .after(bevy::camera::visibility::VisibilitySystems::VisibilityPropagate)
                .after(bevy::camera::CameraUpdateSystems),
        );
}

/// Where every fin-shadowed light's frame is rebuilt (`PostUpdate`).
#[derive(bevy::ecs::schedule::SystemSet, Debug, Clone, PartialEq, Eq, Hash)]
pub(crate) struct FinFramesUpdate;

/// A light asking for fin shadows, as the frame builder sees it.
struct LightSource {
    entity: Entity,
    /// A disk (`FinLight`, `SpotLight`), a rectangle (`RectLight`), the
    /// sun (`DirectionalLight`) or a sphere (`PointLight`).
    light: Light,
    reach: Reach,
    settings: FinShadowSettings,
    shading: LightShading,
    /// A sun's maps fitted to what the cameras see (`sun_fit`), in its axes.
    window: Option<[f32; 4]>,
    /// The light's `RenderLayers`: only casters on a layer it shares cast
    /// for it, as in Bevy's own shadow maps.
    layers: RenderLayers,
}

/// The lights with fin shadows: `FinLight`s, and Bevy `SpotLight`s,
/// `DirectionalLight`s, `RectLight`s and `PointLight`s with [`FinShadows`],
/// by entity order; and the entities of those whose position or direction
/// is not finite (they shadow nothing).
fn light_sources(
    fin_lights: &Query<(Entity, &FinLight, &FinShadowSettings, &GlobalTransform)>,
    spot_lights: &SpotLights,
    directional_lights: &DirectionalLights,
    others: &OtherLights,
) -> (Vec<LightSource>, Vec<Entity>) {
    let rect_lights = &others.rects;
    // Not `GlobalTransform::forward`: it panics (debug) on a zero scale; the
    // core's lights reject a direction of no length instead.
    let forward = |t: &GlobalTransform| Vec3::from(t.affine().matrix3 * bevy::math::Vec3A::NEG_Z);
    let disk = |t: &GlobalTransform, radius: f32| DiskLight::new(t.translation(), forward(t), radius);
    let finite = |x: f32| if x.is_finite() && x > 0.0 { x } else { 0.0 };
    let own = fin_lights.iter().map(|(entity, light, settings, transform)| {
        let source = |disk| LightSource {
            entity,
            light: Light::Disk(disk),
            reach: Reach { range: finite(light.range), cone: None },
            settings: settings.clamped(),
            shading: LightShading::Own { light: *light, transform: *transform },
            window: None,
            layers: RenderLayers::default(),
        };
        disk(transform, light.effective_radius()).map(source).map_err(|_| entity)
    });
    // An entity with both a FinLight and a SpotLight is the FinLight (one slot).
    let spots = spot_lights.iter().filter(|l| l.5 && !fin_lights.contains(l.0)).filter_map(
        |(entity, spot, settings, transform, render, _)| {
            let settings = settings?.clamped();
            let source = |disk| LightSource {
                entity,
                light: Light::Disk(disk),
                // Bevy lights nothing past the outer angle (its spot attenuation).
                reach: Reach { range: finite(spot.range), cone: Some(spot.outer_angle.clamp(0.0, FRAC_PI_2)) },
                settings,
                shading: LightShading::Bevy { render_entity: render.id() },
                window: None,
                layers: RenderLayers::default(),
            };
            Some(disk(transform, finite(spot.radius)).map(source).map_err(|_| entity))
        },
    );
    let suns = directional_lights.iter().filter(|l| l.6 && !fin_lights.contains(l.0)).filter_map(
        |(entity, _, sun_disk, settings, transform, render, _)| {
            let settings = settings?.clamped();
            let sun = SunLight::new(forward(transform), sun_angular_radius(sun_disk)).map_err(|_| entity);
            Some(sun.map(|sun| LightSource {
                entity,
                light: Light::Sun(sun),
                reach: Reach { range: 0.0, cone: None },
                settings,
                shading: LightShading::Bevy { render_entity: render.id() },
                window: None,
                layers: RenderLayers::default(),
            }))
        },
    );
    // Bevy's rectangle spans its local X (width) and Y (height), scaled as
    // Bevy scales it (`ExtractedRectLight`), and faces local −Z.
    let rects = rect_lights.iter().filter(|l| l.5 && !fin_lights.contains(l.0)).filter_map(
        |(entity, rect, settings, transform, render, _)| {
            let settings = settings?.clamped();
            let m = transform.affine().matrix3;
            let size = |s: f32, axis: bevy::math::Vec3A| finite(s) * axis.length();
            if !(size(rect.width, m.x_axis) * size(rect.height, m.y_axis) > 0.0) {
                // Fin shadows of a 0 × 0 rectangle are the hard shadow; Bevy's
                // own shading divides the light's power by its area.
                warn_once!(
                    "fin shadows: a RectLight of zero area: Bevy shades it as infinitely bright (NaN on screen); \
                     give it a width and height > 0"
                );
            }
            let area = RectArea::new(
                transform.translation(),
                forward(transform),
                Vec3::from(m.x_axis),
                size(rect.width, m.x_axis),
                size(rect.height, m.y_axis),
            );
            Some(
                area.map(|area| LightSource {
                    entity,
                    light: Light::Rect(area),
                    reach: Reach { range: finite(rect.range), cone: None },
                    settings,
                    shading: LightShading::Bevy { render_entity: render.id() },
                    window: None,
                    layers: RenderLayers::default(),
                })
                .map_err(|_| entity),
            )
        },
    );
    // A point light is a sphere of its radius at its position (Bevy shades
    // it so: `PointLight::radius`, its representative-point specular).
    let points = others.points.iter().filter(|l| l.5 && !fin_lights.contains(l.0)).filter_map(
        |(entity, point, settings, transform, render, _)| {
            let settings = settings?.clamped();
            let sphere = SphereLight::new(transform.translation(), finite(point.radius)).map_err(|_| entity);
            Some(sphere.map(|sphere| LightSource {
                entity,
                light: Light::Sphere(sphere),
                reach: Reach { range: finite(point.range), cone: None },
                settings,
                shading: LightShading::Bevy { render_entity: render.id() },
                window: None,
                layers: RenderLayers::default(),
            }))
        },
    );
    let (mut sources, mut invalid) = (Vec::new(), Vec::new());
    for light in own.chain(spots).chain(suns).chain(rects).chain(points) {
        match light {
            Ok(source) => sources.push(source),
            Err(entity) => invalid.push(entity),
        }
    }
    sources.sort_by_key(|s| s.entity);
    (sources, invalid)
}

/// The sun's angular radius `θ` from Bevy's `SunDisk::angular_size` (a
/// diameter): half of it, `SunDisk::EARTH` (what Bevy draws) when the light
/// has none, clamped to `[0, 1.4]` rad (the core's `SunLight` range; 80°,
/// far past any sun), 0 for NaN. (`SunDisk::OFF`, size 0, gives the hard
/// shadow.)
pub(crate) fn sun_angular_radius(sun_disk: Option<&SunDisk>) -> f32 {
    let size = sun_disk.map_or(SunDisk::EARTH.angular_size, |d| d.angular_size);
    // +∞ is "as wide as there is"; NaN is no size.
    if size.is_nan() { 0.0 } else { (size * 0.5).clamp(0.0, 1.4) }
}

/// What makes a mesh a caster: drawn (`InheritedVisibility`; a mesh hidden
/// by it or a parent casts no shadow, as in Bevy's own maps), and neither
/// `NotFinShadowCaster` nor Bevy's `NotShadowCaster`.
#[derive(bevy::ecs::query::QueryData)]
pub(crate) struct CasterFlags {
    not_fin_caster: Has<NotFinShadowCaster>,
    not_bevy_caster: Has<bevy::light::NotShadowCaster>,
    visibility: Option<&'static InheritedVisibility>,
    pub(crate) aabb: Option<&'static Aabb>,
    layers: Option<&'static RenderLayers>,
}

impl CasterFlagsItem<'_, '_> {
    pub(crate) fn drawn(&self) -> bool {
        self.visibility.is_none_or(|v| v.get())
    }

    pub(crate) fn casts(&self) -> bool {
        !self.not_fin_caster && !self.not_bevy_caster
    }

    /// The mesh's `RenderLayers` (layer 0 without the component, as in Bevy).
    pub(crate) fn layers(&self) -> RenderLayers {
        self.layers.cloned().unwrap_or_default()
    }
}

/// Hashes a `RenderLayers` (it has no `Hash`) by its layers.
pub(crate) fn hash_layers(layers: &RenderLayers, hasher: &mut impl Hasher) {
    layers.iter().count().hash(hasher);
    for layer in layers.iter() {
        layer.hash(hasher);
    }
}

/// Every mesh that may cast or receive.
pub(crate) type Casters<'w, 's> = Query<'w, 's, (Entity, &'static Mesh3d, &'static GlobalTransform, CasterFlags)>;

/// Every `SpotLight`, fin-shadowed (`FinShadows`) or not: mutable, so that
/// one that stops being fin-shadowed can be marked changed.
type SpotLights<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        &'static mut SpotLight,
        Option<&'static FinShadowSettings>,
        &'static GlobalTransform,
        &'static RenderEntity,
        Has<FinShadows>,
    ),
>;

/// Every `DirectionalLight`, as [`SpotLights`].
type DirectionalLights<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        &'static mut DirectionalLight,
        Option<&'static SunDisk>,
        Option<&'static FinShadowSettings>,
        &'static GlobalTransform,
        &'static RenderEntity,
        Has<FinShadows>,
    ),
>;

/// Every `RectLight` (Bevy has no shadow map for it to turn off).
type RectLights<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        &'static bevy::light::RectLight,
        Option<&'static FinShadowSettings>,
        &'static GlobalTransform,
        &'static RenderEntity,
        Has<FinShadows>,
    ),
>;

/// Every `PointLight`, as [`SpotLights`].
type PointLights<'w, 's> = Query<
    'w,
    's,
    (
        Entity,
        &'static mut PointLight,
        Option<&'static FinShadowSettings>,
        &'static GlobalTransform,
        &'static RenderEntity,
        Has<FinShadows>,
    ),
>;

/// Rectangle and point lights (one parameter: a system takes at most sixteen).
#[derive(bevy::ecs::system::SystemParam)]
struct OtherLights<'w, 's> {
    rects: RectLights<'w, 's>,
    points: PointLights<'w, 's>,
}

/// The casters' meshes and materials, and what changed of them.
#[derive(bevy::ecs::system::SystemParam)]
struct CasterAssets<'w, 's> {
    meshes: Res<'w, Assets<Mesh>>,
    mesh_events: MessageReader<'w, 's, AssetEvent<Mesh>>,
    /// A skin's inverse bind poses loading or changing re-poses its casters
    /// (optional: a world without Bevy's skinning has none).
    bindpose_events: Option<MessageReader<'w, 's, AssetEvent<bevy::mesh::skinning::SkinnedMeshInverseBindposes>>>,
    gpu_posing: Option<Res<'w, crate::pose::FinGpuPosing>>,
    materials: crate::cutout::CasterMaterials<'w, 's>,
}

/// Rebuilds each light's frame when it, a setting or a caster changed.
#[allow(clippy::type_complexity, clippy::too_many_arguments)]
fn update_fin_frames(
    fin_lights: Query<(Entity, &FinLight, &FinShadowSettings, &GlobalTransform)>,
    mut spot_lights: SpotLights,
    mut directional_lights: DirectionalLights,
    mut lights: OtherLights,
    casters: Casters,
    mut changes: CasterChanges,
    light_layers: Query<&RenderLayers>,
    views: Query<(&GlobalTransform, &Projection), With<FinShadowView>>,
    mut light_stats: Query<&mut FinLightStats>,
    mut assets: CasterAssets,
    budget: Res<FinShadowBudget>,
    device: Res<FinDeviceLimits>,
    unsupported: Option<Res<FinShadowsUnsupported>>,
    mut cache: ResMut<MeshCache>,
    mut frames: ResMut<FinFrames>,
) {
    let meshes = &assets.meshes;
    // Bumps the casters' epoch: the same entities, new triangles or cut-outs.
    let mut meshes_changed = false;
    // Any mesh event (one finishing loading, too) changes what casts; so
    // does a change of what an alpha-masked material cuts out.
    let mut mesh_event = false;
    assets.materials.refresh();
    let cutouts = assets.materials.cache.generation();
    if cutouts != cache.cutout_generation {
        cache.cutout_generation = cutouts;
        meshes_changed = true;
        mesh_event = true;
    }
    if let Some(events) = assets.bindpose_events.as_mut()
        && events.read().count() > 0
    {
        // Rare (a skin loading): every posed caster is posed again.
        mesh_event = true;
        cache.posed.clear();
    }
    // Compared with the last frame's, not by change detection: a mutable
    // borrow (an editor's checkbox) is a change, and a removal is none.
    let gpu_posing = assets.gpu_posing.as_ref().is_none_or(|g| g.0);
    if gpu_posing != cache.gpu_posing {
        cache.gpu_posing = gpu_posing;
        // Posed anew, for the GPU or not: new geometry for the GPU's frames.
        meshes_changed = true;
        mesh_event = true;
        cache.posed.clear();
    }
    for event in assets.mesh_events.read() {
        mesh_event = true;
        if let AssetEvent::Modified { id } | AssetEvent::Removed { id } = event {
            cache.meshes.remove(id);
            cache.posable.remove(id);
            assets.materials.cache.forget_mesh(*id);
            // A posed mesh of that asset is posed again (rare: clear them all).
            cache.posed.clear();
            meshes_changed = true;
        }
    }
    let changed_casters = changes.take_changed();
    let (mut sources, invalid) = light_sources(&fin_lights, &spot_lights, &directional_lights, &lights);
    for source in &mut sources {
        if let Ok(layers) = light_layers.get(source.entity) {
            source.layers = layers.clone();
        }
    }
    // A light with no finite position or direction shadows nothing and takes
    // no share of the budget.
    for entity in invalid {
        set_stats(&mut light_stats, entity, FinFrameStats { up_to_date: true, ..default() });
    }
    for cut in sources.drain(sources.len().min(MAX_FIN_LIGHTS)..) {
        warn_once!(
            "fin shadows: more than {MAX_FIN_LIGHTS} fin-shadowed lights; the rest keep Bevy's shadows \
             (a FinLight past the limit is not lit)"
        );
        let over = FinFrameStats {
            degraded: Some(FinDegradation::TooManyLights { max: MAX_FIN_LIGHTS as u32 }),
            up_to_date: true,
            ..default()
        };
        set_stats(&mut light_stats, cut.entity, over);
    }
    if let Some(why) = unsupported {
        let off = FinFrameStats { degraded: Some(FinDegradation::Unsupported(why.0)), up_to_date: true, ..default() };
        for s in &sources {
            set_stats(&mut light_stats, s.entity, off);
        }
        return;
    }
    // The boxes only matter to suns fitted to the views.
    let fitting = sources.iter().any(|s| matches!(s.light, Light::Sun(_)) && s.settings.fit_sun_to_views);
    let kept = &mut *changes.kept;
    if meshes_changed {
        kept.mesh_epoch += 1;
    }
    // The casters' part of every frame's signature: the changed casters
    // signed again (change detection), every caster only when something
    // changed them all (`casters.rs`).
    if mesh_event || kept.signature.is_none() || kept.fitting != fitting || !changed_casters.is_empty() {
        let some = if mesh_event { None } else { Some(&changed_casters) };
        let materials = &assets.materials;
        if kept.update(some, &casters, meshes, |e| materials.material_of(e), &changes.poses, fitting) {
            changes.scans.0 += 1;
        }
    }
    let (scene_box, every_mesh_boxed) = (kept.scene_box, kept.every_mesh_boxed);
    let casters_signature = kept.signature;
    // Suns fit their maps to the cameras' view of the scene's box.
    if fitting && every_mesh_boxed && scene_box.0.x <= scene_box.1.x {
        let volumes = sun_fit::view_volumes(views.iter(), scene_box);
        for source in &mut sources {
            if let (Light::Sun(sun), Some(volumes), true) = (&source.light, &volumes, source.settings.fit_sun_to_views)
            {
                let previous = cache.lights.get(&(source.entity, None)).and_then(|s| s.window);
                source.window = sun_fit::sun_window(volumes, scene_box, sun, previous);
            }
        }
    }
    // One frame per light, six per point light (its cube faces).
    let sources: Vec<(usize, &LightSource, Option<CubeFace>)> = sources
        .iter()
        .enumerate()
        .flat_map(|(layer, source)| faces_of(&source.light).into_iter().map(move |face| (layer, source, face)))
        .collect();
    cache.lights.retain(|key, _| sources.iter().any(|(_, s, face)| (s.entity, *face) == *key));

    let mut scene_caught_up = false;
    let mut next = Vec::with_capacity(sources.len());
    let mut changed = frames.0.len() != sources.len();
    for &(layer, source, face) in &sources {
        let key = (source.entity, face);
        // The light's own part of its frame's signature: it, its settings,
        // the budget and how many lights share it.
        let mut hasher = std::collections::hash_map::DefaultHasher::new();
        budget.hash(&mut hasher);
        sources.len().hash(&mut hasher);
        let state = cache.lights.entry(key).or_default();
        state.window = source.window;
        state.capacity_epoch.hash(&mut hasher);
        source.settings.hash(&mut hasher);
        hash_floats(&mut hasher, &light_key(&source.light));
        hash_floats(&mut hasher, &source.window.unwrap_or([f32::NAN; 4]));
        hash_floats(&mut hasher, &[source.reach.range, source.reach.cone.unwrap_or(-1.0)]);
        hash_layers(&source.layers, &mut hasher);
        let light_part = hasher.finish();
        let signature = {
            let mut hasher = std::collections::hash_map::DefaultHasher::new();
            (light_part, casters_signature).hash(&mut hasher);
            hasher.finish()
        };
        let previous = frames.0.iter().find(|f| f.key() == key);
        if let Some(previous) = previous
            && state.signature == signature
        {
            // Only the shading may have moved (colour, intensity): keep the maps.
            next.push(FinLightFrame { shading: source.shading, layer, ..previous.clone() });
            changed |= previous.shading != source.shading || previous.layer != layer;
            continue;
        }
        state.signature = signature;
        changed = true;
        let light = source.light;
        if !scene_caught_up {
            let MeshCache { meshes: cached, posed, posable, scene, .. } = &mut *cache;
            let mut sources = SlotSources {
                casters: &casters,
                meshes: &assets.meshes,
                cache: cached,
                posed,
                posable,
                gpu_posing,
                poses: &changes.poses,
                materials: &mut assets.materials,
            };
            catch_up(scene, &mut changes.kept.pending, &mut sources, &mut changes.updates);
            scene_caught_up = true;
        }
        let max_buffer = device.max_buffer(&budget);
        // The maps' budget is shared equally between the frames.
        let map_bytes = (budget.map_bytes / sources.len().max(1) as u64).min(max_buffer);
        let limits = FrameLimits { max_buffer, map_bytes };
        cache.generation += 1;
        let generation = cache.generation;
        let MeshCache { scene, lights: states, .. } = &mut *cache;
        let (scene, state) = (scene.as_ref().expect("caught up above"), states.get_mut(&key).expect("inserted above"));
        let sees = LightSees { reach: source.reach, layers: &source.layers };
        let asked = FrameAsked { light, face, window: source.window, sees, settings: source.settings, light_part };
        let data = light_frame(scene, asked, generation, limits, state);
        state.stats = data.stats;
        next.push(FinLightFrame {
            light: source.entity,
            face,
            layer,
            shape: light,
            shading: source.shading,
            data: Arc::new(data),
        });
    }
    if !changed {
        return;
    }
    publish_light_stats(&next, &cache, &mut light_stats);
    // A Bevy light no longer fin-shadowed gets its own shadow map back: marked
    // changed, Bevy extracts it again with the user's `shadow_maps_enabled`
    // (`render/bevy_lights.rs` turned it off in the render world).
    // A light no longer fin-shadowed reports nothing any more.
    for gone in frames.0.iter().filter(|f| !next.iter().any(|n| n.light == f.light)) {
        if matches!(gone.shading, LightShading::Bevy { .. }) {
            if let Ok((_, mut spot, ..)) = spot_lights.get_mut(gone.light) {
                spot.set_changed();
            }
            if let Ok((_, mut sun, ..)) = directional_lights.get_mut(gone.light) {
                sun.set_changed();
            }
            if let Ok((_, mut point, ..)) = lights.points.get_mut(gone.light) {
                point.set_changed();
            }
        }
        set_stats(&mut light_stats, gone.light, FinFrameStats::default());
    }
    frames.0 = next;
}

/// Brings the kept scene up to the casters: the `pending` changed entities
/// rebuilt in place, or the scene collected anew (first frame, after a walk,
/// or a change no slot can take).
fn catch_up(
    scene: &mut Option<CasterScene>,
    pending: &mut Option<HashSet<Entity>>,
    sources: &mut SlotSources<'_, '_, '_, '_, '_, '_, '_>,
    updates: &mut FinCasterUpdates,
) {
    let version = scene.as_ref().map_or(0, |s| s.version) + 1;
    let updated = match (scene.as_mut(), pending.take()) {
        (Some(_), Some(changed)) if changed.is_empty() => true,
        (Some(kept), Some(changed)) => {
            let updated = kept.update(&changed, sources);
            if updated {
                updates.frames += 1;
                updates.records += kept.dirty.as_ref().map_or(0, |d| d.len() as u64);
            }
            updated
        }
        _ => false,
    };
    if !updated {
        *scene = Some(CasterScene::collect(sources, version));
    }
    *pending = Some(HashSet::new());
}

/// The cube faces a light's frames are made for: one frame (`None`) for a
/// disk, rectangle or sun, six for a sphere.
fn faces_of(light: &Light) -> Vec<Option<CubeFace>> {
    match light {
        Light::Sphere(_) => CubeFace::ALL.map(Some).to_vec(),
        _ => vec![None],
    }
}

/// Every light's [`FinLightStats`] from its frames' latest stats.
pub(crate) fn publish_light_stats(
    frames: &[FinLightFrame],
    cache: &MeshCache,
    light_stats: &mut Query<&mut FinLightStats>,
) {
    let mut start = 0;
    while start < frames.len() {
        let light = frames[start].light;
        let end = start + frames[start..].iter().take_while(|f| f.light == light).count();
        let stats = frames[start..end].iter().filter_map(|f| cache.lights.get(&f.key()).map(|s| s.stats));
        if let Some(combined) = FinFrameStats::combined(stats) {
            set_stats(light_stats, light, combined);
        }
        start = end;
    }
}

impl FinFrameStats {
    /// Texels of the penumbra maps, all layers: what a full redraw clears
    /// and draws again ([`Self::redrawn_texels`]).
    pub fn map_texels(&self) -> u64 {
        self.layers as u64 * (self.map_resolution as u64).pow(2)
    }

    /// One light's stats from its frames' (a point light's six faces): the
    /// work summed (silhouettes, fins, extraction time), the casters and
    /// triangles of the face that sees the most (faces share them), the most
    /// layers, the least resolution, up to date when every face is, the
    /// first reason any face was cut.
    fn combined(frames: impl Iterator<Item = FinFrameStats>) -> Option<Self> {
        frames.reduce(|a, b| FinFrameStats {
            casters: a.casters.max(b.casters),
            triangles: a.triangles.max(b.triangles),
            silhouettes: a.silhouettes + b.silhouettes,
            fins: a.fins + b.fins,
            layers: a.layers.max(b.layers),
            extract_ms: a.extract_ms + b.extract_ms,
            up_to_date: a.up_to_date && b.up_to_date,
            degraded: a.degraded.or(b.degraded),
            map_resolution: a.map_resolution.min(b.map_resolution),
            extraction: a.extraction,
            partial_redraw: a.partial_redraw && b.partial_redraw,
            incremental_extraction: a.incremental_extraction && b.incremental_extraction,
            redrawn_texels: a.redrawn_texels + b.redrawn_texels,
            posed_on_gpu: a.posed_on_gpu.max(b.posed_on_gpu),
        })
    }
}

/// [`FinShadowStats`] is the first light's [`FinLightStats`]: the first
/// light with a frame, else (no frame: the device is unsupported, or every
/// light is invalid) the first light asking for fin shadows, by entity order.
/// One place keeps the mirror, whoever wrote the light's stats (the frame
/// builder or the GPU read-back).
fn mirror_first_light_stats(
    frames: Res<FinFrames>,
    lights: Query<(Entity, &FinLightStats)>,
    mut stats: ResMut<FinShadowStats>,
) {
    let first = match frames.0.first() {
        Some(f) => lights.get(f.light).ok().map(|(_, s)| s.0),
        None => lights.iter().min_by_key(|(e, _)| *e).map(|(_, s)| s.0),
    };
    let now = first.unwrap_or_default();
    if stats.0 != now {
        stats.0 = now;
    }
}

/// Sets a light's [`FinLightStats`] when they changed.
pub(crate) fn set_stats(light_stats: &mut Query<&mut FinLightStats>, light: Entity, now: FinFrameStats) {
    if let Ok(mut s) = light_stats.get_mut(light)
        && s.0 != now
    {
        s.0 = now;
    }
}

/// What a light's shadow sees of the scene: where it lights and its layers.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LightSees<'a> {
    pub reach: Reach,
    pub layers: &'a RenderLayers,
}

/// Where a light can light: its range (0: unbounded) and, for a spot, the
/// outer half-angle of its cone around the disk's normal.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Reach {
    pub range: f32,
    pub cone: Option<f32>,
}

/// True when a box (its world corners) cannot shadow anything this light
/// lights: all of it behind the disk's plane, all of it beyond the range from
/// the centre, or all of it outside the cone widened by what the disk and the
/// box subtend (a blocker of a lit receiver lies on a segment from a disk
/// point to the receiver, within `asin(R / d)` of the cone seen from the
/// centre).
pub(crate) fn out_of_reach(corners: &[Vec3; 8], disk: &DiskLight, reach: Reach) -> bool {
    let behind = corners.iter().all(|p| (*p - disk.center).dot(disk.normal) < 0.0);
    let (lo, hi) = corners.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let nearest = disk.center.clamp(lo, hi);
    let beyond = reach.range > 0.0 && nearest.distance(disk.center) > reach.range + disk.radius;
    let outside_cone = reach.cone.is_some_and(|cone| {
        let (middle, radius) = ((lo + hi) * 0.5, (hi - lo).length() * 0.5);
        let to_box = middle - disk.center;
        let distance = to_box.length();
        let margin = radius + disk.radius;
        distance > margin && {
            let angle = (to_box.dot(disk.normal) / distance).clamp(-1.0, 1.0).acos();
            angle - (margin / distance).min(1.0).asin() > cone
        }
    });
    behind || beyond || outside_cone
}

/// The distance from `point` to a box given by its corners (0 inside it).
pub(crate) fn nearest_distance(corners: &[Vec3; 8], point: Vec3) -> f32 {
    let (lo, hi) = corners.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    point.clamp(lo, hi).distance(point)
}

/// True when a box (its world corners) lies wholly outside a point light's
/// cube-face window frustum (`LightFrame::outside_face_window`); false for
/// any other frame.
pub(crate) fn outside_face(corners: &[Vec3; 8], frame: &LightFrame) -> bool {
    frame.outside_face_window(&corners.map(|c| frame.to_frame(c)))
}

/// One light's frame (one cube face's, for a point light) from the scene's objects.
#[allow(clippy::too_many_arguments)]
fn light_frame(
    scene: &CasterScene,
    asked: FrameAsked,
    generation: u64,
    limits: FrameLimits,
    state: &mut LightState,
) -> FinFrameData {
    let FrameAsked { light, face, window, sees, settings, light_part } = asked;
    let start = std::time::Instant::now();
    // A light of no size casts no fins: one layer's slab is the exact hard
    // shadow (the min over layers of slabs is the nearest slab), and the
    // memory of the other layers goes to resolution instead.
    let settings = if light.is_zero_size() { FinShadowSettings { layers: 1, ..settings } } else { settings };
    let (frame, scene_box) = scene.frame_for(&light, face);
    // The objects as this light sees them: after an in-place update of the
    // scene, only its dirty slots again, when nothing of the light changed.
    let mut built = state.built.take().filter(|b| {
        b.scene_version + 1 == scene.version
            && b.light_part == light_part
            && b.seen_frame == frame
            && b.objects.len() == scene.objects.len()
    });
    let dirty = scene.dirty.as_deref().filter(|_| built.is_some());
    match (&mut built, dirty) {
        (Some(b), Some(dirty)) => {
            for &i in dirty {
                b.objects[i] = scene.seen_by_one(i, &light, &frame, sees);
            }
            b.scene_version = scene.version;
        }
        _ => {
            let objects = scene.seen_by(&light, &frame, sees);
            built = Some(LightBuild {
                scene_version: scene.version,
                light_part,
                seen_frame: frame,
                gpu_frame: None,
                objects,
            });
        }
    }
    let built = state.built.insert(built.expect("set above"));
    let gpu_frame = built.gpu_frame.take();
    let objects_of =
        |state: &LightState| -> Vec<SceneObject> { state.built.as_ref().expect("built above").objects.clone() };
    let unread_bounds = scene.unread_bounds.clone();
    // A sun fitted to the views works in a frame placed at its window.
    let fitted = match (light, window) {
        (Light::Sun(sun), Some(w)) => sun_fit::window_frame(w, scene_box, &sun).map(|(f, l0)| (f, l0, w)),
        _ => None,
    };
    let (frame, reference_depth) = fitted.map_or((frame, None), |(f, l0, _)| (f, Some(l0)));
    let map_window = window.map(|w| sun_fit::window_in_frame(w, &frame));
    let extent = (scene_box.1 - scene_box.0).length();
    let in_frame = InFrame { light, frame, extent, scene_box, map_window, reference_depth };
    let penumbra_texels = in_frame.widest_penumbra_texels(settings.map_resolution);
    if settings.method == FinMethod::Coverage {
        let objects = &state.built.as_ref().expect("built above").objects;
        let data = coverage_data(objects, in_frame, settings, generation, start, unread_bounds, limits);
        warn_degradation(&mut state.warned, data.stats.degraded);
        return data;
    }
    let mut extraction = settings.extraction;
    // The GPU extracts an alpha-masked caster from its mesh packed with its
    // outline (`GpuMeshGeometry::pack_outlined`, posed with the mesh when the
    // GPU poses it); one packed without (its cut-out could not be made at
    // rest) sends the frame to the CPU extraction (the maps still run on the GPU).
    let objects = &state.built.as_ref().expect("built above").objects;
    if objects
        .iter()
        .zip(&scene.gpu_meshes)
        .any(|(o, m)| o.casts_shadows && o.fitting_cutout().is_some() && !m.outlined)
    {
        extraction = FinExtraction::Cpu;
    }
    let mut gpu_scene = None;
    let max_buffer = limits.max_buffer;
    if extraction == FinExtraction::Gpu {
        let LightState { gpu, capacity, built, .. } = &mut *state;
        let built = built.as_mut().expect("built above");
        // Records of unchanged objects are kept only in the frame they were made in.
        let dirty = dirty.filter(|_| gpu_frame == Some(frame));
        built.gpu_frame = Some(frame);
        let max = GpuCapacity::max_for(max_buffer);
        let scene = gpu.build(
            &built.objects,
            &scene.gpu_meshes,
            &scene.gpu_poses,
            &frame,
            scene.objects_box,
            dirty,
            capacity,
            max,
        );
        // Buffers sized by the scene itself cannot shrink: past the limit the
        // core crate extracts on the CPU instead.
        match scene.input_bytes().into_iter().find(|(_, bytes)| *bytes > max_buffer) {
            Some((buffer, bytes)) => {
                warn_once!(
                    "fin shadows: the GPU extraction's {buffer} ({bytes} bytes) exceeds the buffer limit; extracting on the CPU"
                );
                extraction = FinExtraction::Cpu;
                gpu_scene = Some(Err(FinDegradation::ExtractedOnCpu { buffer, bytes, limit_bytes: max_buffer }));
            }
            None => gpu_scene = Some(Ok(scene)),
        }
    }
    // The plateaus' texture reads the scene in this frame; the maps below
    // are its hard shadow.
    let plateaus = (settings.method == FinMethod::Plateaus).then(|| {
        let scene = Scene::new(objects_of(state));
        let light_space = in_frame.light_space(&scene, unread_bounds.iter().flatten().copied());
        crate::plateau_frame::plateau_frame(&scene, &light_space)
    });
    let receiver_bound = unread_bounds.into_iter().flatten();
    let mut data = match (extraction, gpu_scene) {
        (FinExtraction::Gpu, Some(Ok(scene))) => {
            // Layers are known to the GPU only (a read-back grows them): the
            // maps hold what the GPU last wanted, at the best resolution that
            // fits, and may grow to the most layers that fit at all.
            let asked = if settings.method == FinMethod::MultiLayer { settings.layers } else { 1 };
            let most =
                allocate_maps(settings.map_resolution, asked, MAP_TEXEL_BYTES, limits.map_bytes, penumbra_texels)
                    .layers;
            let mut scene = scene;
            let wanted = scene.capacity.layers.min(most);
            let alloc =
                allocate_maps(settings.map_resolution, wanted, MAP_TEXEL_BYTES, limits.map_bytes, penumbra_texels);
            scene.capacity.layers = alloc.layers;
            scene.max_capacity.layers = most;
            scene.map_window = in_frame.map_window;
            scene.receiver_depth = match in_frame.reference_depth {
                Some(l0) => l0,
                None => receiver_bound.map(|p| frame.to_frame(p).z).fold(0.0, f32::max),
            };
            scene.fixed_reference_depth = in_frame.reference_depth.is_some();
            let objects = &state.built.as_ref().expect("built above").objects;
            let stats = FinFrameStats {
                casters: objects.iter().filter(|o| o.casts_shadows).count(),
                triangles: objects.iter().map(|o| o.mesh.triangle_count()).sum(),
                extract_ms: start.elapsed().as_secs_f32() * 1e3,
                // No caster face: the GPU runs no pass and there is nothing to read back.
                up_to_date: scene.totals[1] == 0,
                degraded: alloc.degradation,
                map_resolution: alloc.resolution,
                posed_on_gpu: scene.pose_sizes()[0] as usize,
                ..default()
            };
            FinFrameData {
                generation,
                stats,
                casters: Vec::new(),
                cutouts: Vec::new(),
                mask_words: Vec::new(),
                fins: Vec::new(),
                region: MapRegion { min: Vec2::ZERO, texel: 1.0, resolution: alloc.resolution },
                map_layers: alloc.layers,
                limit_bytes: limits.max_buffer,
                map_limit_bytes: limits.map_bytes,
                origin: frame.origin(),
                axes: frame.axes_f64(),
                size: frame.size(),
                aperture: frame.aperture,
                orthographic: !frame.is_perspective(),
                reference_depth: 0.0,
                near: 0.0,
                scene_extent: scene.extent,
                settings,
                gpu: Some(scene),
                coverage: None,
                plateaus: None,
                convolution: None,
                windowed: false,
            }
        }
        (_, fallback) => {
            let mut data =
                cpu_frame(Scene::new(objects_of(state)), in_frame, settings, generation, start, receiver_bound, limits);
            if let Some(Err(why)) = fallback {
                // What the CPU path had to cut (maps, dropped casters) shows first.
                data.stats.degraded = data.stats.degraded.or(Some(why));
            }
            data
        }
    };
    if let Some(p) = plateaus {
        data.stats.silhouettes = p.sheets.len();
        let longest = p.cell_starts.windows(2).map(|w| w[1].saturating_sub(w[0])).max().unwrap_or(0);
        if longest > crate::plateau_frame::MAX_CELL_SHEETS {
            let why = FinDegradation::LongPlateauCell { sheets: longest, limit: crate::plateau_frame::MAX_CELL_SHEETS };
            data.stats.degraded = data.stats.degraded.or(Some(why));
        }
        data.plateaus = Some(p);
    }
    data.windowed = map_window.is_some();
    if settings.method == FinMethod::Convolution {
        // The basis shares the light's map budget with the maps it filters.
        let resolution = data.region.resolution as u64;
        let maps = data.map_layers.max(1) as u64 * resolution * resolution * MAP_TEXEL_BYTES;
        let room = limits.map_bytes.saturating_sub(maps).min(limits.max_buffer);
        match crate::budget::BasisLayout::new(data.region.resolution, settings.convolution_order, room) {
            Ok(layout) => {
                if layout.first > 0 {
                    let why = FinDegradation::ConvolutionLevels { dropped: layout.first, limit_bytes: room };
                    data.stats.degraded = data.stats.degraded.or(Some(why));
                }
                data.convolution = Some(layout);
            }
            Err(bytes) => {
                let why = FinDegradation::ConvolutionBasis { bytes, limit_bytes: room };
                data.stats.degraded = data.stats.degraded.or(Some(why));
            }
        }
    }
    data.stats.map_resolution = data.region.resolution;
    data.stats.extraction = if data.gpu.is_some() { FinExtraction::Gpu } else { FinExtraction::Cpu };
    // What the last read-back said the GPU had to drop still holds until a
    // read-back says otherwise (no flicker between re-extractions).
    data.stats.degraded = data.stats.degraded.or(state.shortfall);
    warn_degradation(&mut state.warned, data.stats.degraded);
    data
}

/// The coverage method's frame: edges and lists from the core crate.
fn coverage_data(
    objects: &[SceneObject],
    in_frame: InFrame,
    settings: FinShadowSettings,
    generation: u64,
    start: std::time::Instant,
    unread_bounds: Vec<[Vec3; 8]>,
    limits: FrameLimits,
) -> FinFrameData {
    let scene = Scene::new(objects.to_vec());
    let (coverage, degraded, potential_silhouettes) = coverage_frame(
        &scene,
        in_frame,
        settings.map_resolution,
        settings.coverage_samples,
        unread_bounds.into_iter().flatten(),
        limits.map_bytes,
        limits.max_buffer,
    );
    let stats = FinFrameStats {
        casters: scene.objects.iter().filter(|o| o.casts_shadows).count(),
        triangles: scene.triangle_count(),
        silhouettes: potential_silhouettes,
        fins: 0,
        layers: if coverage.casters.is_empty() { 0 } else { 1 },
        extract_ms: start.elapsed().as_secs_f32() * 1e3,
        up_to_date: true,
        degraded,
        map_resolution: coverage.region.resolution,
        extraction: FinExtraction::Cpu,
        partial_redraw: false,
        incremental_extraction: false,
        redrawn_texels: 0,
        posed_on_gpu: 0,
    };
    FinFrameData {
        generation,
        stats,
        casters: Vec::new(),
        cutouts: Vec::new(),
        mask_words: Vec::new(),
        fins: Vec::new(),
        region: coverage.region,
        map_layers: 1,
        limit_bytes: limits.max_buffer,
        map_limit_bytes: limits.map_bytes,
        origin: in_frame.frame.origin(),
        axes: in_frame.frame.axes_f64(),
        size: in_frame.frame.size(),
        aperture: in_frame.frame.aperture,
        orthographic: !in_frame.frame.is_perspective(),
        reference_depth: 0.0,
        near: coverage.near,
        scene_extent: coverage.extent,
        settings,
        gpu: None,
        coverage: Some(coverage),
        plateaus: None,
        convolution: None,
        windowed: false,
    }
}

/// Logs a degradation once per distinct reason (a moving light re-extracts
/// every frame; the same reason is said once, not sixty times a second).
pub(crate) fn warn_degradation(warned: &mut Option<FinDegradation>, now: Option<FinDegradation>) {
    if let Some(why) = now
        && *warned != now
    {
        warn!("fin shadows: {why}");
        *warned = now;
    }
}

/// Bytes per penumbra-map texel (nine 32-bit channels, `fin_types.wgsl`).
pub(crate) const MAP_TEXEL_BYTES: u64 = 9 * 4;

/// A light and the frame every path of it (GPU, CPU, coverage) works in.
#[derive(Debug, Clone, Copy)]
pub(crate) struct InFrame {
    pub light: Light,
    pub frame: LightFrame,
    /// The diagonal of everything drawn, and its box.
    pub extent: f32,
    pub scene_box: (Vec3, Vec3),
    /// The part of map space the maps need cover at most (a sun's view fit,
    /// `sun_fit`); `None`: all the casters.
    pub map_window: Option<(Vec2, Vec2)>,
    /// `L0` when the frame fixes it (a sun fitted to the views: the deepest
    /// point of what the window can show, `sun_fit::window_frame`); `None`:
    /// the deepest receiver, found from the geometry.
    pub reference_depth: Option<f32>,
}

impl InFrame {
    /// The scene in this frame, its reference plane `L0` past every receiver:
    /// the scene's own and `receiver_bound` (meshes drawn but not readable),
    /// or the window's deepest point for a sun fitted to the views.
    pub fn light_space(&self, scene: &Scene, receiver_bound: impl Iterator<Item = Vec3>) -> LightSpaceScene {
        let mut ls = LightSpaceScene::in_frame(scene, self.light, self.frame, self.extent);
        match self.reference_depth {
            Some(l0) => ls.reference_depth = l0,
            None => ls.cover_receivers(receiver_bound.map(|p| self.frame.to_frame(p))),
        }
        ls
    }

    /// An estimate of the widest penumbra's half-width in texels of maps at
    /// `resolution`, for the budget's choice between resolution and layers
    /// (`budget::MIN_PENUMBRA_TEXELS`). The sun's: `tan θ` times the scene
    /// box's depth along it, over the map window's (or the box's footprint's)
    /// texel. A disk's widest penumbra comes from the casters nearest to it,
    /// which only the GPU extraction finds: unknown (`INFINITY`).
    pub fn widest_penumbra_texels(&self, resolution: u32) -> f32 {
        let shadow_fins::light::Projection::Orthographic { tan_angle } = self.frame.projection else {
            return f32::INFINITY;
        };
        let corners = sun_fit::corners(self.scene_box).map(|c| self.frame.to_frame(c));
        let (flo, fhi) = corners.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
        let (mut mlo, mut mhi) = (flo.truncate(), fhi.truncate());
        if let Some((wlo, whi)) = self.map_window {
            (mlo, mhi) = (mlo.max(wlo), mhi.min(whi));
        }
        let texel = (mhi - mlo).max_element() / resolution.max(1) as f32;
        // A frame fixed at the views' window casts fins no deeper than its L0.
        let width = tan_angle * self.reference_depth.unwrap_or(fhi.z - flo.z);
        if texel > 0.0 && width.is_finite() { width / texel } else { f32::INFINITY }
    }

    /// The square of maps at `resolution` over `bounds` (map space), within
    /// the map window and a perspective map's angle limit.
    pub fn covering(&self, bounds: impl Iterator<Item = (Vec2, Vec2)>, resolution: u32) -> MapRegion {
        let limit = self.frame.map_limit(shadow_fins::oracle::RASTER_MAP_LIMIT);
        let (lo, hi) = self.map_window.unwrap_or((Vec2::NEG_INFINITY, Vec2::INFINITY));
        MapRegion::covering_within(bounds, resolution, (lo.max(Vec2::splat(-limit)), hi.min(Vec2::splat(limit))))
    }
}

/// The buffer limits one frame is built under.
#[derive(Debug, Clone, Copy)]
struct FrameLimits {
    /// The largest buffer, bytes.
    max_buffer: u64,
    /// All map layers together, bytes.
    map_bytes: u64,
}

/// The eight world-space corners of an entity's bounding box.
pub(crate) fn world_corners(aabb: &Aabb, transform: &GlobalTransform) -> [Vec3; 8] {
    let (c, h) = (Vec3::from(aabb.center), Vec3::from(aabb.half_extents));
    std::array::from_fn(|k| {
        let s = Vec3::new(
            if k & 1 == 0 { -1.0 } else { 1.0 },
            if k & 2 == 0 { -1.0 } else { 1.0 },
            if k & 4 == 0 { -1.0 } else { 1.0 },
        );
        transform.transform_point(c + h * s)
    })
}

/// The whole extraction on the CPU with the core crate.
fn cpu_frame(
    scene: Scene,
    in_frame: InFrame,
    settings: FinShadowSettings,
    generation: u64,
    start: std::time::Instant,
    receiver_bound: impl Iterator<Item = Vec3>,
    limits: FrameLimits,
) -> FinFrameData {
    let ls = in_frame.light_space(&scene, receiver_bound);
    let mut core = settings.core();
    let mut model = FinShadowModel::new(&scene, &ls, settings.method.into(), core);
    let penumbra_texels = in_frame.widest_penumbra_texels(settings.map_resolution);
    let mut alloc = allocate_maps(
        settings.map_resolution,
        model.plan.len() as u32,
        MAP_TEXEL_BYTES,
        limits.map_bytes,
        penumbra_texels,
    );
    if (alloc.layers as usize) < model.plan.len() {
        // Fewer layers fit than the plan made: plan again with that many.
        core.layers = alloc.layers;
        model = FinShadowModel::new(&scene, &ls, settings.method.into(), core);
        alloc.layers = alloc.layers.max(model.plan.len() as u32);
    }
    let bounds = model.casters.iter().map(|c| c.bounds()).chain(model.fins.iter().map(|f| f.bounds()));
    let region = in_frame.covering(bounds, alloc.resolution);
    let mut degraded = alloc.degradation;
    // What does not fit one buffer is dropped (and said so).
    let mut capped = |buffer: &'static str, n: usize, bytes: u64| {
        let keep = (limits.max_buffer / bytes) as usize;
        if n > keep && degraded.is_none() {
            degraded = Some(FinDegradation::Capacity {
                buffer,
                kept: keep as u32,
                wanted: n as u32,
                limit_bytes: limits.max_buffer,
            });
        }
        n.min(keep)
    };
    let n_casters = capped("map casters", model.casters.len(), size_of::<GpuCaster>() as u64);
    let n_fins = capped("fins", model.fins.len(), size_of::<GpuFin>() as u64);
    let (mut casters_gpu, mut cutouts, mut mask_words) =
        gpu_casters(&model.casters[..n_casters], Some(&model.caster_layers[..n_casters]), &ls.masks);
    if let Some(why) = fit_cutouts(&mut casters_gpu, &mut cutouts, &mut mask_words, limits.max_buffer) {
        degraded = degraded.or(Some(why));
    }
    let fins_gpu: Vec<GpuFin> =
        model.fins.iter().take(n_fins).zip(&model.fin_layers).map(|(f, &l)| gpu_fin(f, l)).collect();
    let stats = FinFrameStats {
        casters: scene.objects.iter().filter(|o| o.casts_shadows).count(),
        triangles: scene.triangle_count(),
        silhouettes: model.silhouettes.len(),
        fins: model.fins.len(),
        // Nothing casts: no layer, no map, and the passes have nothing to do.
        layers: if model.casters.is_empty() && model.fins.is_empty() { 0 } else { model.plan.len() },
        extract_ms: start.elapsed().as_secs_f32() * 1e3,
        up_to_date: true,
        degraded,
        map_resolution: region.resolution,
        extraction: FinExtraction::Cpu,
        partial_redraw: false,
        incremental_extraction: false,
        redrawn_texels: (model.plan.len() as u64) * (region.resolution as u64).pow(2),
        posed_on_gpu: 0,
    };
    FinFrameData {
        generation,
        stats,
        casters: casters_gpu,
        cutouts,
        mask_words,
        fins: fins_gpu,
        region,
        map_layers: alloc.layers,
        limit_bytes: limits.max_buffer,
        map_limit_bytes: limits.map_bytes,
        origin: ls.frame.origin(),
        axes: ls.frame.axes_f64(),
        size: ls.frame.size(),
        aperture: ls.frame.aperture,
        orthographic: !ls.frame.is_perspective(),
        reference_depth: ls.reference_depth,
        near: model.near,
        scene_extent: ls.extent,
        settings,
        gpu: None,
        coverage: None,
        plateaus: None,
        convolution: None,
        windowed: false,
    }
}

/// The numbers a light's frame depends on.
fn light_key(light: &Light) -> [f32; 12] {
    // The first entry is the kind, so that no two kinds share a key.
    match light {
        Light::Disk(d) => {
            let (c, n) = (d.center, d.normal);
            [0.0, c.x, c.y, c.z, n.x, n.y, n.z, d.radius, 0.0, 0.0, 0.0, 0.0]
        }
        Light::Rect(r) => {
            let (c, n, t, h) = (r.center, r.normal, r.tangent, r.half_extents);
            [1.0, c.x, c.y, c.z, n.x, n.y, n.z, h.x, h.y, t.x, t.y, t.z]
        }
        Light::Sun(s) => {
            let d = s.direction;
            [2.0, 0.0, 0.0, 0.0, d.x, d.y, d.z, s.angular_radius, 0.0, 0.0, 0.0, 0.0]
        }
        Light::Sphere(s) => {
            let c = s.center;
            [3.0, c.x, c.y, c.z, 0.0, 0.0, 0.0, s.radius, 0.0, 0.0, 0.0, 0.0]
        }
    }
}

pub(crate) fn hash_floats(h: &mut impl Hasher, v: &[f32]) {
    for x in v {
        x.to_bits().hash(h);
    }
}

fn gpu_fin(f: &Fin, layer: u32) -> GpuFin {
    let side = match f.side {
        FinSide::Inner => 0,
        FinSide::Outer => 1,
    };
    match f.shape {
        FinShape::Quad { m0, m1, d0, d1, w0, w1, z0, z1 } => GpuFin {
            header: [0, side, layer, 0],
            data: [m0.x, m0.y, m1.x, m1.y, d0.x, d0.y, d1.x, d1.y, w0, w1, z0, z1],
        },
        FinShape::Sector { center, radius, from, to, depth } => GpuFin {
            header: [1, side, layer, 0],
            data: [center.x, center.y, from.x, from.y, to.x, to.y, radius, depth, 0.0, 0.0, 0.0, 0.0],
        },
    }
}

/// A posed caster as last posed: its pose's hash (with its mesh's), the
/// posed mesh (whose packing is the posable one when the GPU poses it: its
/// words are the mesh at rest), whether its positions are in world space
/// (skinned), and — when the GPU poses it — the pose.
pub(crate) struct PosedCaster {
    key: u64,
    pub mesh: CachedMesh,
    pub world: bool,
    pub gpu: Option<Arc<GpuPose>>,
}

/// `entity`'s mesh (asset `mesh_id`) posed (`pose.rs`), from `posed` while
/// its mesh and pose are the same; `None` when it is not drawn posed.
///
/// The CPU poses it for the oracles, the CPU extraction and the other
/// methods. The GPU extraction poses it itself (`pose.wgsl`), from the
/// topology of the mesh at rest, when that is the posed mesh's topology too
/// — the same welded vertices and faces, which a pose that welds two
/// vertices apart, or folds a face flat, breaks: then the GPU gets the
/// CPU's posed packing, a new mesh each pose. `posable`: the cache of
/// packings the GPU poses, `None` when the GPU is not to pose it.
pub(crate) fn posed_mesh<'a>(
    entity: Entity,
    mesh_id: AssetId<Mesh>,
    mesh: &Mesh,
    posed: &'a mut HashMap<Entity, PosedCaster>,
    at_rest: &mut HashMap<AssetId<Mesh>, CachedMesh>,
    posable: Option<&mut HashMap<AssetId<Mesh>, Option<Arc<GpuMeshGeometry>>>>,
    poses: &crate::pose::Poses,
) -> Option<&'a PosedCaster> {
    if !poses.is_posed(entity) {
        return None;
    }
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    // A mesh swapped for another, already loaded, is posed anew at the same pose.
    mesh_id.hash(&mut hasher);
    poses.hash_pose(entity, &mut hasher);
    let key = hasher.finish();
    if posed.get(&entity).is_none_or(|p| p.key != key) {
        let pose = poses.pose(entity, mesh)?;
        let posed_now = core_topology_at(mesh, pose.positions);
        // The GPU poses it when the pose kept the topology at rest (then no
        // packing of the posed mesh is made: the posable one stands for it).
        let gpu = posed_now.as_ref().ok().zip(posable).and_then(|((_, topology), posable)| {
            let Ok((_, rest, rest_packing)) = at_rest.entry(mesh_id).or_insert_with(|| core_mesh(mesh)) else {
                return None;
            };
            let posable = posable.entry(mesh_id).or_insert_with(|| {
                GpuMeshGeometry::pack_posable(rest_packing, rest, &crate::pose::pose_source(mesh), None).map(Arc::new)
            });
            let same_topology = rest.faces == topology.faces && rest.positions.len() == topology.positions.len();
            Some((posable.clone()?, Arc::new(GpuPose::new(&pose.pose)))).filter(|_| same_topology)
        });
        let cached = posed_now.map(|(core, topology)| {
            let geometry = match &gpu {
                Some((posable, _)) => posable.clone(),
                None => Arc::new(GpuMeshGeometry::pack(&topology)),
            };
            (core, topology, geometry)
        });
        let gpu = gpu.map(|(_, pose)| pose);
        posed.insert(entity, PosedCaster { key, mesh: cached, world: pose.world, gpu });
    }
    posed.get(&entity)
}

/// A Bevy mesh's triangles as the core's mesh, with its topology and its
/// packed GPU geometry.
pub(crate) fn core_mesh(mesh: &Mesh) -> CachedMesh {
    let positions = match mesh.try_attribute_option(Mesh::ATTRIBUTE_POSITION) {
        Ok(Some(VertexAttributeValues::Float32x3(p))) => p.iter().map(|p| Vec3::from_array(*p)).collect::<Vec<_>>(),
        Ok(_) => return Err(FinSceneError::NotTriangles),
        Err(_) => return Err(FinSceneError::NoMainWorldData),
    };
    core_mesh_at(mesh, positions)
}

/// [`core_mesh`] with the vertices at `positions` (a pose of the mesh).
fn core_mesh_at(mesh: &Mesh, positions: Vec<Vec3>) -> CachedMesh {
    let (core, topology) = core_topology_at(mesh, positions)?;
    let geometry = GpuMeshGeometry::pack(&topology);
    Ok((core, topology, Arc::new(geometry)))
}

/// [`core_mesh_at`] without the GPU packing.
fn core_topology_at(mesh: &Mesh, positions: Vec<Vec3>) -> Result<(Arc<CoreMesh>, Arc<Topology>), FinSceneError> {
    if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
        return Err(FinSceneError::NotTriangles);
    }
    let indices: Vec<u32> = match mesh.try_indices_option() {
        Ok(Some(Indices::U16(i))) => i.iter().map(|&i| i as u32).collect(),
        Ok(Some(Indices::U32(i))) => i.clone(),
        Ok(None) => (0..positions.len() as u32).collect(),
        Err(_) => return Err(FinSceneError::NoMainWorldData),
    };
    let core = CoreMesh::new(positions, indices).map_err(FinSceneError::Invalid)?;
    let topology = Topology::build(&core);
    Ok((Arc::new(core), Arc::new(topology)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small_box_at(p: Vec3) -> [Vec3; 8] {
        std::array::from_fn(|k| {
            p + Vec3::new((k & 1) as f32, ((k >> 1) & 1) as f32, ((k >> 2) & 1) as f32) * 0.2 - Vec3::splat(0.1)
        })
    }

    #[test]
    fn the_suns_angular_radius_is_half_its_sun_disk_clamped_and_earths_without_one() {
        let radius = |angular_size| sun_angular_radius(Some(&SunDisk { angular_size, intensity: 1.0 }));
        assert_eq!(sun_angular_radius(None), SunDisk::EARTH.angular_size * 0.5);
        assert_eq!(radius(0.2), 0.1);
        assert_eq!(radius(0.0), 0.0);
        assert_eq!(radius(-1.0), 0.0);
        assert_eq!(radius(f32::NAN), 0.0);
        assert_eq!(radius(f32::INFINITY), 1.4);
        assert_eq!(radius(f32::NEG_INFINITY), 0.0);
        assert_eq!(radius(10.0), 1.4);
        // Every clamped value is a valid core sun.
        for size in [0.0, 0.2, -1.0, f32::NAN, 10.0, f32::INFINITY] {
            assert!(SunLight::new(Vec3::NEG_Y, radius(size)).is_ok(), "{size}");
        }
    }

    #[test]
    fn casters_out_of_a_lights_reach_are_culled_and_none_in_it() {
        let disk = DiskLight::new(Vec3::ZERO, Vec3::NEG_Y, 0.5).unwrap();
        let spot = Reach { range: 10.0, cone: Some(0.5) };
        // On the axis, and just outside the cone but within what the disk subtends: kept.
        assert!(!out_of_reach(&small_box_at(Vec3::new(0.0, -3.0, 0.0)), &disk, spot));
        let edge = Vec3::new(0.6_f32.tan() * 3.0, -3.0, 0.0);
        assert!(!out_of_reach(&small_box_at(edge), &disk, spot));
        // Far outside the cone, behind the disk, beyond the range: culled.
        assert!(out_of_reach(&small_box_at(Vec3::new(3.0, -1.0, 0.0)), &disk, spot));
        assert!(out_of_reach(&small_box_at(Vec3::new(0.0, 2.0, 0.0)), &disk, spot));
        assert!(out_of_reach(&small_box_at(Vec3::new(0.0, -20.0, 0.0)), &disk, spot));
        // No cone, no range: only what is behind the disk goes.
        let everywhere = Reach { range: 0.0, cone: None };
        assert!(!out_of_reach(&small_box_at(Vec3::new(3.0, -1.0, 0.0)), &disk, everywhere));
        assert!(!out_of_reach(&small_box_at(Vec3::new(0.0, -1e6, 0.0)), &disk, everywhere));
        // A box around the light itself is never culled.
        assert!(!out_of_reach(&small_box_at(Vec3::ZERO), &disk, spot));
    }
}
