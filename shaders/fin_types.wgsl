// Shared types and helpers of the fin-shadow passes. The math mirrors the core
// crate's oracle (`shadow_fins::oracle`), function for function.
#define_import_path bevy_shadow_fins::fin_types

struct FinParams {
    // (map min x, map min y, texel size, reference depth L0)
    map: vec4<f32>,
    // (resolution, layers, caster count, fin count)
    counts: vec4<u32>,
    // (light size: disk radius R or sun tan θ, near depth, surface epsilon floor, surface epsilon relative
    // to the receiver's distance from the light: `shadow_fins::scene::surface_epsilon`)
    light: vec4<f32>,
    // (refinement 0/1, falloff 0 linear 1 bernstein 2 disk-segment, overlap 0
    // min-max 1 union, projection 0 perspective (disk) 1 orthographic (sun))
    flags: vec4<u32>,
    origin: vec4<f32>,
    axis_u: vec4<f32>,
    axis_v: vec4<f32>,
    axis_n: vec4<f32>,
    // The texels the map passes redraw, inclusive (x0, x1, y0, y1); the
    // whole maps but on a partial redraw (`extract_plan.wgsl`'s `plan_redraw`).
    redraw: vec4<u32>,
    // The sparse maps' shape (below): (layers the page table holds, tiles
    // the pool holds, 0, 0). Written by the CPU on both paths: the GPU
    // extraction's copy of its `FinParams` stops before it.
    tiles: vec4<u32>,
}

// Words of the GPU extraction's `control` holding where a partial redraw's
// caster and fin lists start (`extract_*.wgsl` writes them, `maps.wgsl` reads).
const CONTROL_LIST_CASTERS: u32 = 106u;
const CONTROL_LIST_FINS: u32 = 107u;

// A partial redraw: `redraw` is not the whole maps.
fn partial_redraw(params: FinParams) -> bool {
    let last = max(params.counts.x, 1u) - 1u;
    return any(params.redraw != vec4<u32>(0u, last, 0u, last));
}

// One caster triangle in light-map space (`GpuCaster`, the core's `MapTriangle`):
// corners, plane `normal · X = offset` in the light frame, depth range, layer,
// its cut-out (`cutout.wgsl`): 0 solid, else 1 + its index, and the GPU
// extraction's patch it belongs to (0 from the CPU).
struct Caster {
    corners: array<f32, 6>,
    normal: array<f32, 3>,
    offset: f32,
    min_depth: f32,
    max_depth: f32,
    layer: u32,
    cutout: u32,
    patch_id: u32,
}

// An alpha-masked caster's cut-out (`GpuCutout`, the core's `MapCutout`):
// the UVs at its corners, the corners' light-frame depths (perspective-correct
// interpolation) and where its mask starts in `mask_words` (`cutout.wgsl`).
// The CPU extraction lists them apart; the GPU one writes each at its
// caster's index.
struct CasterCutout {
    uvs: array<f32, 6>,
    depths: array<f32, 3>,
    mask: u32,
}

// The layer of a caster or fin the GPU extraction retired (its instance
// moved and emitted anew, `extract_plan.wgsl`'s `retire_moved`): the maps skip it.
const RETIRED_LAYER: u32 = 0xffffffffu;

// One fin (`GpuFin`): header = (kind 0 quad / 1 sector, side 0 inner / 1 outer,
// layer, the GPU extraction's patch; 0 from the CPU); a quad's data is m0, m1,
// d0, d1, w0, w1, z0, z1, a sector's is centre, from, to, radius, depth.
struct Fin {
    header: vec4<u32>,
    data: array<f32, 12>,
}

// Nine channels per layer texel: slab depth (f32 bits, atomicMin), inner min
// key, inner max key, outer min key, outer max key, then the exact f32 depth
// of each of those four winners. Keys pack a fin's weight (15 bits, high) and
// a 16-bit depth code so that one atomicMin/Max picks the winner by weight,
// ties to the nearer fin (the plateau trick); 0 / 0xffffffff = none. The key's
// depth code only orders ties: a second pass (`raster_fin_depths`) writes the
// exact depth of the fins whose key won, the nearest when several tie, so the
// depth test and refinement (eq. 5) see the fin's f32 depth, not an
// L0/65535 quantum (0.015 at L0 = 1000, larger than small contact gaps).
const CHANNELS: u32 = 9u;
// Offset of a key channel's exact depth channel.
const DEPTH_OF_KEY: u32 = 4u;
const NO_MIN: u32 = 0xffffffffu;
const NO_MAX: u32 = 0u;
const INF_BITS: u32 = 0x7f800000u;

// A point light's cube face shades the receivers in its frustum |x|, |y| ≤ z
// (`CubeFace::of`): widened by a relative 1e-5 so that no receiver between
// two faces is left out (one on the border is shaded by both, alike).
fn in_face(p: vec3<f32>) -> bool {
    let z = p.z * (1.0 + 1e-5);
    return p.z > 0.0 && abs(p.x) <= z && abs(p.y) <= z;
}

// The sun's maps: map point (x, y), penumbrae tan θ ΔL; else a disk's
// perspective maps: (x/L, y/L), penumbrae R ΔL/(L_b L_r).
fn orthographic(params: FinParams) -> bool {
    return params.flags.w == 1u;
}

// Penumbra half-width in map units that an edge at depth lb casts at depth lr
// (`LightFrame::penumbra_half_width`): a disk's R(1/lb − 1/lr) without the
// cancellation of two nearby reciprocals, the sun's tan θ (lr − lb).
fn penumbra_half_width(params: FinParams, lb: f32, lr: f32) -> f32 {
    if (orthographic(params)) {
        return max(params.light.x * (lr - lb), 0.0);
    }
    return max(params.light.x * ((lr - lb) / lb) / lr, 0.0);
}

// A caster's depth at map point q (`MapTriangle::depth_at`): its plane
// n·X = offset along the ray X = z (q, 1) under perspective, X = (q, z) under
// the sun's orthographic projection, kept within the triangle's own depth
// range (float error near edge-on planes). An orthographic depth clamps at 0:
// a sun's frame may sit in front of only what its cameras see, a caster
// outside that (it reaches no texel seen) may lie in front of the origin, and
// negative depths' bits would not order in the maps' atomics.
fn caster_depth_at(c: Caster, q: vec2<f32>, orthographic: bool) -> f32 {
    let n = vec3<f32>(c.normal[0], c.normal[1], c.normal[2]);
    var z = select(c.offset / dot(n, vec3<f32>(q, 1.0)), (c.offset - n.x * q.x - n.y * q.y) / n.z, orthographic);
    // Not finite, tested by its bits: WGSL lets a compiler assume floats are
    // never NaN, which may fold `z != z` to false.
    if ((bitcast<u32>(z) & 0x7fffffffu) >= INF_BITS || abs(z) > 3.0e38) {
        z = c.min_depth;
    }
    z = clamp(z, c.min_depth, c.max_depth);
    if (orthographic) {
        z = max(z, 0.0);
    }
    return z;
}

// Sparse maps. A layer's texels live in 8×8 tiles, and only tiles that a
// caster or fin writes are allocated (`maps.wgsl`: mark, allocate, draw).
// The maps buffer holds MAPS_HEADER words, then a page table of one word per
// tile per layer (PAGE_EMPTY, PAGE_WANTED while being allocated,
// PAGE_OVERFLOW when the pool was full, else FIRST_SLOT + the tile's slot),
// then the pool: `tiles.y` tiles of TILE_TEXELS texels of CHANNELS words.
// A texel whose tile has no slot reads as cleared: no slab, no fin.
const TILE: u32 = 8u;
const TILE_TEXELS: u32 = 64u;
// Header words: tiles allocated (counting past the pool: what the maps
// wanted, read back), and the count before this redraw (a partial redraw
// clears only tiles it did not allocate itself).
const MAPS_HEADER: u32 = 4u;
const HEADER_TILES: u32 = 0u;
const HEADER_TILES_BEFORE: u32 = 1u;
// The pool's size in tiles (`tiles.y`), for the extraction's next plan: the
// header goes back to its `history` after each redraw (`extract_*.wgsl`).
const HEADER_POOL: u32 = 2u;
const PAGE_EMPTY: u32 = 0u;
const PAGE_WANTED: u32 = 1u;
const PAGE_OVERFLOW: u32 = 2u;
const FIRST_SLOT: u32 = 3u;

fn tiles_per_side(params: FinParams) -> u32 {
    return (params.counts.x + TILE - 1u) / TILE;
}

// The page table word of the tile holding texel (x, y) of `layer`.
fn page_index(params: FinParams, layer: u32, x: u32, y: u32) -> u32 {
    let side = tiles_per_side(params);
    return MAPS_HEADER + (layer * side + y / TILE) * side + x / TILE;
}

// The first word of texel (x, y) in the pool, for a page holding a slot
// (page >= FIRST_SLOT).
fn pooled_texel_index(params: FinParams, page: u32, x: u32, y: u32) -> u32 {
    let side = tiles_per_side(params);
    let pool = MAPS_HEADER + params.tiles.x * side * side;
    return pool + ((page - FIRST_SLOT) * TILE_TEXELS + (y % TILE) * TILE + x % TILE) * CHANNELS;
}

fn weight_code(w: f32) -> u32 {
    return u32(round(clamp(w, 0.0, 0.5) * 2.0 * 32767.0));
}

fn depth_code(params: FinParams, z: f32) -> u32 {
    return u32(round(clamp(z / params.map.w, 0.0, 1.0) * 65535.0));
}

fn min_key(params: FinParams, w: f32, z: f32) -> u32 {
    return 1u + ((weight_code(w) << 16u) | depth_code(params, z));
}

fn max_key(params: FinParams, w: f32, z: f32) -> u32 {
    return 1u + ((weight_code(w) << 16u) | (65535u - depth_code(params, z)));
}

struct FinSample {
    weight: f32,
    depth: f32,
}

fn decode_min_key(params: FinParams, k: u32) -> FinSample {
    let v = k - 1u;
    return FinSample(f32(v >> 16u) / (2.0 * 32767.0), f32(v & 0xffffu) / 65535.0 * params.map.w);
}

fn decode_max_key(params: FinParams, k: u32) -> FinSample {
    let v = k - 1u;
    return FinSample(f32(v >> 16u) / (2.0 * 32767.0), f32(65535u - (v & 0xffffu)) / 65535.0 * params.map.w);
}

fn texel_center(params: FinParams, x: u32, y: u32) -> vec2<f32> {
    return params.map.xy + (vec2<f32>(f32(x), f32(y)) + 0.5) * params.map.z;
}

fn cross2(a: vec2<f32>, b: vec2<f32>) -> f32 {
    return a.x * b.y - a.y * b.x;
}

// A quad fin's corners m0, m1 and their ends m0 + a0 w0, m1 + a1 w1.
fn fin_quad_corners(f: Fin) -> array<vec2<f32>, 4> {
    let m0 = vec2<f32>(f.data[0], f.data[1]);
    let m1 = vec2<f32>(f.data[2], f.data[3]);
    return array<vec2<f32>, 4>(
        m0, m1, m0 + vec2<f32>(f.data[4], f.data[5]) * f.data[8], m1 + vec2<f32>(f.data[6], f.data[7]) * f.data[9],
    );
}

// A fin's map-space bounds (min x, min y, max x, max y).
fn fin_bounds(f: Fin) -> vec4<f32> {
    if (f.header.x == 0u) {
        let p = fin_quad_corners(f);
        return vec4<f32>(min(min(p[0], p[1]), min(p[2], p[3])), max(max(p[0], p[1]), max(p[2], p[3])));
    }
    let c = vec2<f32>(f.data[0], f.data[1]);
    let r = f.data[6];
    return vec4<f32>(c - r, c + r);
}
