//! One light's input to the GPU extraction: the packed geometry of its
//! casters' meshes (`gpu_geometry.rs`) and one small record per caster
//! instance (its transform into the light frame) rebuilt when something
//! moves, with the extraction's buffer capacities.

use crate::{
    casters::gpu_geometry::{GpuMeshGeometry, GpuPose, HEADER_WORDS, POSE_JOB_WORDS, POSES_HEADER_WORDS},
    gpu_layout::{CASTER_BYTES, FACE_STATE_WORDS, FIN_BYTES, SILHOUETTE_BYTES, VERTEX_STATE_WORDS},
};
use bevy::prelude::*;
use shadow_fins::{
    cutout::AlphaMask,
    light::LightFrame,
    scene::{LightInObject, ObjectToFrame, SceneObject},
};
use std::{
    collections::HashMap,
    hash::{Hash, Hasher},
    sync::Arc,
};

/// One caster instance, the layout of `Instance` in `extract_common.wgsl`.
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct GpuInstance {
    pub(crate) linear: [[f32; 4]; 3],
    pub(crate) translation: [f32; 4],
    pub(crate) normal: [[f32; 4]; 3],
    pub(crate) light: [f32; 4],
    /// (geometry word offset, first vertex, first caster face, first caster edge)
    pub(crate) ids: [u32; 4],
    /// (flags 1 casts / 2 closed / 4 mirrors, vertices, caster faces, caster edges)
    pub(crate) info: [u32; 4],
    /// (its pose's hash, low and high words; its cut-out: 0 solid, else 1 +
    /// where its mask starts in the scene's mask words; 0): a new pose
    /// changes the record.
    pub(crate) pose: [u32; 4],
}

impl GpuInstance {
    /// (flags 1 casts / 2 closed / 4 mirrors, vertices, caster faces, caster edges)
    pub fn info(&self) -> [u32; 4] {
        self.info
    }
}

/// Sizes of the GPU extraction's output buffers. They start from the scene's
/// size and grow when a read-back shows a frame needed more (see
/// `FinShadowStats`); they never shrink.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub(crate) struct GpuCapacity {
    pub silhouettes: u32,
    pub fins: u32,
    pub casters: u32,
    /// Layers the maps are allocated for.
    pub layers: u32,
}

impl GpuCapacity {
    /// A first guess for a scene: silhouettes are a small share of a big
    /// scene's edges. With the quarter of room [`Self::resized_for`] keeps, so
    /// that a small scene of open or masked meshes (every face a caster,
    /// nearly every outline edge a silhouette) does not grow, and extract
    /// again, on its first read-back.
    pub(crate) fn initial(faces: u32, edges: u32) -> Self {
        let room = |n: u32| n.saturating_add(n / 4);
        let silhouettes = room(edges).min(4096 + edges / 16).max(64);
        Self { silhouettes, fins: 4 * silhouettes + 64, casters: room(faces).saturating_add(64), layers: 1 }
    }

    fn max(self, o: Self) -> Self {
        Self {
            silhouettes: self.silhouettes.max(o.silhouettes),
            fins: self.fins.max(o.fins),
            casters: self.casters.max(o.casters),
            layers: self.layers.max(o.layers),
        }
    }

    /// Resized to what a read-back says a frame wanted. Grown, with a
    /// quarter more room, when the frame needed more than its capacity minus
    /// that room, but never past `max`. (The room is for the records an
    /// incremental update retires and appends again, `extract_*.wgsl`: a
    /// buffer the live records fill has none, and every update would extract
    /// everything. An alpha-masked card's outline is nearly all silhouettes.)
    /// Shrunk to half as much again as wanted when that is under a quarter of
    /// the capacity (a scene that got smaller), but never below `floor`, the
    /// scene's first guess ([`Self::initial`], which a build takes at least).
    /// Layers only grow. `None` if nothing changes.
    pub fn resized_for(self, wanted: Self, floor: Self, max: Self) -> Option<Self> {
        let fit = |have: u32, want: u32, floor: u32, max: u32| {
            let roomy = want.saturating_add(want / 2);
            if want.saturating_add(want / 4) > have {
                roomy.min(max).max(have)
            } else if roomy < have / 4 {
                roomy.max(floor).min(have)
            } else {
                have
            }
        };
        let next = Self {
            silhouettes: fit(self.silhouettes, wanted.silhouettes, floor.silhouettes, max.silhouettes),
            fins: fit(self.fins, wanted.fins, floor.fins, max.fins),
            casters: fit(self.casters, wanted.casters, floor.casters, max.casters),
            // Layers exactly: each one is a full set of maps.
            layers: self.layers.max(wanted.layers.min(max.layers)),
        };
        (next != self).then_some(next)
    }

    /// The most each output buffer may hold under a `limit`-byte buffer.
    pub fn max_for(limit: u64) -> Self {
        let records = |bytes: u64| (limit / bytes).min(u32::MAX as u64) as u32;
        Self {
            silhouettes: records(SILHOUETTE_BYTES),
            fins: records(FIN_BYTES),
            casters: records(CASTER_BYTES),
            layers: crate::settings::MAX_LAYERS,
        }
    }

    /// Each output buffer that could not hold what a frame wanted: `(buffer,
    /// kept, wanted)`.
    pub fn shortfalls(self, wanted: Self) -> impl Iterator<Item = (&'static str, u32, u32)> {
        [
            ("silhouettes", self.silhouettes, wanted.silhouettes),
            ("fins", self.fins, wanted.fins),
            ("map casters", self.casters, wanted.casters),
        ]
        .into_iter()
        .filter(|(_, kept, wanted)| wanted > kept)
    }

    fn min(self, o: Self) -> Self {
        Self {
            silhouettes: self.silhouettes.min(o.silhouettes),
            fins: self.fins.min(o.fins),
            casters: self.casters.min(o.casters),
            layers: self.layers.min(o.layers),
        }
    }
}

/// Everything the GPU extraction needs for one frame.
#[derive(Debug)]
pub(crate) struct GpuScene {
    /// Every caster mesh's packed geometry, concatenated, then a copy of its
    /// packing for each posed instance (which `pose.wgsl` poses in place);
    /// replaced only when the set of meshes changes (`geometry_key`).
    pub geometry: Arc<Vec<u32>>,
    pub geometry_key: u64,
    pub instances: Vec<GpuInstance>,
    /// What poses the posed instances' copies (`pose.wgsl`): empty when no
    /// instance is posed on the GPU; a new `Arc` only when it changed.
    pub poses: Arc<Vec<u32>>,
    /// The alpha masks the outlined instances cut their casters with
    /// (`cutout::pack_mask`, each once): empty when none is.
    pub mask_words: Arc<Vec<u32>>,
    /// (instance vertices, caster faces, caster edges)
    pub totals: [u32; 3],
    pub capacity: GpuCapacity,
    /// The most the buffers may hold under the device limit and the budget.
    pub max_capacity: GpuCapacity,
    pub axes: [bevy::math::DVec3; 3],
    /// Deepest light-frame depth of receivers drawn but not read here (their
    /// bounds): the reference plane reaches at least this far.
    pub receiver_depth: f32,
    /// The maps' region lies within this (map space; a sun's view fit).
    pub map_window: Option<(Vec2, Vec2)>,
    /// `receiver_depth` is `L0` itself (a sun fitted to the views), not a
    /// bound the casters' vertices may raise.
    pub fixed_reference_depth: bool,
    /// World-space diagonal of the scene's bounds (epsilons; L0 when nothing is in front).
    pub extent: f32,
}

/// Builds [`GpuScene`]s, keeping the concatenated geometry and the instance
/// records between frames.
#[derive(Debug, Default)]
pub(crate) struct GpuSceneBuilder {
    geometry: Arc<Vec<u32>>,
    geometry_key: u64,
    /// Word offset of each packing in `geometry`.
    offsets: HashMap<u64, u32>,
    /// Per object posed on the GPU: its packing and the word offset of its
    /// own copy of it in `geometry`.
    posed_copies: HashMap<usize, (u64, u32)>,
    /// The records of the last build, one per object.
    instances: Vec<GpuInstance>,
    totals: [u32; 3],
    /// The pose buffer of the last build.
    poses: Arc<Vec<u32>>,
    /// The masks packed in `mask_words`, each with where it starts there.
    masks: Vec<(Arc<AlphaMask>, u32)>,
    mask_words: Arc<Vec<u32>>,
}

impl GpuSceneBuilder {
    /// The scene of `objects` (with `meshes` and `poses`, one per object) in
    /// `frame`; `extent_box` is the objects' world box. With `dirty`, only
    /// those objects changed since the last build, which had the same objects
    /// and frame: only their records are made again (and every record's first
    /// ids when a changed one casts more or fewer faces) — unless one of them
    /// has a mesh not packed yet (it changed its mesh, or a pose the GPU does
    /// not pose): then all are. A pose posed on the GPU is not a new mesh:
    /// only its record and the pose buffer change.
    #[allow(clippy::too_many_arguments)]
    pub fn build(
        &mut self,
        objects: &[SceneObject],
        meshes: &[Arc<GpuMeshGeometry>],
        poses: &[Option<Arc<GpuPose>>],
        frame: &LightFrame,
        extent_box: (Vec3, Vec3),
        dirty: Option<&[usize]>,
        capacity_slot: &mut Option<GpuCapacity>,
        max_capacity: GpuCapacity,
    ) -> GpuScene {
        // In place while every mesh is packed already (and every object
        // posed on the GPU has its copy); a changed mesh or a pose posed on
        // the CPU (a new packing) packs the geometry and every record again.
        let in_place = |dirty: &&[usize]| {
            self.instances.len() == objects.len()
                && !self.geometry.is_empty()
                && dirty.iter().all(|&i| match &poses[i] {
                    Some(_) => self.posed_copies.get(&i).is_some_and(|(packing, _)| *packing == meshes[i].packing),
                    None => self.offsets.contains_key(&meshes[i].packing) && !self.posed_copies.contains_key(&i),
                })
                && dirty.iter().all(|&i| cut_mask(&objects[i], &meshes[i]).is_none_or(|m| self.mask_at(m).is_some()))
        };
        let in_place = dirty.filter(in_place);
        match in_place {
            Some(dirty) => self.update_records(objects, meshes, poses, frame, dirty),
            None => self.build_records(objects, meshes, poses, frame),
        }
        // The pose buffer anew only when a posed object's record or any
        // offset may have changed (a rigid caster moving keeps it), and a
        // new `Arc` only when its words did (a light that moved rebuilds
        // every record, and must not pose every posed copy again).
        if in_place.is_none_or(|dirty| dirty.iter().any(|&i| poses[i].is_some())) {
            let words = self.pose_buffer(meshes, poses);
            if words != *self.poses {
                self.poses = Arc::new(words);
            }
        }
        let (lo, hi) = extent_box;
        let extent = if lo.x <= hi.x { (hi - lo).length().max(1e-30) } else { 1.0 };
        let [_, faces, edges] = self.totals;
        let needed = GpuCapacity::initial(faces, edges);
        let capacity = capacity_slot.map_or(needed, |c| c.max(GpuCapacity { layers: 1, ..needed })).min(max_capacity);
        let capacity = *capacity_slot.insert(capacity);
        GpuScene {
            geometry: self.geometry.clone(),
            geometry_key: self.geometry_key,
            instances: self.instances.clone(),
            poses: self.poses.clone(),
            mask_words: self.mask_words.clone(),
            totals: self.totals,
            capacity,
            max_capacity,
            axes: frame.axes_f64(),
            receiver_depth: 0.0,
            map_window: None,
            fixed_reference_depth: false,
            extent,
        }
    }

    /// Every record anew, and the geometry when the set of meshes (or of
    /// objects posed on the GPU) changed.
    fn build_records(
        &mut self,
        objects: &[SceneObject],
        meshes: &[Arc<GpuMeshGeometry>],
        poses: &[Option<Arc<GpuPose>>],
        frame: &LightFrame,
    ) {
        // The distinct meshes in first-use order (a posed one too: its pose
        // section is read from there), then each object posed on the GPU
        // (its own copy, less the pose section); re-pack only when that
        // list changes.
        let mut distinct: Vec<&Arc<GpuMeshGeometry>> = Vec::new();
        let mut seen = std::collections::HashSet::new();
        let mut hasher = std::collections::hash_map::DefaultHasher::new();
        for m in meshes {
            if seen.insert(m.packing) {
                distinct.push(m);
                m.packing.hash(&mut hasher);
            }
        }
        let posed: Vec<usize> = (0..meshes.len()).filter(|&i| poses[i].is_some()).collect();
        debug_assert!(posed.iter().all(|&i| meshes[i].posable()), "a pose for a packing with no pose section");
        for &i in &posed {
            (i, meshes[i].packing).hash(&mut hasher);
        }
        let key = hasher.finish();
        if key != self.geometry_key || self.geometry.is_empty() {
            let copies = posed.iter().map(|&i| meshes[i].posed_part().len()).sum::<usize>();
            let mut words = Vec::with_capacity(distinct.iter().map(|d| d.words.len()).sum::<usize>() + copies);
            self.offsets.clear();
            self.posed_copies.clear();
            for d in &distinct {
                self.offsets.insert(d.packing, words.len() as u32);
                words.extend_from_slice(&d.words);
            }
            for &i in &posed {
                self.posed_copies.insert(i, (meshes[i].packing, words.len() as u32));
                words.extend_from_slice(meshes[i].posed_part());
            }
            // A binding may not be empty.
            words.resize(words.len().max(HEADER_WORDS), 0);
            self.geometry = Arc::new(words);
            self.geometry_key = key;
        }
        self.pack_masks(objects, meshes);
        self.instances =
            (0..objects.len()).map(|i| self.record(i, &objects[i], &meshes[i], &poses[i], frame)).collect();
        self.number_records();
    }

    /// The `dirty` records anew; the first ids again only when a count moved.
    fn update_records(
        &mut self,
        objects: &[SceneObject],
        meshes: &[Arc<GpuMeshGeometry>],
        poses: &[Option<Arc<GpuPose>>],
        frame: &LightFrame,
        dirty: &[usize],
    ) {
        let mut counts_moved = false;
        for &i in dirty {
            let record = self.record(i, &objects[i], &meshes[i], &poses[i], frame);
            let old = &mut self.instances[i];
            counts_moved |= record.info[1..] != old.info[1..];
            // Its geometry is the new record's (a mesh swapped for one
            // packed already); its first ids stay unless a count moved.
            *old = GpuInstance { ids: [record.ids[0], old.ids[1], old.ids[2], old.ids[3]], ..record };
        }
        if counts_moved {
            self.number_records();
        }
    }

    /// The masks the objects cut their casters with, each once, in
    /// first-use order; packed anew only when that list changed.
    fn pack_masks(&mut self, objects: &[SceneObject], meshes: &[Arc<GpuMeshGeometry>]) {
        let mut masks: Vec<&Arc<AlphaMask>> = Vec::new();
        for (o, m) in objects.iter().zip(meshes) {
            if let Some(mask) = cut_mask(o, m)
                && !masks.iter().any(|k| Arc::ptr_eq(k, mask))
            {
                masks.push(mask);
            }
        }
        let same =
            masks.len() == self.masks.len() && masks.iter().zip(&self.masks).all(|(a, (b, _))| Arc::ptr_eq(a, b));
        if same {
            return;
        }
        let mut words = Vec::new();
        self.masks = masks.into_iter().map(|m| (m.clone(), crate::casters::cutout::pack_mask(m, &mut words))).collect();
        self.mask_words = Arc::new(words);
    }

    /// Where `mask` starts in the mask words, if packed.
    fn mask_at(&self, mask: &Arc<AlphaMask>) -> Option<u32> {
        self.masks.iter().find(|(m, _)| Arc::ptr_eq(m, mask)).map(|(_, at)| *at)
    }

    /// Each record's first vertex, face and edge: the counts before it.
    fn number_records(&mut self) {
        let mut totals = [0u32; 3];
        for instance in &mut self.instances {
            instance.ids[1..].copy_from_slice(&totals);
            for (total, count) in totals.iter_mut().zip(&instance.info[1..]) {
                *total += count;
            }
        }
        self.totals = totals;
    }

    /// The pose buffer `pose.wgsl` reads: a header (jobs; the most vertices,
    /// faces and edges of one; the cosine of the crease angle), a job per
    /// object posed on the GPU (its copy's offset in the geometry, its data's
    /// offset here, its joints, its morph weights, 1 when skinned, the
    /// offset of its mesh's shared packing, whose pose section it is posed
    /// from), then each job's joint columns and morph weights.
    fn pose_buffer(&self, meshes: &[Arc<GpuMeshGeometry>], poses: &[Option<Arc<GpuPose>>]) -> Vec<u32> {
        let jobs: Vec<(usize, &GpuPose)> =
            poses.iter().enumerate().filter_map(|(i, p)| Some((i, &**p.as_ref()?))).collect();
        if jobs.is_empty() {
            return Vec::new();
        }
        let mut sizes = [jobs.len() as u32, 0, 0, 0];
        let mut words = vec![0u32; POSES_HEADER_WORDS + POSE_JOB_WORDS * jobs.len()];
        words[4] = shadow_fins::mesh::CREASE_ANGLE_DEG.to_radians().cos().to_bits();
        for (k, (i, pose)) in jobs.iter().enumerate() {
            let m = &meshes[*i];
            sizes[1] = sizes[1].max(m.vertices);
            sizes[2] = sizes[2].max(m.faces);
            sizes[3] = sizes[3].max(m.edges);
            let at = words.len() as u32;
            words.extend(pose.joints.iter().flatten().map(|x| x.to_bits()));
            words.extend(pose.morph_weights.iter().map(|x| x.to_bits()));
            let job = POSES_HEADER_WORDS + POSE_JOB_WORDS * k;
            words[job..job + 6].copy_from_slice(&[
                self.posed_copies[i].1,
                at,
                pose.joints.len() as u32,
                pose.morph_weights.len() as u32,
                pose.skinned as u32,
                self.offsets[&m.packing],
            ]);
        }
        words[..4].copy_from_slice(&sizes);
        words
    }

    /// Object `i`'s record, its first ids left at 0 (`number_records`).
    fn record(
        &self,
        i: usize,
        object: &SceneObject,
        mesh: &GpuMeshGeometry,
        pose: &Option<Arc<GpuPose>>,
        frame: &LightFrame,
    ) -> GpuInstance {
        let to_frame = ObjectToFrame::new(object, frame);
        // The light as a homogeneous point for the facing test n·c > d·w:
        // the disk's centre (w = 1), or the sun at infinity against its
        // travel direction (w = 0: n·(−dir) > 0).
        let light = match to_frame.light_in_object(frame) {
            LightInObject::Point(c) => c.extend(1.0),
            LightInObject::Direction(d) => (-d).extend(0.0),
        };
        let c = to_frame.linear;
        let sign = if to_frame.mirrors { -1.0 } else { 1.0 };
        let cofactor = [c.y_axis.cross(c.z_axis), c.z_axis.cross(c.x_axis), c.x_axis.cross(c.y_axis)];
        let v4 = |v: Vec3| [v.x, v.y, v.z, 0.0];
        let casts = object.casts_shadows;
        let (f, e) = if casts { (mesh.faces, mesh.edges) } else { (0, 0) };
        // A closed mesh with the light inside is drawn both sides, like an open one.
        let closed = mesh.closed && !to_frame.light_inside;
        let flags = casts as u32 | (closed as u32) << 1 | (to_frame.mirrors as u32) << 2;
        let (offset, hash) = match pose {
            Some(pose) => (self.posed_copies[&i].1, pose.hash),
            None => (self.offsets[&mesh.packing], 0),
        };
        // Packed by `pack_masks` (a full build) or checked by `build` (in place).
        let cutout = cut_mask(object, mesh).and_then(|m| self.mask_at(m)).map_or(0, |at| at + 1);
        GpuInstance {
            linear: [v4(c.x_axis), v4(c.y_axis), v4(c.z_axis)],
            translation: v4(to_frame.translation),
            normal: cofactor.map(|n| v4(n * sign)),
            light: light.to_array(),
            ids: [offset, 0, 0, 0],
            info: [flags, mesh.vertices, f, e],
            pose: [hash as u32, (hash >> 32) as u32, cutout, 0],
        }
    }
}

/// The mask an object cuts its casters with on the GPU: a casting object
/// whose cut-out fits its mesh, packed with that cut-out's outline.
pub(crate) fn cut_mask<'a>(object: &'a SceneObject, mesh: &GpuMeshGeometry) -> Option<&'a Arc<AlphaMask>> {
    object.fitting_cutout().filter(|_| object.casts_shadows && mesh.outlined).map(|c| &c.mask)
}

/// (jobs, most vertices, faces, edges of one) of a pose buffer: its first
/// words (none when it is empty).
pub(crate) fn pose_sizes(poses: &[u32]) -> [u32; 4] {
    poses.get(..4).map_or([0; 4], |w| [w[0], w[1], w[2], w[3]])
}

impl GpuScene {
    /// (jobs, most vertices, faces, edges of one): the posing passes' sizes,
    /// the pose buffer's first words.
    pub fn pose_sizes(&self) -> [u32; 4] {
        pose_sizes(&self.poses)
    }

    /// Bytes of the extraction's buffers that the scene sizes by itself.
    pub fn input_bytes(&self) -> [(&'static str, u64); 5] {
        let [vertices, faces, edges] = self.totals.map(|x| x as u64);
        [
            ("packed geometry", self.geometry.len() as u64 * 4),
            ("poses", self.poses.len() as u64 * 4),
            ("instances", self.instances.len() as u64 * size_of::<GpuInstance>() as u64),
            ("face, edge and vertex state", (faces * FACE_STATE_WORDS + edges + vertices * VERTEX_STATE_WORDS) * 4),
            ("alpha masks", self.mask_words.len() as u64 * 4),
        ]
    }
}

#[cfg(test)]
mod tests {
    use shadow_fins::mesh::Topology;

    use super::*;
    use crate::casters::{gpu_geometry::*, pose::PoseSource};
    use shadow_fins::shapes;

    #[test]
    fn capacity_grows_past_what_a_frame_wanted_and_shrinks_when_the_scene_got_smaller() {
        let have = GpuCapacity { silhouettes: 100, fins: 400, casters: 1000, layers: 2 };
        let max = GpuCapacity::max_for(1 << 30);
        let floor = GpuCapacity { silhouettes: 64, fins: 64, casters: 64, layers: 1 };
        let want = |silhouettes, fins, casters, layers| GpuCapacity { silhouettes, fins, casters, layers };
        assert_eq!(have.resized_for(want(80, 200, 700, 2), floor, max), None);
        // Full to the last record: no room to retire and append in.
        let full = have.resized_for(want(100, 200, 700, 2), floor, max).unwrap();
        assert_eq!(full.silhouettes, 150);
        let grown = have.resized_for(want(300, 200, 700, 5), floor, max).unwrap();
        assert_eq!(grown, GpuCapacity { silhouettes: 450, fins: 400, casters: 1000, layers: 5 });
        // Far less wanted: down to half as much again, never below the floor;
        // layers stay.
        let shrunk = have.resized_for(want(80, 10, 100, 1), floor, max).unwrap();
        assert_eq!(shrunk, GpuCapacity { silhouettes: 100, fins: 64, casters: 150, layers: 2 });
        // Shrunk capacity is stable for the same want.
        assert_eq!(shrunk.resized_for(want(80, 10, 100, 1), floor, max), None);
    }

    #[test]
    fn capacity_stops_growing_at_the_buffer_limit() {
        // A 64 KiB limit holds 585 silhouettes of 112 bytes.
        let max = GpuCapacity::max_for(64 << 10);
        assert_eq!(max.silhouettes, 585);
        let have = GpuCapacity { silhouettes: 100, fins: 400, casters: 1000, layers: 1 };
        let wanted = GpuCapacity { silhouettes: 5000, fins: 10, casters: 0, layers: 1 };
        let grown = have.resized_for(wanted, GpuCapacity::initial(0, 0), max).unwrap();
        assert_eq!(grown.silhouettes, 585);
        // At the limit a frame that still wants more grows no further: no endless redo.
        assert_eq!(grown.resized_for(wanted, GpuCapacity::initial(0, 0), max), None);
        assert_eq!(grown.shortfalls(wanted).collect::<Vec<_>>(), vec![("silhouettes", 585, 5000)]);
    }

    #[test]
    fn packing_the_same_mesh_twice_gives_two_packings() {
        // The geometry cache is keyed by packing: a mesh edited in place is
        // packed again and must never be taken for its old packing (its `Arc`
        // address could be reused, which is what the cache once keyed by).
        let topology = Topology::build(&shapes::cuboid(Vec3::ONE));
        let (a, b) = (GpuMeshGeometry::pack(&topology), GpuMeshGeometry::pack(&topology));
        assert_ne!(a.packing, b.packing);
        let disk = shadow_fins::light::DiskLight::new(Vec3::new(0.0, 5.0, 0.0), Vec3::NEG_Y, 0.5).unwrap();
        let frame = LightFrame::disk(&disk);
        let objects = [SceneObject::new("box", shapes::cuboid(Vec3::ONE), bevy::math::Affine3A::IDENTITY).unwrap()];
        let mut builder = GpuSceneBuilder::default();
        let max = GpuCapacity::max_for(1 << 30);
        let world = (Vec3::splat(-0.5), Vec3::splat(0.5));
        let first = builder.build(&objects, &[Arc::new(a)], &[None], &frame, world, None, &mut None, max).geometry_key;
        let second = builder.build(&objects, &[Arc::new(b)], &[None], &frame, world, None, &mut None, max).geometry_key;
        assert_ne!(first, second, "a new packing of the same mesh kept the old geometry key");
    }

    #[test]
    fn a_posable_packing_poses_each_welded_vertex_as_its_first_input_vertex() {
        // A cuboid's 8 corners as 24 split vertices (as a flat-shaded export
        // has them), each with its own joints and weights; one weight a NaN.
        let mesh = shapes::cuboid(Vec3::ONE);
        let split: Vec<Vec3> = mesh.indices().iter().map(|&i| mesh.positions()[i as usize]).collect();
        let n = split.len();
        let split_mesh = shadow_fins::mesh::Mesh::new(split.clone(), (0..n as u32).collect()).unwrap();
        let topology = Topology::build(&split_mesh);
        let mut source = PoseSource {
            positions: split.clone(),
            joints: (0..n).map(|i| [i as u16, 1, 2, 3]).collect(),
            weights: vec![[0.25; 4]; n],
            morph_targets: vec![vec![Vec3::X; n], vec![Vec3::splat(f32::NAN); n], vec![Vec3::Y; 3]],
        };
        source.weights[0][2] = f32::NAN;
        let g = GpuMeshGeometry::pack_posable(&GpuMeshGeometry::pack(&topology), &topology, &source, None)
            .expect("its own topology");
        assert!(g.posable() && !GpuMeshGeometry::pack(&topology).posable());
        let at = g.words[G_POSE_AT] as usize;
        // Two whole targets (the third is short and left out).
        assert_eq!(g.words[G_MORPH_TARGETS], 2);
        assert_eq!(g.words.len(), at + POSE_VERTEX_WORDS * 8 + 2 * 8 * 3);
        for (w, p) in topology.positions.iter().enumerate() {
            let first = split.iter().position(|q| q == p).unwrap();
            let words = &g.words[at + POSE_VERTEX_WORDS * w..at + POSE_VERTEX_WORDS * (w + 1)];
            assert_eq!(words[..3], p.to_array().map(f32::to_bits), "vertex {w}: its bind position");
            let third = if first == 0 { NO_JOINT } else { 2 };
            assert_eq!(words[3..5], [first as u32 | 1 << 16, third | 3 << 16], "vertex {w}: its first input's joints");
            let third = if first == 0 { 1.0 } else { 0.25 };
            assert_eq!(words[5..9], [0.25, 0.25, third, 0.25].map(f32::to_bits), "vertex {w}: weights");
        }
        let deltas = at + POSE_VERTEX_WORDS * 8;
        assert_eq!(g.words[deltas..deltas + 3], Vec3::X.to_array().map(f32::to_bits));
        // A displacement not finite is none (a NaN would survive a zero weight).
        assert!(g.words[deltas + 24..deltas + 48].iter().all(|w| *w == 0));
        // Another mesh's topology is not this one's.
        let other = Topology::build(&shapes::cuboid(Vec3::splat(2.0)));
        assert!(GpuMeshGeometry::pack_posable(&GpuMeshGeometry::pack(&other), &other, &source, None).is_none());
    }

    /// A split cuboid (24 input vertices welded to 8), packed to be posed,
    /// with each vertex on joint 0 or 1.
    fn posable_cuboid() -> GpuMeshGeometry {
        let mesh = shapes::cuboid(Vec3::ONE);
        let split: Vec<Vec3> = mesh.indices().iter().map(|&i| mesh.positions()[i as usize]).collect();
        let n = split.len();
        let topology = Topology::build(&shadow_fins::mesh::Mesh::new(split.clone(), (0..n as u32).collect()).unwrap());
        let source = PoseSource {
            joints: split.iter().map(|p| [(p.x > 0.0) as u16, 0, 0, 0]).collect(),
            weights: vec![[1.0, 0.0, 0.0, 0.0]; n],
            positions: split,
            morph_targets: vec![],
        };
        GpuMeshGeometry::pack_posable(&GpuMeshGeometry::pack(&topology), &topology, &source, None).unwrap()
    }

    fn pose_at(x: f32) -> Arc<GpuPose> {
        let joints = Some(vec![Mat4::IDENTITY, Mat4::from_translation(Vec3::X * x)]);
        Arc::new(GpuPose::new(&crate::casters::pose::Pose { morph_weights: vec![], joints }))
    }

    #[test]
    fn posed_instances_get_their_own_copies_and_a_new_pose_changes_only_their_records() {
        let disk = shadow_fins::light::DiskLight::new(Vec3::new(0.0, 5.0, 0.0), Vec3::NEG_Y, 0.5).unwrap();
        let frame = LightFrame::disk(&disk);
        let object = |x: f32| {
            SceneObject::new("box", shapes::cuboid(Vec3::ONE), bevy::math::Affine3A::from_translation(Vec3::X * x))
                .unwrap()
        };
        let objects = [object(0.0), object(2.0), object(4.0)];
        let (rest, posable) =
            (Arc::new(GpuMeshGeometry::pack(&Topology::build(&shapes::cuboid(Vec3::ONE)))), Arc::new(posable_cuboid()));
        let meshes = [rest.clone(), posable.clone(), posable.clone()];
        let mut poses = [None, Some(pose_at(0.5)), Some(pose_at(1.0))];
        let (max, world) = (GpuCapacity::max_for(1 << 30), (Vec3::splat(-1.0), Vec3::splat(5.0)));
        let mut builder = GpuSceneBuilder::default();
        let first = builder.build(&objects, &meshes, &poses, &frame, world, None, &mut None, max);
        // Each mesh once (the posable one for its pose section), then a copy
        // per posed instance, less the pose section.
        let part = posable.posed_part();
        assert!(part.len() < posable.words.len());
        assert_eq!(first.geometry.len(), rest.words.len() + posable.words.len() + 2 * part.len());
        let [a, b, c] = [0, 1, 2].map(|i| first.instances[i].ids[0] as usize);
        assert_eq!(first.geometry[a..a + rest.words.len()], rest.words[..]);
        assert!(b != c && b > a && c > a);
        for copy in [b, c] {
            assert_eq!(first.geometry[copy..copy + part.len()], *part, "a posed instance's own copy");
        }
        // The pose buffer: two jobs, each naming its copy, its joints and the shared packing.
        assert_eq!(first.pose_sizes(), [2, 8, 12, 18]);
        let shared = rest.words.len() as u32;
        for (k, copy) in [b, c].into_iter().enumerate() {
            let job = &first.poses[POSES_HEADER_WORDS + POSE_JOB_WORDS * k..][..6];
            assert_eq!([job[0], job[2], job[3], job[4], job[5]], [copy as u32, 2, 0, 1, shared]);
            let data = &first.poses[job[1] as usize..][..32];
            let x: f32 = if k == 0 { 0.5 } else { 1.0 };
            assert_eq!(data[16 + 12], x.to_bits(), "joint 1's translation x");
            assert_eq!([data[15], data[31]], [1.0f32.to_bits(); 2], "both joints finite");
        }
        // A new pose of one: the same geometry, only its record differs.
        poses[1] = Some(pose_at(0.75));
        let second = builder.build(&objects, &meshes, &poses, &frame, world, Some(&[1]), &mut None, max);
        assert_eq!(second.geometry_key, first.geometry_key, "a new pose repacked the geometry");
        assert_ne!(second.instances[1].pose, first.instances[1].pose);
        assert_eq!(second.instances[1].ids, first.instances[1].ids);
        for i in [0, 2] {
            assert_eq!(bytemuck::bytes_of(&second.instances[i]), bytemuck::bytes_of(&first.instances[i]));
        }
    }

    #[test]
    fn a_mesh_swapped_for_one_already_packed_takes_its_geometry() {
        // In place (the other mesh is packed already): the record must point
        // at the new mesh's words, not keep the old offset with new counts.
        let disk = shadow_fins::light::DiskLight::new(Vec3::new(0.0, 5.0, 0.0), Vec3::NEG_Y, 0.5).unwrap();
        let frame = LightFrame::disk(&disk);
        let box_ =
            |s: f32| SceneObject::new("box", shapes::cuboid(Vec3::splat(s)), bevy::math::Affine3A::IDENTITY).unwrap();
        let objects = [box_(1.0), box_(1.0)];
        let small = Arc::new(GpuMeshGeometry::pack(&Topology::build(&shapes::cuboid(Vec3::ONE))));
        let sphere = Arc::new(GpuMeshGeometry::pack(&Topology::build(&shapes::uv_sphere(1.0, 8, 6))));
        let (max, world) = (GpuCapacity::max_for(1 << 30), (Vec3::splat(-1.0), Vec3::splat(1.0)));
        let mut builder = GpuSceneBuilder::default();
        let first = builder.build(
            &objects,
            &[small.clone(), sphere.clone()],
            &[None, None],
            &frame,
            world,
            None,
            &mut None,
            max,
        );
        let second = builder.build(
            &objects,
            &[sphere.clone(), sphere.clone()],
            &[None, None],
            &frame,
            world,
            Some(&[0]),
            &mut None,
            max,
        );
        assert_eq!(second.instances[0].ids[0], first.instances[1].ids[0], "the swapped mesh kept its old words");
        assert_eq!(second.instances[0].info[1..], first.instances[1].info[1..]);
        assert_eq!(second.totals[1], 2 * sphere.faces);
    }

    #[test]
    fn a_pose_flags_joints_that_are_not_finite_and_hashes_what_it_holds() {
        let pose = crate::casters::pose::Pose {
            morph_weights: vec![0.5],
            joints: Some(vec![Mat4::from_translation(Vec3::X), Mat4::NAN]),
        };
        let gpu = GpuPose::new(&pose);
        assert!(gpu.skinned);
        assert_eq!(gpu.joints[0][12..], [1.0, 0.0, 0.0, 1.0]);
        assert_eq!(gpu.joints[1], [[0.0; 15].as_slice(), &[0.0]].concat()[..]);
        let moved = GpuPose::new(&crate::casters::pose::Pose { morph_weights: vec![0.6], ..pose.clone() });
        assert_ne!(gpu.hash, moved.hash, "a new weight must change the record");
        let unskinned = GpuPose::new(&crate::casters::pose::Pose { joints: None, ..pose });
        assert!(!unskinned.skinned && unskinned.joints.is_empty());
    }

    #[test]
    fn packed_geometry_lists_every_edge_at_both_its_vertices() {
        let topology = Topology::build(&shapes::cuboid(Vec3::ONE));
        let g = GpuMeshGeometry::pack(&topology);
        let [v, f, e, faces_at, _, edges_at, csr_at, _] = std::array::from_fn(|i| g.words[i] as usize);
        assert_eq!((v, f, e), (8, 12, 18));
        assert!(g.closed);
        assert_eq!(g.words[faces_at..faces_at + 3], topology.faces[0]);
        for edge in 0..e {
            let ends = &g.words[edges_at + 5 * edge..edges_at + 5 * edge + 2];
            for &x in ends {
                let (start, end) = (g.words[csr_at + x as usize], g.words[csr_at + x as usize + 1]);
                let list = &g.words[csr_at + v + 1 + start as usize..csr_at + v + 1 + end as usize];
                assert!(list.contains(&(edge as u32)), "edge {edge} missing at vertex {x}");
            }
        }
        // A closed box: every vertex has three or more edges, 2·18 entries in all.
        assert_eq!(g.words[csr_at + v] as usize, 2 * e);
    }

    /// The core's leaf-cards scene: the ground, then five masked cards
    /// sharing one mesh and one cut-out.
    fn leaf_cards() -> Vec<SceneObject> {
        shadow_fins::scenes::SceneId::LeafCards.build().scene.objects
    }

    #[test]
    fn an_outlined_packing_has_the_outline_after_the_mesh_and_the_faces_uvs() {
        let card = &leaf_cards()[1];
        let cutout = card.fitting_cutout().expect("a masked card");
        let (t, o) = (&card.topology, &cutout.outline);
        assert!(!o.edges.is_empty());
        let g = GpuMeshGeometry::pack_outlined(t, cutout);
        let [v, f, e, _, vertices_at, edges_at, csr_at, _] = std::array::from_fn(|i| g.words[i] as usize);
        let mesh_edges = t.edges.len() + t.non_manifold_edges.len();
        assert_eq!((v, f, e), (t.positions.len() + o.positions.len(), t.faces.len(), mesh_edges + o.edges.len()));
        assert!(g.outlined && !g.closed && !GpuMeshGeometry::pack(t).outlined);
        // The outline's vertices follow the mesh's, numbered as the core numbers them.
        let first = t.positions.len();
        let at = vertices_at + 6 * first;
        assert_eq!(g.words[at..at + 3], o.positions[0].to_array().map(f32::to_bits));
        let edge = |k: usize| &g.words[edges_at + 5 * k..edges_at + 5 * k + 5];
        for k in 0..t.edges.len() {
            assert_eq!(edge(k)[4] & (EDGE_PATCH_ONLY | EDGE_OUTLINE), EDGE_PATCH_ONLY, "mesh edge {k}");
        }
        for (k, outline_edge) in o.edges.iter().enumerate() {
            let w = edge(t.edges.len() + k);
            assert_eq!(w[4] & (EDGE_PATCH_ONLY | EDGE_OUTLINE), EDGE_OUTLINE, "outline edge {k}");
            assert_eq!(w[..2], outline_edge.vertices.map(|x| x + first as u32));
            assert_eq!(w[2], outline_edge.faces[0]);
            assert_eq!(w[4] & EDGE_CREASE != 0, o.crease[k]);
            // Listed at both its (outline) vertices.
            for &x in &w[..2] {
                let (start, end) = (g.words[csr_at + x as usize], g.words[csr_at + x as usize + 1]);
                let list = &g.words[csr_at + v + 1 + start as usize..csr_at + v + 1 + end as usize];
                assert!(list.contains(&((t.edges.len() + k) as u32)), "outline edge {k} missing at {x}");
            }
        }
        let uvs_at = g.words[G_FACE_UVS_AT] as usize;
        assert_eq!(g.words.len(), uvs_at + 6 * f);
        for (face, uvs) in cutout.face_uvs.iter().enumerate() {
            let words: Vec<u32> = uvs.iter().flat_map(|uv| [uv.x, uv.y]).map(f32::to_bits).collect();
            assert_eq!(g.words[uvs_at + 6 * face..uvs_at + 6 * face + 6], words[..], "face {face}");
        }
    }

    #[test]
    fn a_slivers_barycentrics_hold_once_a_pose_changes_its_shape() {
        // A face 1000 times longer than wide: at rest any barycentrics near
        // the right ones rebuild the point, posed only the right ones do.
        let c = [Vec3::ZERO, Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.5, 1e-3, 0.0)];
        let p = c[0] + (c[1] - c[0]) * 0.3 + (c[2] - c[0]) * 0.2;
        let b = barycentrics(c, p);
        assert!((b - Vec3::new(0.5, 0.3, 0.2)).abs().max_element() < 1e-5, "{b}");
        // Sheared by a pose: the point stays where its barycentrics put it.
        let posed = [c[0], c[1], Vec3::new(0.5, 0.5, 0.0)];
        let q = posed[0] + (posed[1] - posed[0]) * b.y + (posed[2] - posed[0]) * b.z;
        let expected = posed[0] + (posed[1] - posed[0]) * 0.3 + (posed[2] - posed[0]) * 0.2;
        assert!(q.distance(expected) < 1e-5, "{q} against {expected}");
        // A degenerate face: its first corner.
        assert_eq!(barycentrics([Vec3::ZERO; 3], Vec3::ONE), Vec3::X);
    }

    #[test]
    fn a_posable_outlined_packing_carries_each_outline_vertex_by_its_face() {
        let card = &leaf_cards()[1];
        let cutout = card.fitting_cutout().unwrap();
        let (t, o) = (&card.topology, &cutout.outline);
        let source = PoseSource { positions: card.mesh.positions().to_vec(), ..Default::default() };
        let rest = GpuMeshGeometry::pack_outlined(t, cutout);
        let g = GpuMeshGeometry::pack_posable(&rest, t, &source, Some(o)).expect("its own outline");
        assert!(g.posable() && g.outlined);
        assert_eq!(g.words[G_MESH_VERTICES] as usize, t.positions.len());
        // After the mesh's vertices (no morph target): face, w1, w2 per outline vertex.
        let at = g.words[G_POSE_AT] as usize + POSE_VERTEX_WORDS * t.positions.len();
        assert_eq!(g.words.len(), at + 3 * o.positions.len());
        for (k, p) in o.positions.iter().enumerate() {
            let w = &g.words[at + 3 * k..at + 3 * k + 3];
            assert_eq!(w[0], o.faces[k]);
            let c = t.faces[w[0] as usize].map(|v| t.positions[v as usize]);
            let q = c[0] + (c[1] - c[0]) * f32::from_bits(w[1]) + (c[2] - c[0]) * f32::from_bits(w[2]);
            assert!(q.distance(*p) < 1e-5, "outline vertex {k}: {q} against {p}");
        }
        // A packing without the outline is not posed with one, nor the reverse.
        assert!(GpuMeshGeometry::pack_posable(&GpuMeshGeometry::pack(t), t, &source, Some(o)).is_none());
        assert!(GpuMeshGeometry::pack_posable(&rest, t, &source, None).is_none());
    }

    #[test]
    fn outlined_instances_point_at_their_mask_packed_once() {
        let objects = leaf_cards();
        let cutout = objects[1].fitting_cutout().unwrap();
        let solid = Arc::new(GpuMeshGeometry::pack(&objects[0].topology));
        let outlined = Arc::new(GpuMeshGeometry::pack_outlined(&objects[1].topology, cutout));
        let plain_card = Arc::new(GpuMeshGeometry::pack(&objects[1].topology));
        // The ground solid, four cards outlined, one card packed without its
        // outline (as one the GPU poses): solid on the GPU.
        let mut meshes = vec![solid, outlined.clone(), outlined.clone(), outlined.clone(), outlined.clone()];
        meshes.push(plain_card);
        let poses = vec![None; objects.len()];
        let disk = shadow_fins::light::DiskLight::new(Vec3::new(0.0, 5.0, 0.0), Vec3::NEG_Y, 0.5).unwrap();
        let frame = LightFrame::disk(&disk);
        let (max, world) = (GpuCapacity::max_for(1 << 30), (Vec3::splat(-4.0), Vec3::splat(4.0)));
        let mut builder = GpuSceneBuilder::default();
        let scene = builder.build(&objects, &meshes, &poses, &frame, world, None, &mut None, max);
        let mut words = Vec::new();
        crate::casters::cutout::pack_mask(&cutout.mask, &mut words);
        assert_eq!(*scene.mask_words, words, "the shared mask, once");
        let cut: Vec<u32> = scene.instances.iter().map(|i| i.pose[2]).collect();
        assert_eq!(cut, [0, 1, 1, 1, 1, 0]);
        // Outlined instances are never closed (flag 2), whatever the mesh.
        assert!(scene.instances[1..5].iter().all(|i| i.info[0] & 2 == 0));
        // A card that moved keeps its mask in place; the words are not packed again.
        let mut moved = objects.clone();
        moved[2].transform.translation += bevy::math::Vec3A::X;
        let again = builder.build(&moved, &meshes, &poses, &frame, world, Some(&[2]), &mut None, max);
        assert!(Arc::ptr_eq(&again.mask_words, &scene.mask_words));
        assert_eq!(again.instances[2].pose[2], 1);
        // Without a masked caster there are no mask words.
        let none = GpuSceneBuilder::default().build(
            &objects[..1],
            &meshes[..1],
            &poses[..1],
            &frame,
            world,
            None,
            &mut None,
            max,
        );
        assert!(none.mask_words.is_empty());
    }
}
