//! Ground truth: the fraction of the light (disk, rectangle, sun, or the
//! outline of a sphere seen from the point) visible from a point, from `M` deterministic equal-weight samples of its aperture (default 1024, as in all five papers), each
//! an exact ray–triangle test through a BVH.

use glam::Vec2;

use crate::{bvh::Bvh, light::Projection, receiver::Receiver, scene::LightSpaceScene};

/// Default sample count.
pub const DEFAULT_SAMPLES: u32 = 1024;

/// Many-sample visibility of the light, in the light frame of a [`LightSpaceScene`].
pub struct GroundTruth<'a> {
    scene: &'a LightSpaceScene,
    bvh: Bvh,
    samples: Vec<Vec2>,
}

impl<'a> GroundTruth<'a> {
    pub fn new(scene: &'a LightSpaceScene, samples: u32) -> Self {
        Self { scene, bvh: Bvh::new(&scene.casters), samples: scene.frame.aperture.samples(samples) }
    }

    /// The BVH over the casters (light frame), for primary rays.
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// True when a caster blocks the segment `p + t·dir`, `t ∈ (t_min,
    /// t_max)`: any triangle for solid casters, where its alpha passes the
    /// cutoff at the crossing for an alpha-masked one ([`crate::cutout`]).
    #[inline]
    fn blocked(&self, p: glam::Vec3, dir: glam::Vec3, t_min: f32, t_max: f32) -> bool {
        if self.scene.caster_cutouts.is_empty() {
            self.bvh.any_hit(p, dir, t_min, t_max)
        } else {
            self.bvh.any_hit_where(p, dir, t_min, t_max, |k, u, v| self.scene.blocks_at(k as usize, u, v))
        }
    }

    /// Fraction of the disk visible from the receiver, in `[0, 1]`, counting only
    /// the part of the disk above the receiver's tangent plane when its normal
    /// is known.
    ///
    /// Why the horizon: the part of the disk below a surface's own horizon is
    /// cut off by the surface itself, not by a shadow. That is the light's
    /// shading (the cosine term, which Bevy's lighting applies when the fin
    /// light is composited), so counting it here would charge every shadow
    /// method for a shading term on surfaces that face the light at a grazing
    /// angle. When the whole disk is below the horizon, the result is 0.
    ///
    /// The receiver is lifted off its surface along its normal by the same
    /// lift the oracle uses ([`crate::scene::surface_epsilon`]). Points at or
    /// behind the light plane see nothing of the one-sided disk. A sphere
    /// light's outline is the disk of it a receiver sees (the tangent
    /// circle), in any of its face frames: the casters are all there.
    pub fn visibility(&self, receiver: Receiver) -> f32 {
        let eps = crate::scene::surface_epsilon(receiver.position, self.scene.extent);
        let p = receiver.position + receiver.normal * eps;
        if !p.is_finite() {
            return 0.0;
        }
        let n = receiver.normal;
        let (mut visible, mut above) = (0u32, 0u32);
        if let Some(radius) = self.scene.frame.sphere_radius() {
            // A sphere: its outline seen from p, in any face's frame (the
            // frame's origin is the sphere's centre). Inside it, nothing
            // comes between.
            let Some((center, r, e1, e2)) = crate::light::outline_seen_from(radius, p) else { return 1.0 };
            for s in &self.samples {
                let dir = center + e1 * (s.x * r) + e2 * (s.y * r) - p;
                if n.dot(dir) < 0.0 {
                    continue;
                }
                above += 1;
                let t_min = eps / dir.length().max(eps);
                if !self.blocked(p, dir, t_min, 1.0) {
                    visible += 1;
                }
            }
            return if above == 0 { 0.0 } else { visible as f32 / above as f32 };
        }
        match self.scene.frame.projection {
            Projection::Perspective { radius } => {
                if !(p.z > self.scene.reference_depth * 1e-5) {
                    return 0.0;
                }
                for s in &self.samples {
                    let target = (*s * radius).extend(0.0);
                    let dir = target - p;
                    if n.dot(dir) < 0.0 {
                        continue;
                    }
                    above += 1;
                    // Segment p → target, t ∈ (ε, 1): excludes the receiver itself.
                    let t_min = eps / dir.length().max(eps);
                    if !self.blocked(p, dir, t_min, 1.0) {
                        visible += 1;
                    }
                }
            }
            Projection::Orthographic { tan_angle } => {
                let far = self.scene.extent * 4.0 + p.z.abs();
                for s in &self.samples {
                    let dir = (*s * tan_angle).extend(-1.0);
                    if n.dot(dir) < 0.0 {
                        continue;
                    }
                    above += 1;
                    if !self.blocked(p, dir, eps, far) {
                        visible += 1;
                    }
                }
            }
        }
        if above == 0 { 0.0 } else { visible as f32 / above as f32 }
    }
}
