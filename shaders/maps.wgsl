// Penumbra-map passes: every layer's slab depth and inner/outer fin extremes,
// evaluated at texel centres exactly as `shadow_fins::oracle::RasterMaps` does.
// One workgroup per primitive; its threads stride over the primitive's texels.
#import bevy_shadow_fins::fin_types::{
    FinParams, Caster, Fin, CHANNELS, DEPTH_OF_KEY, NO_MIN, NO_MAX, INF_BITS, texel_index, min_key, max_key,
    texel_center, cross2, orthographic, caster_depth_at, fin_bounds, partial_redraw, CONTROL_LIST_CASTERS,
    CONTROL_LIST_FINS, RETIRED_LAYER,
}
#import bevy_shadow_fins::cutout::caster_opaque

@group(0) @binding(0) var<uniform> params: FinParams;
@group(0) @binding(1) var<storage, read_write> maps: array<atomic<u32>>;
@group(0) @binding(2) var<storage, read> casters: array<Caster>;
@group(0) @binding(3) var<storage, read> fins: array<Fin>;
// The GPU extraction's `control`: a partial redraw's caster and fin lists
// (count, then indices) at the offsets in its words CONTROL_LIST_CASTERS and
// CONTROL_LIST_FINS (`extract.wgsl`). Not read on a full redraw (a stand-in
// on the CPU path).
@group(0) @binding(6) var<storage, read> control: array<u32>;

const WORKGROUP: u32 = 64u;

// Clears the texels `params.redraw` names (the whole maps but on a partial
// redraw) in every layer.
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
    let base = texel_index(params, t / per_layer, r.x + k % width, r.z + k / width);
    atomicStore(&maps[base + 0u], INF_BITS);
    atomicStore(&maps[base + 1u], NO_MIN);
    atomicStore(&maps[base + 2u], NO_MAX);
    atomicStore(&maps[base + 3u], NO_MIN);
    atomicStore(&maps[base + 4u], NO_MAX);
    for (var c = 5u; c < CHANNELS; c++) {
        atomicStore(&maps[base + c], INF_BITS);
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
fn raster_casters(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let i = caster_index(wg);
    if (i >= params.counts.z) {
        return;
    }
    let c = casters[i];
    if (c.layer == RETIRED_LAYER) {
        return;
    }
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
            atomicMin(&maps[texel_index(params, c.layer, x, y)], bitcast<u32>(z));
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

fn raster_fin(i: u32, lane: u32, depths: bool) {
    if (i >= params.counts.w) {
        return;
    }
    let f = fins[i];
    if (f.header.z == RETIRED_LAYER) {
        return;
    }
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
        let base = texel_index(params, f.header.z, x, y) + channel;
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
