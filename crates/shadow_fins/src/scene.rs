//! Scenes: meshes placed in the world, and their light-space view.

use std::sync::Arc;

use glam::{Affine3A, DAffine3, DVec3, Vec3};

use crate::{
    error::MeshError,
    light::{Light, LightFrame},
    mesh::{Mesh, Topology},
};

/// One mesh placed in the world.
#[derive(Debug, Clone)]
pub struct SceneObject {
    pub name: String,
    pub mesh: Arc<Mesh>,
    /// Built once from `mesh`; shared between instances of the same mesh.
    pub topology: Arc<Topology>,
    pub transform: Affine3A,
    /// Casts shadows (and fins). Like Bevy's `NotShadowCaster` when false.
    pub casts_shadows: bool,
    /// Receives shadows: its depth counts for the reference plane `L0`.
    pub receives_shadows: bool,
    /// Holes where its material's alpha is below the cutoff (an
    /// alpha-masked material, [`crate::cutout`]); `None`: solid.
    pub cutout: Option<crate::cutout::Cutout>,
}

impl SceneObject {
    /// Places a mesh; builds its topology. Errors on a non-finite or singular transform.
    pub fn new(name: impl Into<String>, mesh: Mesh, transform: Affine3A) -> Result<Self, MeshError> {
        let mesh = Arc::new(mesh);
        let topology = Arc::new(Topology::build(&mesh));
        Self::shared(name, mesh, topology, transform)
    }

    /// Places an already built mesh and topology (instancing).
    pub fn shared(
        name: impl Into<String>,
        mesh: Arc<Mesh>,
        topology: Arc<Topology>,
        transform: Affine3A,
    ) -> Result<Self, MeshError> {
        let det = transform.matrix3.determinant();
        if !transform.is_finite() || !(det.abs() > 1e-20) {
            return Err(MeshError::BadTransform(det));
        }
        Ok(Self {
            name: name.into(),
            mesh,
            topology,
            transform,
            casts_shadows: true,
            receives_shadows: true,
            cutout: None,
        })
    }

    /// Its cut-out, when it was built for this object's topology (one UV
    /// triangle per face); a cut-out of another mesh is ignored: solid.
    pub fn fitting_cutout(&self) -> Option<&crate::cutout::Cutout> {
        self.cutout.as_ref().filter(|c| c.face_uvs.len() == self.topology.faces.len())
    }

    /// The object → world transform in f64.
    pub fn transform_f64(&self) -> DAffine3 {
        DAffine3::from_mat3_translation(
            glam::Mat3::from(self.transform.matrix3).as_dmat3(),
            Vec3::from(self.transform.translation).as_dvec3(),
        )
    }
}

/// A set of objects. Every object casts and receives unless told otherwise.
#[derive(Debug, Clone, Default)]
pub struct Scene {
    pub objects: Vec<SceneObject>,
}

impl Scene {
    pub fn new(objects: Vec<SceneObject>) -> Self {
        Self { objects }
    }

    pub fn triangle_count(&self) -> usize {
        self.objects.iter().map(|o| o.mesh.triangle_count()).sum()
    }

    /// The length of the bounds' diagonal (`None` when empty): the scene's size.
    pub fn diagonal(&self) -> Option<f32> {
        self.bounds().map(|(lo, hi)| (hi - lo).length())
    }

    /// World-space axis-aligned bounds of every object (`None` when empty).
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for o in &self.objects {
            let m = o.transform_f64();
            for p in o.topology.positions.iter() {
                let w = m.transform_point3(p.as_dvec3());
                lo = lo.min(w);
                hi = hi.max(w);
            }
        }
        (lo.x <= hi.x).then(|| (lo.as_vec3(), hi.as_vec3()))
    }

    /// Translates every object (stability tests: "the whole scene offset by 1e5").
    pub fn translated(&self, offset: Vec3) -> Self {
        let mut s = self.clone();
        for o in &mut s.objects {
            o.transform.translation += glam::Vec3A::from(offset);
        }
        s
    }
}

/// Object space → light frame, as `f32` after the large offsets cancelled in `f64`.
#[derive(Debug, Clone, Copy)]
pub struct ObjectToFrame {
    pub linear: glam::Mat3,
    pub translation: Vec3,
    /// The transform mirrors (negative determinant): face orientation flips.
    pub mirrors: bool,
    /// The disk light's centre lies inside this closed mesh (ray parity, see
    /// [`Topology::contains_point`]). From inside, the faces that block the
    /// way out are the ones facing away from the light, which the usual rule
    /// (back faces of closed meshes stay out of the maps) leaves out — for a
    /// convex mesh all of them, and the whole world outside was lit; such an
    /// instance is drawn as an open mesh instead, both sides, and shadows
    /// everything outside it.
    pub light_inside: bool,
}

impl ObjectToFrame {
    pub fn new(object: &SceneObject, frame: &LightFrame) -> Self {
        let m = object.transform_f64();
        let [u, v, n] = frame.axes().map(|a| a.as_dvec3());
        let rows = glam::DMat3::from_cols(u, v, n).transpose();
        let linear = rows * m.matrix3;
        let translation = rows * (m.translation - frame.origin());
        let light_inside = frame.is_perspective() && {
            // The light centre (the frame origin) in object space, in f64.
            let centre = m.matrix3.inverse() * (frame.origin() - m.translation);
            object.topology.contains_point(centre.as_vec3())
        };
        Self {
            linear: linear.as_mat3(),
            translation: translation.as_vec3(),
            mirrors: linear.determinant() < 0.0,
            light_inside,
        }
    }

    /// Whether this instance's back faces stay out of the maps: a closed mesh
    /// the light is outside of.
    pub fn culls_back_faces(&self, topology: &Topology) -> bool {
        topology.is_closed_manifold() && !self.light_inside
    }

    #[inline]
    pub fn point(&self, p: Vec3) -> Vec3 {
        self.linear * p + self.translation
    }

    /// Transforms a normal (inverse transpose of the linear part, up to scale).
    pub fn normal(&self, n: Vec3) -> Vec3 {
        let c = self.linear;
        // Cofactor matrix = det · inverse-transpose: no division, sign kept for mirrors.
        let cof = glam::Mat3::from_cols(c.y_axis.cross(c.z_axis), c.z_axis.cross(c.x_axis), c.x_axis.cross(c.y_axis));
        let n = cof * n;
        if self.mirrors { -n } else { n }
    }

    /// The light seen from object space: the disk centre (frame origin) as a
    /// point, or the sun's travel direction (frame +z), for the facing test.
    pub fn light_in_object(&self, frame: &LightFrame) -> LightInObject {
        let inv = self.linear.as_dmat3().inverse();
        if frame.is_perspective() {
            LightInObject::Point((inv * (-self.translation.as_dvec3())).as_vec3())
        } else {
            LightInObject::Direction((inv * DVec3::Z).as_vec3())
        }
    }
}

/// The light's position or direction in an object's own space.
#[derive(Debug, Clone, Copy)]
pub enum LightInObject {
    Point(Vec3),
    Direction(Vec3),
}

/// The scene seen from the light: caster triangles in the light frame and the
/// reference plane `L0`.
#[derive(Debug, Clone)]
pub struct LightSpaceScene {
    pub light: Light,
    pub frame: LightFrame,
    /// Shadow-casting triangles, light frame, degenerate ones dropped: casting
    /// objects in order, each object's topology faces in order. The ground truth
    /// traces all of them; the fin method maps those in a patch.
    pub casters: Vec<[Vec3; 3]>,
    /// Per object: its transform into the light frame (same order as `Scene::objects`).
    pub object_frames: Vec<ObjectToFrame>,
    /// Reference plane depth `L0`: the deepest receiver (so real receivers never lie beyond it).
    pub reference_depth: f32,
    /// Per caster (same order as `casters`), its cut-out, or empty when no
    /// caster has one ([`crate::cutout`]).
    pub caster_cutouts: Vec<Option<crate::cutout::CasterCutout>>,
    /// The alpha masks `caster_cutouts` index.
    pub masks: Vec<std::sync::Arc<crate::cutout::AlphaMask>>,
    /// World-space diagonal of the scene's bounds.
    pub extent: f32,
}

/// Relative size of the lift that keeps a receiver off its own surface.
pub const SURFACE_EPSILON: f32 = 1e-5;

/// The lift off its surface of a receiver at light-frame point `p`:
/// [`SURFACE_EPSILON`] of its distance from the light's centre (the frame
/// origin), never less than 1e-7 of the scene's size.
///
/// Why relative to the receiver, not to the scene: f32 positions are as
/// precise as their own magnitude, and a scene's size says nothing about its
/// details. With 1e-5 of the diagonal, a 2e6-wide ground lifted receivers by
/// 28 units — above a light 4.5 units over it — and every method and the
/// ground truth then agreed on "unlit", scoring 0 error on a blank image.
#[inline]
pub fn surface_epsilon(p: Vec3, extent: f32) -> f32 {
    (SURFACE_EPSILON * p.length()).max(1e-7 * extent)
}

/// Per casting face of `scene` (objects in order, faces in topology order:
/// [`LightSpaceScene::casters`]' order) its cut-out, and the masks they
/// index, each mask its instances share once; both empty when no caster is
/// alpha-masked.
pub fn caster_cutouts(
    scene: &Scene,
) -> (Vec<Option<crate::cutout::CasterCutout>>, Vec<std::sync::Arc<crate::cutout::AlphaMask>>) {
    let (mut cutouts, mut masks) = (Vec::new(), Vec::<std::sync::Arc<crate::cutout::AlphaMask>>::new());
    if !scene.objects.iter().any(|o| o.casts_shadows && o.fitting_cutout().is_some()) {
        return (cutouts, masks);
    }
    for o in scene.objects.iter().filter(|o| o.casts_shadows) {
        match o.fitting_cutout() {
            Some(c) => {
                let mask = match masks.iter().position(|m| std::sync::Arc::ptr_eq(m, &c.mask)) {
                    Some(i) => i as u32,
                    None => {
                        masks.push(c.mask.clone());
                        masks.len() as u32 - 1
                    }
                };
                cutouts.extend(c.face_uvs.iter().map(|uvs| Some(crate::cutout::CasterCutout { mask, uvs: *uvs })));
            }
            None => cutouts.extend(o.topology.faces.iter().map(|_| None)),
        }
    }
    (cutouts, masks)
}

impl LightSpaceScene {
    pub fn new(scene: &Scene, light: Light) -> Self {
        let (lo, hi) = scene.bounds().unwrap_or((Vec3::ZERO, Vec3::ONE));
        let frame = LightFrame::new(&light, lo, hi);
        Self::in_frame(scene, light, frame, (hi - lo).length())
    }

    /// The scene in a frame chosen by the caller: a renderer places a sun's
    /// frame from bounds it already has (every drawn mesh's box, not only
    /// the ones it can read), so that the GPU and the CPU paths share it.
    /// `extent` is the scene's diagonal (the surface epsilon's floor).
    pub fn in_frame(scene: &Scene, light: Light, frame: LightFrame, extent: f32) -> Self {
        let extent = if extent.is_finite() { extent.max(1e-30) } else { 1.0 };
        let object_frames: Vec<ObjectToFrame> = scene.objects.iter().map(|o| ObjectToFrame::new(o, &frame)).collect();
        let mut casters = Vec::with_capacity(scene.triangle_count());
        let mut deepest = f32::NEG_INFINITY;
        let (caster_cutouts, masks) = caster_cutouts(scene);
        for (o, to_frame) in scene.objects.iter().zip(&object_frames) {
            let pts: Vec<Vec3> = o.topology.positions.iter().map(|&p| to_frame.point(p)).collect();
            if o.receives_shadows || o.casts_shadows {
                deepest = pts.iter().fold(deepest, |d, p| d.max(p.z));
            }
            if o.casts_shadows {
                casters.extend(o.topology.faces.iter().map(|f| f.map(|i| pts[i as usize])));
            }
        }
        // A scene entirely behind the light still needs a positive L0.
        let reference_depth = if deepest > 0.0 { deepest } else { extent };
        Self { light, frame, casters, object_frames, reference_depth, extent, caster_cutouts, masks }
    }

    /// The scene in every frame the light's maps are made in: one for a
    /// disk, a rectangle or the sun (as [`Self::new`]); six for a sphere,
    /// in [`crate::light::CubeFace::ALL`] order, their maps' margin
    /// from the caster nearest to its centre
    /// ([`crate::light::SphereLight::face_window`]). Which one shades
    /// a receiver: [`Self::face_of`].
    pub fn faces(scene: &Scene, light: Light) -> Vec<Self> {
        let Light::Sphere(sphere) = light else { return vec![Self::new(scene, light)] };
        let (lo, hi) = scene.bounds().unwrap_or((Vec3::ZERO, Vec3::ONE));
        let window = sphere.face_window(nearest_caster_distance(scene, sphere.center));
        sphere.face_frames(window).map(|frame| Self::in_frame(scene, light, frame, (hi - lo).length())).to_vec()
    }

    /// Which of [`Self::faces`] shadows a receiver at world point `p`: the
    /// cube face whose frustum holds it (0 when there is one frame).
    pub fn face_of(faces: &[Self], p: Vec3) -> usize {
        match faces.first().map(|f| f.light) {
            Some(Light::Sphere(s)) if faces.len() == 6 => crate::light::CubeFace::of(p - s.center).index(),
            _ => 0,
        }
    }

    /// A receiver at world point `p` with world normal `n`, in the frame of
    /// the face of [`Self::faces`] that shadows it, and that face's index.
    pub fn receiver_in_face(faces: &[Self], p: Vec3, n: Vec3) -> (usize, crate::receiver::Receiver) {
        let k = Self::face_of(faces, p);
        let frame = &faces[k].frame;
        (k, crate::receiver::Receiver { position: frame.to_frame(p), normal: frame.dir_to_frame(n) })
    }

    /// `receivers` (in this scene's frame) grouped by the light's frame
    /// that shadows them: for a sphere light, one group per cube face of
    /// [`Self::faces`] (empty ones too, in face order), each face's reference
    /// plane covering its receivers; for any other light, one group, this
    /// frame's. What every evaluation of a sphere light does first.
    pub fn group_by_face(&self, scene: &Scene, receivers: &[crate::receiver::Receiver]) -> Vec<FaceGroup> {
        if !matches!(self.light, Light::Sphere(_)) {
            return vec![FaceGroup {
                light_space: self.clone(),
                indices: (0..receivers.len()).collect(),
                receivers: receivers.to_vec(),
            }];
        }
        let faces = Self::faces(scene, self.light);
        let frame = &self.frame;
        let routed: Vec<(usize, crate::receiver::Receiver)> = receivers
            .iter()
            .map(|r| Self::receiver_in_face(&faces, frame.to_world(r.position), frame.dir_to_world(r.normal)))
            .collect();
        faces
            .into_iter()
            .enumerate()
            .map(|(k, mut light_space)| {
                let indices: Vec<usize> = (0..receivers.len()).filter(|&i| routed[i].0 == k).collect();
                let receivers: Vec<_> = indices.iter().map(|&i| routed[i].1).collect();
                light_space.cover_receivers(receivers.iter().map(|r| r.position));
                FaceGroup { light_space, indices, receivers }
            })
            .collect()
    }

    /// The cut-out of caster `k`, if it has one.
    #[inline]
    pub fn cutout(&self, k: usize) -> Option<crate::cutout::CasterCutout> {
        self.caster_cutouts.get(k).copied().flatten()
    }

    /// True when caster `k` blocks light at its barycentric point `(u, v)`
    /// (weights `1 − u − v`, `u`, `v` of its corners): always for a solid
    /// caster, where its alpha passes the cutoff for a masked one.
    #[inline]
    pub fn blocks_at(&self, k: usize, u: f32, v: f32) -> bool {
        crate::cutout::caster_blocks_at(&self.caster_cutouts, &self.masks, k, u, v)
    }

    /// Moves the reference plane `L0` down to the deepest of `receivers` (light
    /// frame) when one lies beyond it, so that every receiver is in front of
    /// the plane the fins are built for (DESIGN §3).
    ///
    /// Why: a fin is as wide as the penumbra on the reference plane; a receiver
    /// behind it has a wider penumbra, whose outer part no fin covers, and
    /// refinement then leaves a step of `½(1 − B0/Br)` at the fin's end. The
    /// scene's own surfaces never lie beyond `L0` (it is their deepest vertex);
    /// points given from outside (the lab's CSV points) can.
    pub fn cover_receivers(&mut self, receivers: impl IntoIterator<Item = Vec3>) {
        for p in receivers {
            if p.z.is_finite() && p.z > self.reference_depth {
                self.reference_depth = p.z;
            }
        }
    }
}

/// Receivers shadowed through one light frame ([`LightSpaceScene::group_by_face`]).
#[derive(Debug, Clone)]
pub struct FaceGroup {
    /// The scene in that frame, its reference plane covering the receivers.
    pub light_space: LightSpaceScene,
    /// Where the receivers were in the list grouped.
    pub indices: Vec<usize>,
    /// The receivers in that frame.
    pub receivers: Vec<crate::receiver::Receiver>,
}

/// The distance from `point` to the nearest shadow-casting triangle (world
/// space, f64 offsets); `INFINITY` when nothing casts.
pub fn nearest_caster_distance(scene: &Scene, point: Vec3) -> f32 {
    scene
        .objects
        .iter()
        .filter(|o| o.casts_shadows)
        .map(|o| nearest_triangle_distance(o, point))
        .fold(f32::INFINITY, f32::min)
}

/// The distance from `point` to the nearest triangle of `object` (world
/// space, f64 offsets), whether it casts or not.
pub fn nearest_triangle_distance(object: &SceneObject, point: Vec3) -> f32 {
    let point = point.as_dvec3();
    let m = object.transform_f64();
    let pts: Vec<DVec3> = object.topology.positions.iter().map(|p| m.transform_point3(p.as_dvec3()) - point).collect();
    let mut nearest = f64::INFINITY;
    for f in &object.topology.faces {
        let [a, b, c] = f.map(|i| pts[i as usize]);
        nearest = nearest.min(closest_on_triangle(a, b, c).length());
    }
    nearest as f32
}

/// The point of triangle `abc` closest to the origin (Ericson, *Real-Time
/// Collision Detection* §5.1.5, with the query point at the origin).
fn closest_on_triangle(a: DVec3, b: DVec3, c: DVec3) -> DVec3 {
    let (ab, ac, ap) = (b - a, c - a, -a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = -b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = -c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = va + vb + vc;
    if !(denom.abs() > 0.0) {
        return a;
    }
    a + ab * (vb / denom) + ac * (vc / denom)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_closest_point_of_a_triangle_is_no_farther_than_any_point_of_it() {
        let mut seed = 0x9e37_79b9_u32;
        let mut next = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed as f64 / u32::MAX as f64 * 4.0 - 2.0
        };
        for _ in 0..500 {
            let mut v = || DVec3::new(next(), next(), next());
            let (a, b, c) = (v(), v(), v());
            let best = closest_on_triangle(a, b, c).length();
            for i in 0..=10 {
                for j in 0..=10 - i {
                    let (s, t) = (i as f64 / 10.0, j as f64 / 10.0);
                    let q = a + (b - a) * s + (c - a) * t;
                    assert!(best <= q.length() + 1e-9, "{best} > {}", q.length());
                }
            }
        }
        // Over the interior of a face: the plane's distance.
        let (a, b, c) = (DVec3::new(-1.0, -1.0, 2.0), DVec3::new(3.0, -1.0, 2.0), DVec3::new(-1.0, 3.0, 2.0));
        assert!((closest_on_triangle(a, b, c) - DVec3::new(0.0, 0.0, 2.0)).length() < 1e-12);
    }
}
