//! Alpha-masked casters (glTF `alphaMode: MASK`, Bevy's `AlphaMode::Mask`):
//! where the material's alpha is below its cutoff, the caster is a hole and
//! light passes (issue 16, item 2).
//!
//! Semantics, the same for the ground truth, the CPU oracle and the GPU:
//! - the alpha at a UV is the texture's bilinear interpolation between
//!   texel centres — or, for a nearest-filtered texture ([`Filter`]), the
//!   alpha of the texel the UV falls in —, the texture read by its
//!   sampler's wrap modes (repeat, mirrored repeat, clamp), times the
//!   material's base alpha; a masked triangle blocks a ray (the ground
//!   truth's) or a texel's centre ray (a light-space map's) where that alpha
//!   is at least the cutoff (ties opaque, as Bevy's `alpha < cutoff →
//!   discard`);
//! - UVs are interpolated linearly in 3D: in a perspective map that is
//!   `Σ (bᵢ/zᵢ) uvᵢ / Σ bᵢ/zᵢ` over the map triangle's barycentrics `bᵢ`
//!   and corner depths `zᵢ` ([`crate::oracle::MapTriangle::opaque_at`]);
//! - the outline of the opaque region is geometry: per masked face, the
//!   iso-line `alpha = cutoff` by marching squares over the texel-centre
//!   grid (exact at the grid's cell edges, a chord of the bilinear curve
//!   inside a cell) — a nearest-filtered mask's, exactly, the texel borders
//!   between opaque and clear texels —, clipped to the face's UV triangle, and the opaque
//!   stretches of the face's own edges ([`Outline`]). A masked object's
//!   silhouettes (the fins') and potential silhouette edges (the coverage
//!   method's) are its outline's edges instead of its mesh edges, so a hole
//!   and a leaf's blade have penumbrae of their own;
//! - a mask larger than [`MAX_MASK_SIDE`] on a side is box-filtered down to
//!   it first (a hole smaller than 1/256 of the texture is not modelled):
//!   the outline's detail follows the mask, not the texture's resolution;
//!   the work of building it is capped per face ([`MAX_CELLS_PER_FACE`])
//!   and per mesh ([`MAX_CELLS_PER_MESH`]), past which faces are modelled
//!   by their edges' opaque stretches alone;
//! - a non-manifold edge (three or more faces) is cut per face, each face's
//!   opaque stretches a one-face edge.

use std::sync::Arc;

use glam::Vec2;

mod mask;
mod outline;

pub use mask::{Address, AlphaMask, CutoutError, Filter, MAX_MASK_SIDE, MAX_UV};
pub use outline::{MAX_CELLS_PER_FACE, MAX_CELLS_PER_MESH, Outline};

/// The cut-outs of one mesh under one mask: per face of its topology
/// (`Topology::faces` order), the UVs of the face's corners, and the
/// outline of the opaque region. Built once per (mesh, mask) and shared by
/// every instance.
#[derive(Debug, Clone)]
pub struct Cutout {
    pub mask: Arc<AlphaMask>,
    /// One UV per mesh vertex, as given.
    pub vertex_uvs: Arc<Vec<Vec2>>,
    pub face_uvs: Arc<Vec<[Vec2; 3]>>,
    pub outline: Arc<Outline>,
}

impl Cutout {
    /// The cut-outs of `mesh` with one UV per mesh vertex.
    pub fn new(
        mask: Arc<AlphaMask>,
        uvs: &[Vec2],
        mesh: &crate::mesh::Mesh,
        topology: &crate::mesh::Topology,
    ) -> Result<Self, CutoutError> {
        if uvs.len() != mesh.positions().len() {
            return Err(CutoutError::Uvs { uvs: uvs.len(), vertices: mesh.positions().len() });
        }
        if let Some(bad) = uvs.iter().find(|uv| !uv.is_finite() || uv.abs().max_element() > MAX_UV) {
            return Err(CutoutError::BadUv(*bad));
        }
        let face_uvs: Vec<[Vec2; 3]> = topology
            .source_triangles
            .iter()
            .map(|&t| {
                let i = &mesh.indices()[t as usize * 3..t as usize * 3 + 3];
                [uvs[i[0] as usize], uvs[i[1] as usize], uvs[i[2] as usize]]
            })
            .collect();
        let outline = Outline::build(&mask, &face_uvs, topology);
        Ok(Self { mask, vertex_uvs: Arc::new(uvs.to_vec()), face_uvs: Arc::new(face_uvs), outline: Arc::new(outline) })
    }
}

/// One caster triangle's cut-out: its mask (an index into the scene's masks)
/// and the UVs of its corners.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CasterCutout {
    pub mask: u32,
    pub uvs: [Vec2; 3],
}

/// Whether caster `k` blocks light at its barycentric point `(u, v)`, given
/// every caster's cut-out (`cutouts`, empty when none is masked; see
/// [`crate::scene::caster_cutouts`]) and the masks they index: always for a
/// solid caster.
#[inline]
pub fn caster_blocks_at(cutouts: &[Option<CasterCutout>], masks: &[Arc<AlphaMask>], k: usize, u: f32, v: f32) -> bool {
    cutouts.get(k).copied().flatten().is_none_or(|c| c.blocks_at(masks, u, v))
}

impl CasterCutout {
    /// True where the triangle is opaque at its barycentric point `(u, v)`
    /// (weights `1 − u − v`, `u`, `v` of its corners), reading `masks`.
    #[inline]
    pub fn blocks_at(&self, masks: &[Arc<AlphaMask>], u: f32, v: f32) -> bool {
        masks[self.mask as usize].opaque(self.uvs[0] * (1.0 - u - v) + self.uvs[1] * u + self.uvs[2] * v)
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::mesh::{Mesh, NO_FACE, Topology};

    #[test]
    fn alpha_is_bilinear_between_texel_centres_repeated_and_bad_input_is_an_error() {
        // 2 × 2: a hole at the top left texel.
        let m = AlphaMask::new(2, 2, vec![0, 255, 255, 255], 1.0, 0.5).unwrap();
        // At texel centres, the texel.
        assert!(!m.opaque(Vec2::new(0.25, 0.25)));
        assert!(m.opaque(Vec2::new(0.75, 0.25)) && m.opaque(Vec2::new(0.25, 0.75)));
        // Half way between the hole and its right neighbour: 0.5.
        assert!((m.alpha_at(Vec2::new(0.5, 0.25)) - 0.5).abs() < 1e-6);
        // Repeated: 1.25 and −0.75 are 0.25; the wrap joins the last texel to the first.
        assert!(!m.opaque(Vec2::new(1.25, -0.75)));
        assert!((m.alpha_at(Vec2::new(0.0, 0.25)) - 0.5).abs() < 1e-6);
        assert!(m.opaque(Vec2::NAN));
        // The base alpha scales every texel: at 0.4, nothing reaches 0.5.
        let faded = AlphaMask::new(2, 2, vec![0, 255, 255, 255], 0.4, 0.5).unwrap();
        assert!(!faded.opaque(Vec2::new(0.75, 0.75)));
        // No texture: the base alpha alone.
        assert!(AlphaMask::new(0, 0, vec![], 1.0, 0.5).unwrap().opaque(Vec2::new(0.3, 0.9)));
        assert!(matches!(AlphaMask::new(2, 2, vec![0; 3], 1.0, 0.5), Err(CutoutError::Size { .. })));
        assert!(matches!(AlphaMask::new(1, 1, vec![0], 1.0, f32::NAN), Err(CutoutError::Cutoff(_))));
        assert_eq!(AlphaMask::new(1, 1, vec![0], 1.0, 7.0).unwrap().cutoff(), 1.0);
        // A big mask is box-filtered to MAX_MASK_SIDE, its alpha kept.
        let big = AlphaMask::new(
            1024,
            512,
            (0..1024 * 512).map(|i| if i % 1024 < 512 { 0 } else { 255 }).collect(),
            1.0,
            0.5,
        )
        .unwrap();
        assert_eq!((big.width(), big.height()), (256, 128));
        assert!(!big.opaque(Vec2::new(0.2, 0.5)) && big.opaque(Vec2::new(0.8, 0.5)));
    }

    #[test]
    fn a_nearest_filtered_mask_is_its_texels_squares() {
        let m = AlphaMask::new(2, 2, vec![0, 255, 255, 255], 1.0, 0.5).unwrap().with_filter(Filter::Nearest);
        // Up to the texel border the hole's alpha, from it on the neighbour's (bilinear: 0.5 there).
        assert_eq!(m.alpha_at(Vec2::new(0.499, 0.25)), 0.0);
        assert_eq!(m.alpha_at(Vec2::new(0.5, 0.25)), 1.0);
        assert!(!m.opaque(Vec2::new(0.01, 0.49)) && m.opaque(Vec2::new(0.01, 0.51)));
        // Wrapped as the linear mask is: −0.25 repeats to 0.75.
        assert!(m.opaque(Vec2::new(-0.25, 0.25)) && !m.opaque(Vec2::new(1.25, 0.25)));
        // Its outline is the hole's two inner sides on a card (u, v in [0, 1]):
        // a 0.5 × 0.5 square hole, the rest of the card opaque.
        let (_, c) = card_cutout(m, 0.0, false);
        assert!(unbalanced_vertices(&c.outline).is_empty());
        assert!((enclosed_area(&c.outline) - 0.54 * 0.75).abs() < 1e-5, "{}", enclosed_area(&c.outline));
    }

    /// A 0.6 × 0.9 card with its UVs turned by `uv_turn` about the
    /// texture's centre, and mirrored in u when `mirror` (the UV triangles
    /// then turn the way the faces wind; unmirrored, against it).
    fn card_cutout(mask: AlphaMask, uv_turn: f32, mirror: bool) -> (Topology, Cutout) {
        let (mesh, uvs) = crate::shapes::card(0.6, 0.9);
        let rot = glam::Mat2::from_angle(uv_turn);
        let flip = |uv: Vec2| if mirror { Vec2::new(1.0 - uv.x, uv.y) } else { uv };
        let uvs: Vec<Vec2> = uvs.iter().map(|&uv| rot * (flip(uv) - 0.5) + 0.5).collect();
        let topology = Topology::build(&mesh);
        let cutout = Cutout::new(Arc::new(mask), &uvs, &mesh, &topology).unwrap();
        (topology, cutout)
    }

    /// The vertices where one-face edges leaving, each walked the way its
    /// face winds, do not match those entering (none on closed outlines),
    /// with the edges there.
    fn unbalanced_vertices(o: &Outline) -> Vec<String> {
        let mut degree = vec![0i32; o.positions.len()];
        for e in o.edges.iter().filter(|e| e.faces[1] == NO_FACE) {
            let [a, b] = if e.forward[0] { e.vertices } else { [e.vertices[1], e.vertices[0]] };
            degree[a as usize] += 1;
            degree[b as usize] -= 1;
        }
        (0..degree.len())
            .filter(|&i| degree[i] != 0)
            .map(|i| {
                let at: Vec<String> = o
                    .edges
                    .iter()
                    .filter(|e| e.vertices.contains(&(i as u32)))
                    .map(|e| {
                        format!(
                            "{:?}: {} → {}",
                            e, o.positions[e.vertices[0] as usize], o.positions[e.vertices[1] as usize]
                        )
                    })
                    .collect();
                format!("{} at {}: {}", degree[i], o.positions[i], at.join("; "))
            })
            .collect()
    }

    /// The area the one-face edges enclose, in the card's plane (z = 0, seen from +z).
    fn enclosed_area(o: &Outline) -> f32 {
        o.edges
            .iter()
            .filter(|e| e.faces[1] == NO_FACE)
            .map(|e| {
                let [a, b] = if e.forward[0] { e.vertices } else { [e.vertices[1], e.vertices[0]] };
                let (a, b) = (o.positions[a as usize], o.positions[b as usize]);
                0.5 * a.truncate().perp_dot(b.truncate())
            })
            .sum()
    }

    #[test]
    fn an_opaque_card_is_outlined_by_its_border_and_a_clear_one_by_nothing() {
        let (_, solid) = card_cutout(AlphaMask::new(4, 4, vec![255; 16], 1.0, 0.5).unwrap(), 0.0, false);
        let o = &solid.outline;
        let border: f32 = o
            .edges
            .iter()
            .filter(|e| e.faces[1] == NO_FACE)
            .map(|e| o.positions[e.vertices[0] as usize].distance(o.positions[e.vertices[1] as usize]))
            .sum();
        assert!((border - 3.0).abs() < 1e-5, "border {border}, the card's perimeter is 3");
        assert!((enclosed_area(o) - 0.54).abs() < 1e-5);
        // The diagonal, both faces opaque: one two-face edge.
        assert_eq!(o.edges.iter().filter(|e| e.faces[1] != NO_FACE).count(), 1);
        assert!(unbalanced_vertices(o).is_empty());
        let (_, clear) = card_cutout(AlphaMask::new(4, 4, vec![0; 16], 1.0, 0.5).unwrap(), 0.0, false);
        assert!(clear.outline.edges.is_empty());
    }

    #[test]
    fn the_leafs_outline_is_closed_and_encloses_its_opaque_area_at_any_uv_rotation() {
        let alpha = crate::shapes::leaf_alpha(128);
        // The opaque area by the mask's test on a fine grid, against the
        // area the outline encloses; bilinear and nearest (whose texel
        // corners the card's diagonal runs through, unturned).
        let cases = [(0.0, false), (0.3, false), (1.9, false), (0.0, true), (0.7, true)];
        for ((turn, mirror), filter) in cases.into_iter().flat_map(|c| [(c, Filter::Linear), (c, Filter::Nearest)]) {
            let mask = AlphaMask::new(128, 128, alpha.clone(), 1.0, 0.5).unwrap().with_filter(filter);
            let (_, c) = card_cutout(mask, turn, mirror);
            let o = &c.outline;
            let open = unbalanced_vertices(o);
            assert!(open.is_empty(), "turn {turn}, mirror {mirror}, {filter:?}: open outline: {open:#?}");
            assert_eq!(o.joined_ends, 0, "turn {turn}, mirror {mirror}, {filter:?}: closed without joining ends");
            let n = 600;
            let mut opaque = 0;
            for y in 0..n {
                for x in 0..n {
                    let q = Vec2::new((x as f32 + 0.5) / n as f32, (y as f32 + 0.5) / n as f32);
                    // The card's UV at its point (u, 1 − y) mirrored and turned like its corners'.
                    let q = if mirror { Vec2::new(1.0 - q.x, q.y) } else { q };
                    let uv = glam::Mat2::from_angle(turn) * (q - 0.5) + 0.5;
                    opaque += c.mask.opaque(uv) as u32;
                }
            }
            let sampled = opaque as f32 / (n * n) as f32 * 0.54;
            let area = enclosed_area(o);
            assert!(
                (area - sampled).abs() < 0.01 * 0.54,
                "turn {turn}, mirror {mirror}, {filter:?}: outline encloses {area}, opaque {sampled}"
            );
            // Holes and blade: many more edges than the card's four.
            assert!(o.edges.len() > 100, "{}", o.edges.len());
        }
    }

    #[test]
    fn a_bent_strip_of_random_masks_keeps_a_closed_outline() {
        // A strip of 8 faces folded along its rungs, UVs continuous, a noisy
        // mask at any cutoff: every outline closes.
        let mut seed = 12345u32;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        };
        let mut joined = 0;
        for k in 0..2000 {
            let alpha: Vec<u8> = (0..64).map(|_| (rnd() % 256) as u8).collect();
            let cutoff = (rnd() % 100) as f32 / 100.0;
            let filter = if k % 2 == 0 { Filter::Linear } else { Filter::Nearest };
            let mask = AlphaMask::new(8, 8, alpha, 1.0, cutoff).unwrap().with_filter(filter);
            let (mut positions, mut uvs, mut indices) = (Vec::new(), Vec::new(), Vec::new());
            for i in 0..5u32 {
                let x = i as f32 * 0.25;
                let z = if i % 2 == 1 { 0.1 } else { 0.0 };
                positions.extend([Vec3::new(x, 0.0, z), Vec3::new(x, 1.0, z)]);
                let u = i as f32 * 0.17 + (rnd() % 100) as f32 * 1e-4;
                uvs.extend([Vec2::new(u, 0.9), Vec2::new(u, 0.05)]);
                if i > 0 {
                    let b = 2 * (i - 1);
                    indices.extend([b, b + 2, b + 3, b, b + 3, b + 1]);
                }
            }
            let mesh = Mesh::new(positions, indices).unwrap();
            let topology = Topology::build(&mesh);
            let c = Cutout::new(Arc::new(mask), &uvs, &mesh, &topology).unwrap();
            let open = unbalanced_vertices(&c.outline);
            assert!(open.is_empty(), "open outline: {open:#?}");
            joined += c.outline.joined_ends;
            for e in &c.outline.edges {
                let (a, b) = (c.outline.positions[e.vertices[0] as usize], c.outline.positions[e.vertices[1] as usize]);
                assert!(a.is_finite() && b.is_finite() && a != b);
            }
        }
        // Joins mend the rare corner case only (a few in 16 000 faces).
        assert!(joined <= 40, "{joined} dangling ends joined");
    }
}
