// The coverage method's depth lists (`shadow_fins::coverage::DepthLists`):
// per caster triangle (both sides), at every texel centre it owns (top-left
// rule), its depth into the texel's near and far k-buffers and the texel's total.
// One workgroup per (caster, block of LIST_BLOCK texels of its bounding box).
#import bevy_shadow_fins::coverage_types::{CoverageParams, INF_BITS, WORKGROUP, list_stride, texel_center, owns}
#import bevy_shadow_fins::fin_types::{Caster, caster_depth_at}
#import bevy_shadow_fins::cutout::caster_opaque

@group(0) @binding(0) var<uniform> params: CoverageParams;
@group(0) @binding(1) var<storage, read_write> lists_rw: array<atomic<u32>>;
@group(0) @binding(2) var<storage, read> casters: array<Caster>;
@group(0) @binding(3) var<storage, read> work: array<vec2<u32>>;

// `frame/coverage.rs::LIST_BLOCK_TEXELS`.
const LIST_BLOCK: u32 = 4096u;

@compute @workgroup_size(64, 1, 1)
fn clear_lists(@builtin(global_invocation_id) id: vec3<u32>) {
    let res = params.counts.x;
    let t = id.x + id.y * 65535u * WORKGROUP;
    if (t >= res * res) {
        return;
    }
    let base = t * list_stride(params);
    for (var i = 0u; i < params.counts.y; i++) {
        atomicStore(&lists_rw[base + i], INF_BITS);
    }
    for (var i = 0u; i <= params.counts.z; i++) {
        atomicStore(&lists_rw[base + params.counts.y + i], 0u);
    }
}

fn texel_range(lo: vec2<f32>, hi: vec2<f32>) -> vec4<i32> {
    let r = f32(params.counts.x) - 1.0;
    let a = ceil((lo - params.lists.xy) / params.lists.z - 0.5);
    let b = floor((hi - params.lists.xy) / params.lists.z - 0.5);
    return vec4<i32>(i32(max(a.x, 0.0)), i32(min(b.x, r)), i32(max(a.y, 0.0)), i32(min(b.y, r)));
}

@compute @workgroup_size(64, 1, 1)
fn raster_lists(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let i = wg.x + wg.y * 65535u;
    if (i >= params.counts.w) {
        return;
    }
    let item = work[i];
    let c = casters[item.x];
    let a = vec2<f32>(c.corners[0], c.corners[1]);
    let b = vec2<f32>(c.corners[2], c.corners[3]);
    let d = vec2<f32>(c.corners[4], c.corners[5]);
    let range = texel_range(min(a, min(b, d)), max(a, max(b, d)));
    if (range.x > range.y || range.z > range.w) {
        return;
    }
    let w = u32(range.y - range.x + 1);
    let count = w * u32(range.w - range.z + 1);
    let near_depths = params.counts.y;
    let far_depths = params.counts.z;
    let end = min(count, (item.y + 1u) * LIST_BLOCK);
    for (var k = item.y * LIST_BLOCK + lane; k < end; k += WORKGROUP) {
        let x = u32(range.x) + k % w;
        let y = u32(range.z) + k / w;
        let q = texel_center(params, x, y);
        if (!owns(a, b, d, q)) {
            continue;
        }
        // w: the projection code (0 disk or rectangle, 1 sun, 2 cube face): 1 is orthographic.
        let z = caster_depth_at(c, q, params.info.w == 1u);
        if (!(z > params.light.y) || !caster_opaque(c, q, params.info.w == 1u)) {
            continue;
        }
        let base = (y * params.counts.x + x) * list_stride(params);
        // A k-buffer by an atomic min cascade: each slot keeps the smaller,
        // the larger moves on; depths are positive, so their bits order as they do.
        var carry = bitcast<u32>(z);
        for (var s = 0u; s < near_depths; s++) {
            let old = atomicMin(&lists_rw[base + s], carry);
            if (old == INF_BITS) {
                break;
            }
            carry = max(old, carry);
        }
        // The far list: the largest, by a max cascade (0 = empty).
        carry = bitcast<u32>(z);
        for (var s = 0u; s < far_depths; s++) {
            let old = atomicMax(&lists_rw[base + near_depths + s], carry);
            if (old == 0u) {
                break;
            }
            carry = min(old, carry);
        }
        atomicAdd(&lists_rw[base + near_depths + far_depths], 1u);
    }
}

