//! The casters every light's frame is built from, kept between frames and
//! updated per entity (issue 16, "big scenes that move").
//!
//! Three things scale with the number of mesh entities, and each is kept so
//! that a frame in which a few casters changed costs what those few cost:
//!
//! - [`CasterSignature`]: the casters' part of every light's signature, a sum
//!   of one hash per entity. A frame with changes rehashes only the changed
//!   entities (Bevy's change detection names them); the walk over every mesh
//!   ([`FinCasterScans`](crate::FinCasterScans)) is left for what may change
//!   every caster at once (a mesh asset loading or edited, a material's
//!   cut-out changing, a skin's bind poses loading, a sun starting to fit
//!   its views).
//! - [`CasterScene`]: the casters as core `SceneObject`s with their packed GPU
//!   geometry, boxes and layers. A caster that moved, changed its layers or
//!   shadow flags, changed its mesh or was posed again (a skinned or morphed
//!   mesh; the GPU poses its own copy, `pose.rs`) is rebuilt in its slot
//!   ([`CasterScene::update`]; new geometry makes each light pack its
//!   meshes again, `gpu_scene.rs`); one that appears, goes, is hidden or
//!   shown re-collects the scene.
//! - each light's objects and GPU instance records (`frame/build.rs`,
//!   `gpu_scene.rs`): after an in-place update of the scene, only the slots
//!   it names ([`CasterScene::dirty`]) are recomputed for a light whose own
//!   part did not change, and the render world writes only the instance
//!   records that differ (`render/extraction.rs`).
//!
//! What still scales with the scene when one caster moves is the GPU passes
//! that touch every instance or record once without extracting it (depth
//! and footprint reductions, retiring, layer assignment, gathering: only
//! the moved instances are extracted and the maps redrawn under them when
//! the plan stayed, `extract_*.wgsl`), a few flat loops
//! here (the scene's box, a copy of the instance records) and, for a caster
//! with new geometry (a mesh swapped, or a pose the GPU cannot pose), each
//! light's records and packed geometry.

use std::{
    collections::{HashMap, HashSet},
    hash::{Hash, Hasher},
    sync::Arc,
};

use bevy::{asset::AssetId, camera::visibility::RenderLayers, prelude::*};
use shadow_fins::{
    light::{CubeFace, Light, LightFrame},
    scene::SceneObject,
};

use crate::hashing::{hash_floats, hash_layers};

use self::{
    gpu_geometry::{GpuMeshGeometry, GpuPose},
    mesh::{CachedMesh, Casters, core_mesh, posed_mesh},
    reach::{LightSees, nearest_distance, out_of_reach, outside_face, world_corners},
};

pub(crate) mod cutout;
pub(crate) mod gpu_geometry;
pub(crate) mod gpu_scene;
pub(crate) mod mesh;
pub(crate) mod pose;
pub(crate) mod reach;
pub(crate) mod snapshot;

/// How many caster records were rebuilt in place, without a walk over every
/// mesh: `frames` in which it happened, `records` in all (a diagnostic of
/// the incremental path, beside [`FinCasterScans`](crate::FinCasterScans)).
#[derive(Resource, Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct FinCasterUpdates {
    pub frames: u64,
    pub records: u64,
}

/// One entity's part of the casters' signature, and its world box when it
/// is drawn (for a sun fitted to the views).
#[derive(Debug, Clone, Copy)]
struct SignedCaster {
    hash: u64,
    /// `None`: not drawn; `Some(None)`: drawn without an `Aabb`.
    drawn_box: Option<Option<(Vec3, Vec3)>>,
}

/// The casters' signature, kept between frames: the wrapping sum of one hash
/// per entity (order-free, so one entity's change is one subtraction and one
/// addition), and what changed since the scene last caught up.
#[derive(Default)]
pub(crate) struct CasterSignature {
    /// `None` before the first walk.
    pub signature: Option<u64>,
    per_entity: HashMap<Entity, SignedCaster>,
    sum: u64,
    pub scene_box: (Vec3, Vec3),
    pub every_mesh_boxed: bool,
    /// Whether the boxes are gathered (only when a sun is fitted to views).
    pub fitting: bool,
    /// Bumped when a mesh asset's content changes (same id, new triangles)
    /// or a material's cut-out does: every caster's frame changes.
    pub mesh_epoch: u64,
    /// Entities changed since the [`CasterScene`] last caught up; `None`
    /// after a walk (the scene is collected anew).
    pub pending: Option<HashSet<Entity>>,
}

/// What one entity contributes, read from its components.
#[allow(clippy::too_many_arguments)]
fn sign_caster(
    entity: Entity,
    casters: &Casters,
    meshes: &Assets<Mesh>,
    material_of: impl Fn(Entity) -> Option<AssetId<StandardMaterial>>,
    poses: &crate::casters::pose::Poses,
    fitting: bool,
) -> Option<SignedCaster> {
    let (entity, mesh, transform, caster) = casters.get(entity).ok()?;
    let mut hasher = std::collections::hash_map::DefaultHasher::new();
    entity.hash(&mut hasher);
    (caster.drawn(), caster.casts()).hash(&mut hasher);
    hash_layers(&caster.layers(), &mut hasher);
    if !caster.drawn() {
        return Some(SignedCaster { hash: hasher.finish(), drawn_box: None });
    }
    // The box culls casters by a light's range and cone, fitted or not.
    if let Some(b) = caster.aabb {
        hash_floats(&mut hasher, &[b.center.x, b.center.y, b.center.z]);
        hash_floats(&mut hasher, &[b.half_extents.x, b.half_extents.y, b.half_extents.z]);
    }
    let drawn_box = caster.aabb.filter(|_| fitting).map(|aabb| {
        world_corners(aabb, transform)
            .into_iter()
            .filter(|c| c.is_finite())
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), c| (lo.min(c), hi.max(c)))
    });
    mesh.id().hash(&mut hasher);
    // A mesh that finishes loading changes the frame too.
    meshes.contains(mesh.id()).hash(&mut hasher);
    // What it casts with (an alpha-masked material cuts it out).
    material_of(entity).hash(&mut hasher);
    hash_floats(&mut hasher, &transform.to_matrix().to_cols_array());
    poses.hash_pose(entity, &mut hasher);
    Some(SignedCaster { hash: hasher.finish(), drawn_box: Some(drawn_box) })
}

impl CasterSignature {
    /// Signs every caster anew (`changed`: `None`), or only `changed` ones.
    /// Returns whether it walked every mesh.
    pub fn update(
        &mut self,
        changed: Option<&HashSet<Entity>>,
        casters: &Casters,
        meshes: &Assets<Mesh>,
        material_of: impl Fn(Entity) -> Option<AssetId<StandardMaterial>>,
        poses: &crate::casters::pose::Poses,
        fitting: bool,
    ) -> bool {
        let walk = changed.is_none() || self.signature.is_none() || self.fitting != fitting;
        if walk {
            self.per_entity.clear();
            self.sum = 0;
            for (entity, ..) in casters {
                if let Some(signed) = sign_caster(entity, casters, meshes, &material_of, poses, fitting) {
                    self.sum = self.sum.wrapping_add(signed.hash);
                    self.per_entity.insert(entity, signed);
                }
            }
            self.pending = None;
        } else if let Some(changed) = changed {
            for &entity in changed {
                if let Some(old) = self.per_entity.remove(&entity) {
                    self.sum = self.sum.wrapping_sub(old.hash);
                }
                if let Some(signed) = sign_caster(entity, casters, meshes, &material_of, poses, fitting) {
                    self.sum = self.sum.wrapping_add(signed.hash);
                    self.per_entity.insert(entity, signed);
                }
            }
            if let Some(pending) = &mut self.pending {
                pending.extend(changed.iter().copied());
            }
        }
        self.fitting = fitting;
        // A mesh without an `Aabb` (`NoFrustumCulling`, `NoAutoAabb`) has no box
        // here: then no sun is fitted to the views, which could cut it out.
        let (mut scene_box, mut every_mesh_boxed) = ((Vec3::INFINITY, Vec3::NEG_INFINITY), true);
        if fitting {
            for drawn in self.per_entity.values().filter_map(|s| s.drawn_box) {
                match drawn {
                    Some((lo, hi)) => scene_box = (scene_box.0.min(lo), scene_box.1.max(hi)),
                    None => every_mesh_boxed = false,
                }
            }
        }
        (self.scene_box, self.every_mesh_boxed) = (scene_box, every_mesh_boxed);
        let mut hasher = std::collections::hash_map::DefaultHasher::new();
        (self.mesh_epoch, self.sum, self.per_entity.len()).hash(&mut hasher);
        self.signature = Some(hasher.finish());
        walk
    }
}

/// A caster entity as the scene holds it.
enum Slot {
    /// Hidden, or not a mesh entity (any more): neither casts nor receives.
    NotDrawn,
    /// Drawn but unreadable here (a mesh not loaded, render-world only, or
    /// invalid): it receives all the same, within these bounds.
    Unread(Option<[Vec3; 8]>),
    Object(Box<ObjectSlot>),
}

struct ObjectSlot {
    object: SceneObject,
    gpu_mesh: Arc<GpuMeshGeometry>,
    /// The pose the GPU poses `gpu_mesh` at (a posable packing), if any.
    gpu_pose: Option<Arc<GpuPose>>,
    bounds: Option<[Vec3; 8]>,
    world_box: (Vec3, Vec3),
    layers: RenderLayers,
}

/// What builds a caster's slot: the meshes, their converted and posed
/// copies, the poses and the materials.
/// (Each system parameter keeps its own lifetimes: a `&mut` to one fixes them.)
pub(crate) struct SlotSources<'a, 'cw, 'cs, 'pw, 'ps, 'mw, 'ms> {
    pub casters: &'a Casters<'cw, 'cs>,
    pub meshes: &'a Assets<Mesh>,
    pub cache: &'a mut HashMap<AssetId<Mesh>, CachedMesh>,
    pub posed: &'a mut HashMap<Entity, crate::casters::mesh::PosedCaster>,
    pub posable: &'a mut HashMap<AssetId<Mesh>, Option<Arc<GpuMeshGeometry>>>,
    /// The GPU poses what it can ([`FinGpuPosing`](crate::casters::pose::FinGpuPosing)).
    pub gpu_posing: bool,
    pub poses: &'a crate::casters::pose::Poses<'pw, 'ps>,
    pub materials: &'a mut crate::casters::cutout::CasterMaterials<'mw, 'ms>,
}

impl SlotSources<'_, '_, '_, '_, '_, '_, '_> {
    fn slot(&mut self, entity: Entity) -> Slot {
        let Ok((entity, mesh3d, transform, caster)) = self.casters.get(entity) else {
            return Slot::NotDrawn;
        };
        // A hidden mesh is not drawn: it neither casts nor receives.
        if !caster.drawn() {
            return Slot::NotDrawn;
        }
        let mut corners = caster.aabb.map(|b| world_corners(b, transform));
        let Some(mesh) = self.meshes.get(mesh3d.id()) else {
            return Slot::Unread(corners);
        };
        // A skinned or morphed mesh in its current pose (`pose.rs`); any
        // other mesh as stored, converted once per asset.
        let posable = Some(&mut *self.posable).filter(|_| self.gpu_posing);
        let posed = posed_mesh(entity, mesh3d.id(), mesh, self.posed, self.cache, posable, self.poses);
        // A posed mesh's topology is this pose's (even where `world` is
        // false: a morph alone): nothing made from it is cached per asset.
        let is_posed = posed.is_some();
        // A mesh the GPU poses: its mesh at rest, whose outline the GPU poses with it.
        let rest = match posed.filter(|p| p.gpu.is_some()).and(self.cache.get(&mesh3d.id())) {
            Some(Ok((core, topology, _))) => Some((core.clone(), topology.clone())),
            _ => None,
        };
        let (entry, world, gpu_pose) = match posed {
            Some(p) => (&p.mesh, p.world, p.gpu.clone()),
            None => {
                let entry = self.cache.entry(mesh3d.id()).or_insert_with(|| {
                    let converted = core_mesh(mesh);
                    if let Err(e) = &converted {
                        warn!("fin shadows: mesh {:?} casts no fin shadow: {e:?}", mesh3d.id());
                    }
                    converted
                });
                (&*entry, false, None)
            }
        };
        let Ok((core, topology, geometry)) = entry else {
            return Slot::Unread(corners);
        };
        let placed = if world { bevy::math::Affine3A::IDENTITY } else { transform.affine() };
        if world {
            // Its box is where the pose put it, not Bevy's (which may lag a frame).
            corners = Some(crate::casters::reach::box_corners(topology.bounds));
        }
        match SceneObject::shared("mesh", core.clone(), topology.clone(), placed) {
            Ok(mut object) => {
                // Meshes that do not cast still receive: they count for the reference plane.
                object.casts_shadows = caster.casts();
                let mut gpu_mesh = geometry.clone();
                if object.casts_shadows {
                    object.cutout = self.materials.cutout(entity, mesh3d.id(), mesh, core, topology, is_posed);
                    // The GPU extracts an alpha-masked caster from its outline:
                    // this pose's, or, when the GPU poses it, its rest
                    // outline posed with it.
                    match (object.fitting_cutout(), &gpu_pose) {
                        (Some(cutout), None) => {
                            gpu_mesh = self.materials.outlined_packing(entity, mesh3d.id(), topology, cutout, is_posed);
                        }
                        (Some(_), Some(_)) => {
                            let packing = rest.and_then(|(core, topology)| {
                                self.materials.outlined_posable_packing(entity, mesh3d.id(), mesh, (&core, &topology))
                            });
                            // Else it stays solid on the GPU, and its frames extract on the CPU.
                            gpu_mesh = packing.unwrap_or(gpu_mesh);
                        }
                        (None, _) => {}
                    }
                }
                // The posed vertices' box (a posable packing's is the rest pose's).
                let world_box = crate::casters::reach::box_corners(topology.bounds)
                    .map(|c| object.transform.transform_point3(c))
                    .into_iter()
                    .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(p), hi.max(p)));
                Slot::Object(Box::new(ObjectSlot {
                    object,
                    gpu_mesh,
                    gpu_pose,
                    bounds: corners,
                    world_box,
                    layers: caster.layers(),
                }))
            }
            // A degenerate transform: Bevy may still draw it; it receives.
            Err(_) => Slot::Unread(corners),
        }
    }
}

/// The drawn casters, one slot per object, kept between frames.
pub(crate) struct CasterScene {
    pub objects: Vec<SceneObject>,
    pub gpu_meshes: Vec<Arc<GpuMeshGeometry>>,
    /// Each object's pose, when the GPU poses its mesh (`pose.wgsl`).
    pub gpu_poses: Vec<Option<Arc<GpuPose>>>,
    /// Each object's world bounding box corners (from Bevy's `Aabb`), for
    /// the lights' range culling; `None` is never culled.
    bounds: Vec<Option<[Vec3; 8]>>,
    /// Each object's mesh box in the world (its vertices' box carried by its
    /// transform: what the frames' extents are made of).
    world_boxes: Vec<(Vec3, Vec3)>,
    /// Each object's `RenderLayers`.
    layers: Vec<RenderLayers>,
    /// The entity of each object.
    entities: Vec<Entity>,
    index: HashMap<Entity, usize>,
    /// World bounds of meshes drawn but unreadable here (render-world only,
    /// invalid): receivers all the same, so the reference plane must cover them.
    pub unread_bounds: Vec<[Vec3; 8]>,
    unread: HashSet<Entity>,
    /// The readable objects' world box ([`Self::measure_boxes`]).
    pub objects_box: (Vec3, Vec3),
    /// Every drawn mesh's world box, readable or not.
    drawn_box: (Vec3, Vec3),
    /// Bumped by every collect and update.
    pub version: u64,
    /// The slots the latest update rebuilt in place; `None` when the latest
    /// change re-collected the scene.
    pub dirty: Option<Vec<usize>>,
    /// The nearest caster's distance from each point light's centre, found
    /// once for its six faces.
    nearest: std::sync::Mutex<HashMap<[u32; 3], f32>>,
}

impl CasterScene {
    /// Every drawn mesh entity, in the query's order.
    pub fn collect(sources: &mut SlotSources<'_, '_, '_, '_, '_, '_, '_>, version: u64) -> Self {
        let mut scene = Self {
            objects: vec![],
            gpu_meshes: vec![],
            gpu_poses: vec![],
            bounds: vec![],
            world_boxes: vec![],
            layers: vec![],
            entities: vec![],
            index: HashMap::new(),
            unread_bounds: vec![],
            unread: HashSet::new(),
            objects_box: (Vec3::INFINITY, Vec3::NEG_INFINITY),
            drawn_box: (Vec3::ZERO, Vec3::ONE),
            version,
            dirty: None,
            nearest: Default::default(),
        };
        let casters = sources.casters;
        sources.posed.retain(|e, _| casters.contains(*e));
        for (entity, ..) in casters.iter() {
            match sources.slot(entity) {
                Slot::NotDrawn => {}
                Slot::Unread(corners) => {
                    scene.unread.insert(entity);
                    scene.unread_bounds.extend(corners);
                }
                Slot::Object(slot) => {
                    scene.index.insert(entity, scene.objects.len());
                    scene.entities.push(entity);
                    scene.objects.push(slot.object);
                    scene.gpu_meshes.push(slot.gpu_mesh);
                    scene.gpu_poses.push(slot.gpu_pose);
                    scene.bounds.push(slot.bounds);
                    scene.world_boxes.push(slot.world_box);
                    scene.layers.push(slot.layers);
                }
            }
        }
        scene.measure_boxes();
        scene
    }

    /// Rebuilds the slots of `changed` entities in place and names them in
    /// [`Self::dirty`]. Returns false, changing nothing, when a change is not
    /// one of a slot's content (an object appearing or going, turning
    /// unreadable or back): then the scene must be collected anew. Other
    /// geometry (a mesh swapped, a new pose) is a slot's content.
    pub fn update(&mut self, changed: &HashSet<Entity>, sources: &mut SlotSources<'_, '_, '_, '_, '_, '_, '_>) -> bool {
        let mut rebuilt = Vec::with_capacity(changed.len());
        for &entity in changed {
            let slot = sources.slot(entity);
            match (self.index.get(&entity), slot) {
                (None, Slot::NotDrawn) if !self.unread.contains(&entity) => {}
                // Its mesh or pose may have changed: the lights' builders see a
                // new packing and pack their geometry again.
                (Some(&i), Slot::Object(slot)) => rebuilt.push((i, slot)),
                _ => return false,
            }
        }
        let mut dirty = Vec::with_capacity(rebuilt.len());
        for (i, slot) in rebuilt {
            let ObjectSlot { object, gpu_mesh, gpu_pose, bounds, world_box, layers } = *slot;
            (self.objects[i], self.gpu_meshes[i], self.gpu_poses[i], self.bounds[i]) =
                (object, gpu_mesh, gpu_pose, bounds);
            (self.world_boxes[i], self.layers[i]) = (world_box, layers);
            dirty.push(i);
        }
        self.measure_boxes();
        self.version += 1;
        self.dirty = Some(dirty);
        self.nearest.lock().unwrap_or_else(|e| e.into_inner()).clear();
        true
    }

    /// The distance from `point` to the nearest casting triangle, as the
    /// core's `nearest_caster_distance` finds it; objects whose box lies
    /// farther than the nearest triangle found yet are not scanned.
    fn nearest_caster(&self, point: Vec3) -> f32 {
        let mut order: Vec<(f32, usize)> = (self.objects.iter().zip(&self.bounds).enumerate())
            .filter(|(_, (o, _))| o.casts_shadows)
            .map(|(i, (_, b))| (b.map_or(0.0, |b| nearest_distance(&b, point)), i))
            .collect();
        order.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut nearest = f32::INFINITY;
        for (lower_bound, i) in order {
            if lower_bound >= nearest {
                break;
            }
            nearest = nearest.min(shadow_fins::scene::nearest_triangle_distance(&self.objects[i], point));
        }
        nearest
    }

    /// Object `i` as one light sees it: a caster on no layer of the light's,
    /// or out of its reach (beyond its range, outside its cone, wholly behind
    /// its disk, or — for a point light's cube face — wholly outside the
    /// face's window frustum) casts nothing for it, but still receives.
    pub fn seen_by_one(&self, i: usize, light: &Light, frame: &LightFrame, sees: LightSees) -> SceneObject {
        let (mut o, bounds, layers) = (self.objects[i].clone(), &self.bounds[i], &self.layers[i]);
        // The sun lights everything in front of it: no caster is out of its reach.
        let out = match light {
            Light::Disk(disk) => bounds.is_some_and(|b| out_of_reach(&b, disk, sees.reach)),
            // A rectangle reaches what its bounding disk reaches.
            Light::Rect(r) => bounds.is_some_and(|b| out_of_reach(&b, &r.bounding_disk(), sees.reach)),
            Light::Sun(_) => false,
            Light::Sphere(s) => bounds.is_some_and(|b| {
                let beyond = sees.reach.range > 0.0 && nearest_distance(&b, s.center) > sees.reach.range + s.radius;
                beyond || outside_face(&b, frame)
            }),
        };
        if o.casts_shadows && (out || !layers.intersects(sees.layers)) {
            o.casts_shadows = false;
        }
        o
    }

    /// Every object as one light sees it ([`Self::seen_by_one`]).
    pub fn seen_by(&self, light: &Light, frame: &LightFrame, sees: LightSees) -> Vec<SceneObject> {
        (0..self.objects.len()).map(|i| self.seen_by_one(i, light, frame, sees)).collect()
    }

    /// The boxes every light's frame reads, made once per collect or update:
    /// the readable objects' and (a unit box when nothing is drawn) every
    /// drawn mesh's, readable or not.
    fn measure_boxes(&mut self) {
        self.objects_box = self
            .world_boxes
            .iter()
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), b| (lo.min(b.0), hi.max(b.1)));
        let (lo, hi) = self
            .unread_bounds
            .iter()
            .flatten()
            .filter(|p| p.is_finite())
            .fold(self.objects_box, |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        self.drawn_box = if lo.x <= hi.x { (lo, hi) } else { (Vec3::ZERO, Vec3::ONE) };
    }

    /// The light's frame. A disk's is its own; the sun's origin is put in
    /// front of everything drawn (every mesh's world box, readable or not),
    /// so that every depth is positive (`LightFrame::sun`); a point light's
    /// cube face covers a margin for the caster nearest to the light
    /// (`SphereLight::face_window`, the core's `nearest_caster_distance`,
    /// triangles scanned only in boxes nearer than the nearest found yet).
    pub fn frame_for(&self, light: &Light, face: Option<CubeFace>) -> (LightFrame, (Vec3, Vec3)) {
        let (lo, hi) = self.drawn_box;
        if let (Light::Sphere(sphere), Some(face)) = (light, face) {
            let key = sphere.center.to_array().map(f32::to_bits);
            let mut known = self.nearest.lock().unwrap_or_else(|e| e.into_inner());
            let nearest = *known.entry(key).or_insert_with(|| self.nearest_caster(sphere.center));
            return (sphere.face_frame(face, sphere.face_window(nearest)), (lo, hi));
        }
        (LightFrame::new(light, lo, hi), (lo, hi))
    }
}
