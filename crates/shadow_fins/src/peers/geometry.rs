//! Small geometry the peers share: convex clipping, and an orthonormal pair
//! across a direction.

/// Sutherland–Hodgman: the part of a convex polygon where `side(p) >= 0`,
/// for points of any dimension and precision (single sample clips `Vec3`
/// triangles, the wedges `DVec2` quadrants).
pub(crate) fn clip_convex<P, S>(poly: &[P], side: impl Fn(P) -> S) -> Vec<P>
where
    P: Copy + std::ops::Add<Output = P> + std::ops::Sub<Output = P> + std::ops::Mul<S, Output = P>,
    S: Copy + PartialOrd + Default + std::ops::Sub<Output = S> + std::ops::Div<Output = S>,
{
    let zero = S::default();
    let mut out = Vec::with_capacity(poly.len() + 1);
    for i in 0..poly.len() {
        let (p, q) = (poly[i], poly[(i + 1) % poly.len()]);
        let (sp, sq) = (side(p), side(q));
        if sp >= zero {
            out.push(p);
        }
        if (sp >= zero) != (sq >= zero) {
            out.push(p + (q - p) * (sp / (sp - sq)));
        }
    }
    out
}

/// Two unit vectors across the unit direction `n` (with `n`, an orthonormal
/// frame): the plateaus' plane axes, the single-sample ray's cross-section.
pub(crate) fn across(n: glam::Vec3) -> (glam::Vec3, glam::Vec3) {
    let helper = if n.x.abs() < 0.9 { glam::Vec3::X } else { glam::Vec3::Y };
    let e1 = helper.cross(n).normalize();
    (e1, n.cross(e1))
}
