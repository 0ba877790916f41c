//! A pinhole camera for visibility images.

use glam::Vec3;

/// Pinhole camera looking from `position` at `target`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub position: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    /// Vertical field of view in degrees.
    pub vertical_fov: f32,
}

impl Camera {
    pub fn looking_at(position: Vec3, target: Vec3) -> Self {
        Self { position, target, up: Vec3::Y, vertical_fov: 45.0 }
    }

    /// World-space ray (origin, unit direction) through the centre of pixel `(x, y)`
    /// of a `width × height` image, `y` down.
    pub fn ray(&self, x: u32, y: u32, width: u32, height: u32) -> (Vec3, Vec3) {
        let forward = (self.target - self.position).normalize_or(Vec3::NEG_Z);
        let right = forward.cross(self.up).normalize_or(Vec3::X);
        let up = right.cross(forward);
        let half_h = (self.vertical_fov.to_radians() * 0.5).tan();
        let half_w = half_h * width as f32 / height.max(1) as f32;
        let sx = ((x as f32 + 0.5) / width as f32 * 2.0 - 1.0) * half_w;
        let sy = (1.0 - (y as f32 + 0.5) / height as f32 * 2.0) * half_h;
        (self.position, (forward + right * sx + up * sy).normalize())
    }
}

/// The receiver a camera pixel sees: the first hit of its ray in the light
/// frame of `light_space`, with the surface normal turned towards the camera;
/// `None` for the background. `bvh` must be built over `light_space.casters`.
pub fn pixel_receiver(
    camera: &Camera,
    (x, y, width, height): (u32, u32, u32, u32),
    light_space: &crate::scene::LightSpaceScene,
    bvh: &crate::bvh::Bvh,
) -> Option<crate::receiver::Receiver> {
    let (o, d) = camera.ray(x, y, width, height);
    let (o, d) = (light_space.frame.to_frame(o), light_space.frame.dir_to_frame(d));
    // An alpha-masked surface is seen where it is opaque, as it casts.
    let hit = if light_space.caster_cutouts.is_empty() {
        bvh.closest_hit(o, d, 0.0)
    } else {
        bvh.closest_hit_where(o, d, 0.0, |k, u, v| light_space.blocks_at(k as usize, u, v))
    };
    hit.map(|h| {
        let normal = if h.normal.dot(d) > 0.0 { -h.normal } else { h.normal };
        crate::receiver::Receiver { position: o + d * h.t, normal }
    })
}
