// Penumbra-map passes: every layer's slab depth and inner/outer fin extremes,
// evaluated at texel centres exactly as `shadow_fins::oracle::RasterMaps` does.
// One workgroup per primitive; its threads stride over the primitive's texels.
//
// The maps are sparse (`fin_types.wgsl`): a redraw first resets the page
// table (`reset_tiles`), marks every tile a caster or fin may write, by a
// conservative test of the primitive against each tile of its bounds
// (`mark_casters`, `mark_fins`: 64 times fewer tests than texels), gives
// each marked tile a slot in the pool and clears it (`allocate_tiles`), and
// only then draws. A tile nothing writes costs one page word.
#import bevy_shadow_fins::fin_types::{
    FinParams, Caster, Fin, CHANNELS, DEPTH_OF_KEY, NO_MIN, NO_MAX, INF_BITS, min_key, max_key, texel_center,
    cross2, orthographic, caster_depth_at, fin_bounds, fin_quad_corners, partial_redraw, CONTROL_LIST_CASTERS, CONTROL_LIST_FINS,
    RETIRED_LAYER, TILE_TEXELS, MAPS_HEADER, HEADER_TILES, HEADER_TILES_BEFORE, HEADER_POOL, PAGE_EMPTY, PAGE_WANTED,
    PAGE_OVERFLOW, FIRST_SLOT, TILE, tiles_per_side, page_index, pooled_texel_index,
}
#import bevy_shadow_fins::cutout::caster_opaque

@group(0) @binding(0) var<uniform> params: FinParams;
@group(0) @binding(1) var<storage, read_write> maps: array<atomic<u32>>;
@group(0) @binding(2) var<storage, read> casters: array<Caster>;
@group(0) @binding(3) var<storage, read> fins: array<Fin>;
// The GPU extraction's `control`: a partial redraw's caster and fin lists
// (count, then indices) at the offsets in its words CONTROL_LIST_CASTERS and
// CONTROL_LIST_FINS (`extract_*.wgsl`). Not read on a full redraw (a stand-in
// on the CPU path).
@group(0) @binding(6) var<storage, read> control: array<u32>;

const WORKGROUP: u32 = 64u;

fn clear_texel(base: u32) {
    atomicStore(&maps[base + 0u], INF_BITS);
    atomicStore(&maps[base + 1u], NO_MIN);
    atomicStore(&maps[base + 2u], NO_MAX);
    atomicStore(&maps[base + 3u], NO_MIN);
    atomicStore(&maps[base + 4u], NO_MAX);
    for (var c = 5u; c < CHANNELS; c++) {
        atomicStore(&maps[base + c], INF_BITS);
    }
}

fn page_words() -> u32 {
    let side = tiles_per_side(params);
    return params.tiles.x * side * side;
}

// A redraw's first pass, one thread per page word. A full redraw empties
// the page table and the pool; a partial one keeps both (the texels outside
// `params.redraw` stay as drawn) and notes where this redraw's tiles start.
@compute @workgroup_size(64, 1, 1)
fn reset_tiles(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = id.x + id.y * 65535u * WORKGROUP;
    let partial = partial_redraw(params);
    if (t == 0u) {
        // Not clamped to the pool: past it, the count is still what the maps want.
        let before = select(0u, atomicLoad(&maps[HEADER_TILES]), partial);
        atomicStore(&maps[HEADER_TILES], before);
        atomicStore(&maps[HEADER_TILES_BEFORE], before);
        // A pool of every tile cannot overflow, however many a partial
        // redraw leaves allocated: no limit for the next plan.
        atomicStore(&maps[HEADER_POOL], select(params.tiles.y, 0xffffffffu, params.tiles.y >= page_words()));
    }
    if (t < page_words() && !partial) {
        atomicStore(&maps[MAPS_HEADER + t], PAGE_EMPTY);
    }
}

// A texel a primitive writes: its tile is wanted, if it has no slot yet.
fn mark_tile(layer: u32, x: u32, y: u32) {
    let page = page_index(params, layer, x, y);
    // Most texels of a tile find it marked already: load before storing.
    if (atomicLoad(&maps[page]) == PAGE_EMPTY) {
        atomicStore(&maps[page], PAGE_WANTED);
    }
}

// One thread per page word: each wanted tile takes the next slot of the pool
// and is cleared; past the pool's end it overflows (its texels read as
// empty, and the count read back says how many the maps wanted).
@compute @workgroup_size(64, 1, 1)
fn allocate_tiles(@builtin(global_invocation_id) id: vec3<u32>) {
    let t = id.x + id.y * 65535u * WORKGROUP;
    if (t >= page_words() || atomicLoad(&maps[MAPS_HEADER + t]) != PAGE_WANTED) {
        return;
    }
    let slot = atomicAdd(&maps[HEADER_TILES], 1u);
    if (slot >= params.tiles.y) {
        atomicStore(&maps[MAPS_HEADER + t], PAGE_OVERFLOW);
        return;
    }
    let page = FIRST_SLOT + slot;
    atomicStore(&maps[MAPS_HEADER + t], page);
    // The slot's texels in order: (x, y) within the tile only matter mod 8.
    for (var k = 0u; k < TILE_TEXELS; k++) {
        clear_texel(pooled_texel_index(params, page, k % 8u, k / 8u));
    }
}

// The texel's first word, or NONE when its tile has no slot.
fn drawn_texel(layer: u32, x: u32, y: u32) -> u32 {
    let page = atomicLoad(&maps[page_index(params, layer, x, y)]);
    return select(NONE, pooled_texel_index(params, page, x, y), page >= FIRST_SLOT);
}

// A partial redraw clears the texels `params.redraw` names in every layer's
// tiles it kept (`allocate_tiles` cleared the ones it added). A full redraw
// dispatches nothing here (all its tiles are new).
@compute @workgroup_size(64, 1, 1)
fn clear_maps(@builtin(global_invocation_id) id: vec3<u32>) {
    let r = params.redraw;
    if (r.x > r.y || r.z > r.w) {
        return;
    }
    let width = r.y - r.x + 1u;
    let per_layer = width * (r.w - r.z + 1u);
    let t = id.x + id.y * 65535u * WORKGROUP;
    if (t >= params.counts.y * per_layer) {
        return;
    }
    let k = t % per_layer;
    let x = r.x + k % width;
    let y = r.z + k / width;
    let page = atomicLoad(&maps[page_index(params, t / per_layer, x, y)]);
    if (page >= FIRST_SLOT && page - FIRST_SLOT < atomicLoad(&maps[HEADER_TILES_BEFORE])) {
        clear_texel(pooled_texel_index(params, page, x, y));
    }
}

// Inclusive texel range whose centres may lie in [lo, hi], within the
// texels redrawn (`params.redraw`); empty when x0 > x1.
fn texel_range(lo: vec2<f32>, hi: vec2<f32>) -> vec4<i32> {
    let r = vec4<f32>(params.redraw);
    let a = ceil((lo - params.map.xy) / params.map.z - 0.5);
    let b = floor((hi - params.map.xy) / params.map.z - 0.5);
    return vec4<i32>(i32(max(a.x, r.x)), i32(min(b.x, r.y)), i32(max(a.y, r.z)), i32(min(b.y, r.w)));
}

fn primitive_index(wg: vec3<u32>) -> u32 {
    return wg.x + wg.y * 65535u;
}

// The primitive the workgroup draws: every one on a full redraw, on a
// partial one the gathered ones (`NONE` past them) of the list whose offset
// is at `control[list_at]`.
fn listed_index(wg: vec3<u32>, list_at: u32) -> u32 {
    let i = primitive_index(wg);
    if (!partial_redraw(params)) {
        return i;
    }
    let list = control[list_at];
    return select(NONE, control[list + 1u + i], i < control[list]);
}

fn caster_index(wg: vec3<u32>) -> u32 {
    return listed_index(wg, CONTROL_LIST_CASTERS);
}

fn fin_index(wg: vec3<u32>) -> u32 {
    return listed_index(wg, CONTROL_LIST_FINS);
}

const NONE: u32 = 0xffffffffu;

@compute @workgroup_size(64, 1, 1)
fn mark_casters(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let i = caster_index(wg);
    if (!live_caster(i)) {
        return;
    }
    let c = casters[i];
    let a = vec2<f32>(c.corners[0], c.corners[1]);
    let b = vec2<f32>(c.corners[2], c.corners[3]);
    let d = vec2<f32>(c.corners[4], c.corners[5]);
    let footprint = Footprint(array<vec2<f32>, 4>(a, b, d, d), FOOTPRINT_TRIANGLE, 0.0);
    mark_footprint_tiles(c.layer, footprint, min(a, min(b, d)), max(a, max(b, d)), lane);
}

// What a primitive may cover, for marking tiles: a triangle (the first
// three points), the convex hull of four (a fin quad, twisted or not), or a
// disk (centre `points[0]`, `radius`: a sector fin).
struct Footprint {
    points: array<vec2<f32>, 4>,
    kind: u32,
    radius: f32,
}

const FOOTPRINT_TRIANGLE: u32 = 0u;
const FOOTPRINT_HULL: u32 = 1u;
const FOOTPRINT_DISK: u32 = 2u;

// The tile range (x0, x1, y0, y1) holding the texels `texel_range` gives.
fn tile_range(range: vec4<i32>) -> vec4<u32> {
    return vec4<u32>(range) / TILE;
}

// A tile's map-space rectangle (min, max), grown by half a texel so that the
// tests below stay conservative against the rasters' own tolerances (a
// texel centre on an edge, `quad_coordinates`' 1e-5).
fn tile_rect(tx: u32, ty: u32) -> vec4<f32> {
    let lo = params.map.xy + vec2<f32>(f32(tx * TILE), f32(ty * TILE)) * params.map.z;
    let pad = 0.5 * params.map.z;
    return vec4<f32>(lo - pad, lo + f32(TILE) * params.map.z + pad);
}

// Whether the rectangle lies wholly outside the line a → b on the side away
// from `inner` (a separating axis of a convex polygon holding `inner`).
fn outside_edge(rect: vec4<f32>, a: vec2<f32>, b: vec2<f32>, inner: vec2<f32>) -> bool {
    let e = b - a;
    let s = cross2(e, inner - a);
    if (s == 0.0) {
        return false;
    }
    let corners = array<vec2<f32>, 4>(rect.xy, rect.zy, rect.xw, rect.zw);
    for (var k = 0; k < 4; k++) {
        if (cross2(e, corners[k] - a) * s >= 0.0) {
            return false;
        }
    }
    return true;
}

// Whether a tile's rectangle meets the triangle a b c (separating axes:
// the rectangle's own are the tile range; then the triangle's edges). A
// triangle of no area is kept whole (its texels are decided by the raster).
fn rect_meets_triangle(rect: vec4<f32>, a: vec2<f32>, b: vec2<f32>, c: vec2<f32>) -> bool {
    let lo = min(a, min(b, c));
    let hi = max(a, max(b, c));
    if (any(hi < rect.xy) || any(lo > rect.zw)) {
        return false;
    }
    return !(outside_edge(rect, a, b, c) || outside_edge(rect, b, c, a) || outside_edge(rect, c, a, b));
}

// Whether a tile's rectangle meets a footprint: a hull is the union of the
// four triangles of three of its points.
fn footprint_meets(rect: vec4<f32>, f: Footprint) -> bool {
    let p = f.points;
    if (f.kind == FOOTPRINT_DISK) {
        let gap = p[0] - clamp(p[0], rect.xy, rect.zw);
        return dot(gap, gap) <= f.radius * f.radius;
    }
    return rect_meets_triangle(rect, p[0], p[1], p[2]) || (f.kind == FOOTPRINT_HULL && (rect_meets_triangle(rect, p[0], p[1], p[3])
        || rect_meets_triangle(rect, p[0], p[2], p[3]) || rect_meets_triangle(rect, p[1], p[2], p[3])));
}

// Marks the tiles of `layer` within the bounds [lo, hi] that the footprint
// meets, the workgroup's lanes striding over them.
fn mark_footprint_tiles(layer: u32, footprint: Footprint, lo: vec2<f32>, hi: vec2<f32>, lane: u32) {
    let range = texel_range(lo, hi);
    if (range.x > range.y || range.z > range.w) {
        return;
    }
    let t = tile_range(range);
    let w = t.y - t.x + 1u;
    let count = w * (t.w - t.z + 1u);
    for (var k = lane; k < count; k += WORKGROUP) {
        let tx = t.x + k % w;
        let ty = t.z + k / w;
        if (footprint_meets(tile_rect(tx, ty), footprint)) {
            mark_tile(layer, tx * TILE, ty * TILE);
        }
    }
}

@compute @workgroup_size(64, 1, 1)
fn raster_casters(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    draw_caster(caster_index(wg), lane);
}

// A caster the passes draw: listed, and not retired by the extraction.
fn live_caster(i: u32) -> bool {
    return i < params.counts.z && casters[i].layer != RETIRED_LAYER;
}

// A caster's slab depth into every texel it covers whose tile has a slot.
fn draw_caster(i: u32, lane: u32) {
    if (!live_caster(i)) {
        return;
    }
    let c = casters[i];
    let a = vec2<f32>(c.corners[0], c.corners[1]);
    let b = vec2<f32>(c.corners[2], c.corners[3]);
    let d = vec2<f32>(c.corners[4], c.corners[5]);
    let range = texel_range(min(a, min(b, d)), max(a, max(b, d)));
    if (range.x > range.y || range.z > range.w) {
        return;
    }
    let w = u32(range.y - range.x + 1);
    let count = w * u32(range.w - range.z + 1);
    for (var k = lane; k < count; k += WORKGROUP) {
        let x = u32(range.x) + k % w;
        let y = u32(range.z) + k / w;
        let q = texel_center(params, x, y);
        let w0 = cross2(b - a, q - a);
        let w1 = cross2(d - b, q - b);
        let w2 = cross2(a - d, q - d);
        let inside = (w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0) || (w0 <= 0.0 && w1 <= 0.0 && w2 <= 0.0);
        if (!inside) {
            continue;
        }
        let z = caster_depth_at(c, q, orthographic(params));
        if (z > params.light.y && caster_opaque(c, q, orthographic(params))) {
            let base = drawn_texel(c.layer, x, y);
            if (base != NONE) {
                atomicMin(&maps[base], bitcast<u32>(z));
            }
        }
    }
}

// (α, t) of q in the quad lerp(m0, m1, α) + t · lerp(a0, a1, α), or (-1, -1) outside.
// Mirrors `shadow_fins::fins::quad_coordinates`.
fn quad_coordinates(q: vec2<f32>, m0: vec2<f32>, m1: vec2<f32>, a0: vec2<f32>, a1: vec2<f32>) -> vec2<f32> {
    let e = m1 - m0;
    let h = q - m0;
    let g = a1 - a0;
    let k2 = cross2(g, a0);
    let k1 = cross2(e, a0) + cross2(h, g);
    let k0 = cross2(h, e);
    let scale = max(dot(e, e), max(dot(a0, a0), dot(a1, a1)));
    var ts = vec2<f32>(-1.0, -1.0);
    if (abs(k2) <= 1e-7 * scale * scale) {
        if (k1 == 0.0) {
            return vec2<f32>(-1.0);
        }
        ts = vec2<f32>(-k0 / k1, 1e30);
    } else {
        let disc = k1 * k1 - 4.0 * k0 * k2;
        if (disc < 0.0) {
            return vec2<f32>(-1.0);
        }
        let root = sqrt(disc);
        let qq = -0.5 * (k1 + select(-root, root, k1 >= 0.0));
        var second = 1e30;
        if (qq != 0.0) {
            second = k0 / qq;
        }
        ts = vec2<f32>(qq / k2, second);
    }
    for (var i = 0; i < 2; i++) {
        var t = ts[i];
        if (abs(t) <= 1e-6) {
            t = 0.0;
        }
        if (!(t >= 0.0 && t <= 1.0 + 1e-5)) {
            continue;
        }
        let dir = e + g * t;
        let len2 = dot(dir, dir);
        if (len2 <= 0.0) {
            continue;
        }
        let alpha = dot(h - a0 * t, dir) / len2;
        let back = m0 + e * alpha + (a0 + g * alpha) * t;
        let miss = back - q;
        if (alpha >= -1e-5 && alpha <= 1.0 + 1e-5 && dot(miss, miss) <= 1e-8 * scale) {
            return vec2<f32>(clamp(alpha, 0.0, 1.0), min(t, 1.0));
        }
    }
    return vec2<f32>(-1.0);
}

// Weight s0 = (1 − t)/2 (eq. 1) and depth L_b of a fin at q; weight < 0 outside.
fn fin_sample(f: Fin, q: vec2<f32>) -> vec2<f32> {
    let outer = f.header.y == 1u;
    if (f.header.x == 0u) {
        let m0 = vec2<f32>(f.data[0], f.data[1]);
        let m1 = vec2<f32>(f.data[2], f.data[3]);
        let a0 = vec2<f32>(f.data[4], f.data[5]) * f.data[8];
        let a1 = vec2<f32>(f.data[6], f.data[7]) * f.data[9];
        let at = quad_coordinates(q, m0, m1, a0, a1);
        if (at.x < 0.0 || (at.y == 0.0 && outer)) {
            return vec2<f32>(-1.0);
        }
        let z0 = f.data[10];
        let z1 = f.data[11];
        // 1/L is linear along the edge's projection under perspective; L
        // itself under the sun's orthographic projection.
        var depth = 1.0 / (1.0 / z0 + (1.0 / z1 - 1.0 / z0) * at.x);
        if (orthographic(params)) {
            depth = z0 + (z1 - z0) * at.x;
        }
        return vec2<f32>(0.5 * (1.0 - at.y), depth);
    }
    let center = vec2<f32>(f.data[0], f.data[1]);
    let from_dir = vec2<f32>(f.data[2], f.data[3]);
    let to_dir = vec2<f32>(f.data[4], f.data[5]);
    let radius = f.data[6];
    let rel = q - center;
    let r2 = dot(rel, rel);
    if (!(r2 <= radius * radius) || (r2 == 0.0 && outer)) {
        return vec2<f32>(-1.0);
    }
    // `shadow_fins::fins::sector_orientation`: opposite bounds (cross ±0) turn
    // counter-clockwise. WGSL's sign(0) is 0, which made such a sector the whole disk.
    let s = select(-1.0, 1.0, cross2(from_dir, to_dir) >= 0.0);
    if (cross2(from_dir, rel) * s < 0.0 || cross2(rel, to_dir) * s < 0.0) {
        return vec2<f32>(-1.0);
    }
    return vec2<f32>(0.5 * (1.0 - sqrt(r2) / radius), f.data[7]);
}

// Marks the tiles every fin may write (before `allocate_tiles`): a quad's
// by the hull of its four corners, a sector's by its disk.
@compute @workgroup_size(64, 1, 1)
fn mark_fins(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let i = fin_index(wg);
    if (!live_fin(i)) {
        return;
    }
    let f = fins[i];
    let center = vec2<f32>(f.data[0], f.data[1]);
    var footprint = Footprint(array<vec2<f32>, 4>(center, center, center, center), FOOTPRINT_DISK, f.data[6]);
    if (f.header.x == 0u) {
        footprint = Footprint(fin_quad_corners(f), FOOTPRINT_HULL, 0.0);
    }
    let bounds = fin_bounds(f);
    mark_footprint_tiles(f.header.z, footprint, bounds.xy, bounds.zw, lane);
}

// Pass 1 of the fins: every fin's key into its side's min and max channels.
@compute @workgroup_size(64, 1, 1)
fn raster_fins(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    raster_fin(fin_index(wg), lane, false);
}

// Pass 2: the exact depth of the fins whose key won in pass 1 (the nearest,
// when several fins share the winning key). Runs after pass 1 has finished,
// so the comparison sees the final keys: deterministic whatever the order.
@compute @workgroup_size(64, 1, 1)
fn raster_fin_depths(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    raster_fin(fin_index(wg), lane, true);
}

// A fin the passes draw: listed, and not retired by the extraction.
fn live_fin(i: u32) -> bool {
    return i < params.counts.w && fins[i].header.z != RETIRED_LAYER;
}

fn raster_fin(i: u32, lane: u32, depths: bool) {
    if (!live_fin(i)) {
        return;
    }
    let f = fins[i];
    let bounds = fin_bounds(f);
    let range = texel_range(bounds.xy, bounds.zw);
    if (range.x > range.y || range.z > range.w) {
        return;
    }
    let w = u32(range.y - range.x + 1);
    let count = w * u32(range.w - range.z + 1);
    let channel = select(1u, 3u, f.header.y == 1u);
    for (var k = lane; k < count; k += WORKGROUP) {
        let x = u32(range.x) + k % w;
        let y = u32(range.z) + k / w;
        var s = fin_sample(f, texel_center(params, x, y));
        if (s.x < 0.0) {
            continue;
        }
        // As for casters: a sun's fin outside its cameras' window may lie in
        // front of the origin; keep its depth's bits ordered.
        if (orthographic(params)) {
            s.y = max(s.y, 0.0);
        }
        let texel = drawn_texel(f.header.z, x, y);
        if (texel == NONE) {
            continue;
        }
        let base = texel + channel;
        let lo = min_key(params, s.x, s.y);
        let hi = max_key(params, s.x, s.y);
        if (!depths) {
            atomicMin(&maps[base], lo);
            atomicMax(&maps[base + 1u], hi);
            continue;
        }
        // Depths are positive: their f32 bits order as the values do.
        if (atomicLoad(&maps[base]) == lo) {
            atomicMin(&maps[base + DEPTH_OF_KEY], bitcast<u32>(s.y));
        }
        if (atomicLoad(&maps[base + 1u]) == hi) {
            atomicMin(&maps[base + 1u + DEPTH_OF_KEY], bitcast<u32>(s.y));
        }
    }
}
