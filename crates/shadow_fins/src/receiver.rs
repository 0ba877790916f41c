//! A point that receives a shadow: where it is in the light frame and which
//! way it faces (what every visibility function of this crate is asked about).

use glam::Vec3;

use crate::light::LightFrame;

/// A receiver point in the light frame, with its unit normal (zero if unknown).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Receiver {
    pub position: Vec3,
    pub normal: Vec3,
}

impl Receiver {
    /// True when the light's centre is in front of the surface (or the normal is
    /// unknown). Elsewhere the light's shading is zero, so visibility there is
    /// never seen: error metrics skip such receivers.
    pub fn faces_light(&self, frame: &LightFrame) -> bool {
        if self.normal == Vec3::ZERO {
            return true;
        }
        if frame.is_perspective() { self.normal.dot(-self.position) > 0.0 } else { self.normal.z < 0.0 }
    }
}
