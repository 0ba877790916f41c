// The illuminance (visibility) buffer of one camera: per pixel, the receiver
// from the depth and normal prepasses, looked up in every layer's maps and
// combined as `shadow_fins::oracle::combine_layers` does (DESIGN §3, with the
// refinement of eq. 5, the overlap rule and the falloff).
#import bevy_render::view::View
#import bevy_shadow_fins::fin_types::{
    FinParams, FinSample, DEPTH_OF_KEY, NO_MIN, NO_MAX, FIRST_SLOT, page_index, pooled_texel_index, decode_min_key,
    decode_max_key,
    orthographic, penumbra_half_width,
}
#import bevy_shadow_fins::receiver_normal::{clamped_to, receiver_normal}
#import bevy_shadow_fins::fin_view::{FinView, PIXEL_BACKGROUND, PIXEL_OTHER_FACE, pixel_receiver}

@group(0) @binding(0) var<uniform> params: FinParams;
@group(0) @binding(1) var<storage, read> maps: array<u32>;
@group(0) @binding(2) var depth_prepass: texture_depth_2d;
@group(0) @binding(3) var normal_prepass: texture_2d<f32>;
@group(0) @binding(4) var visibility: texture_storage_2d<r32float, write>;
@group(0) @binding(5) var<uniform> view: View;
@group(0) @binding(6) var<uniform> fin_view: FinView;
// Bevy's deferred G-buffer (`receiver_normal.wgsl`), zeros without one.
@group(0) @binding(7) var gbuffer: texture_2d<u32>;

fn half_width(lb: f32, lr: f32) -> f32 {
    return penumbra_half_width(params, lb, lr);
}

// Eq. 5, clamped; a negative result means the fin is not in front of the receiver.
fn refine(s: FinSample, lr: f32) -> f32 {
    if (!(s.depth < lr)) {
        return -1.0;
    }
    if (params.flags.x == 0u) {
        return s.weight;
    }
    let b0 = half_width(s.depth, params.map.w);
    let br = half_width(s.depth, lr);
    var ratio = 1e12;
    if (br > b0 * 1e-12) {
        ratio = b0 / br;
    }
    return clamp(0.5 + ratio * (s.weight - 0.5), 0.0, 0.5);
}

// A key channel's winner: its weight from the key, its exact depth from the
// depth channel beside it.
fn winner(base: u32, channel: u32, min_side: bool) -> FinSample {
    let k = maps[base + channel];
    let depth = bitcast<f32>(maps[base + channel + DEPTH_OF_KEY]);
    if (min_side) {
        return FinSample(decode_min_key(params, k).weight, depth);
    }
    return FinSample(decode_max_key(params, k).weight, depth);
}

// One side's refined weight at a texel (min/max keys at `channel`), or -1 when
// no fin applies.
fn side_weight(base: u32, channel: u32, lr: f32, paper_pick_min: bool) -> f32 {
    let min_k = maps[base + channel];
    let max_k = maps[base + channel + 1u];
    if (min_k == NO_MIN) {
        return -1.0;
    }
    let lo = refine(winner(base, channel, true), lr);
    let hi = refine(winner(base, channel + 1u, false), lr);
    if (params.flags.z == 0u) {
        return select(hi, lo, paper_pick_min);
    }
    // Union of two distinct fins; one fin when both keys name the same.
    let distinct = (min_k - 1u) >> 16u != (max_k - 1u) >> 16u
        || ((min_k - 1u) & 0xffffu) != 65535u - ((max_k - 1u) & 0xffffu);
    if (distinct && lo >= 0.0 && hi >= 0.0) {
        return 1.0 - (1.0 - lo) * (1.0 - hi);
    }
    if (lo >= 0.0) {
        return lo;
    }
    return select(-1.0, hi, distinct);
}

fn falloff(i: f32) -> f32 {
    let x = clamp(i, 0.0, 1.0);
    if (params.flags.y == 0u) {
        return x;
    }
    if (params.flags.y == 1u) {
        return x * x * (3.0 - 2.0 * x);
    }
    let s = 2.0 * x - 1.0;
    return clamp(0.5 + (s * sqrt(max(1.0 - s * s, 0.0)) + asin(s)) / 3.14159265358979, 0.0, 1.0);
}

@compute @workgroup_size(8, 8, 1)
fn visibility_pass(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = textureDimensions(visibility);
    if (id.x >= size.x || id.y >= size.y) {
        return;
    }
    let pixel = vec2<i32>(id.xy);
    let r = pixel_receiver(view, fin_view, params, id.xy, textureLoad(depth_prepass, pixel, 0),
        receiver_normal(textureLoad(normal_prepass, pixel, 0), textureLoad(gbuffer, clamped_to(textureDimensions(gbuffer), pixel), 0)));
    if (r.kind == PIXEL_BACKGROUND) {
        textureStore(visibility, pixel, vec4<f32>(1.0));
        return;
    }
    if (r.kind == PIXEL_OTHER_FACE) {
        return;
    }
    let position = r.position;
    let normal = r.normal;
    // No layer: nothing casts.
    if (params.counts.y == 0u) {
        textureStore(visibility, pixel, vec4<f32>(1.0));
        return;
    }

    // Lift by one texel's world size along the normal (as the raster oracle:
    // a perspective texel grows with depth, an orthographic one does not).
    let near = params.light.y;
    let texel_world = select(params.map.z * max(position.z, near), params.map.z, orthographic(params));
    let eps = max(params.light.w * length(position), params.light.z);
    let p = position + normal * (eps + texel_world);
    var v = 0.0;
    if (p.z > near) {
        let q = select(p.xy / p.z, p.xy, orthographic(params));
        let t = (q - params.map.xy) / params.map.z;
        let res = f32(params.counts.x);
        let inside = t.x >= 0.0 && t.y >= 0.0 && t.x < res && t.y < res;
        let limit = p.z * (1.0 - 1e-6);
        var illuminance = 1.0;
        for (var layer = 0u; layer < params.counts.y; layer++) {
            if (!inside) {
                break;
            }
            // A tile that no caster or fin wrote holds nothing.
            let page = maps[page_index(params, layer, u32(t.x), u32(t.y))];
            if (page < FIRST_SLOT) {
                continue;
            }
            let base = pooled_texel_index(params, page, u32(t.x), u32(t.y));
            let slab = bitcast<f32>(maps[base]);
            let blocked = slab < limit;
            let inner = side_weight(base, 1u, p.z, true);
            let outer = side_weight(base, 3u, p.z, false);
            if (inner >= 0.0 || outer >= 0.0) {
                let u = clamp(select(1.0, 0.0, blocked) + max(inner, 0.0) - max(outer, 0.0), 0.0, 1.0);
                if (params.flags.z == 0u) {
                    illuminance = min(illuminance, u);
                } else {
                    illuminance = illuminance * u;
                }
            } else if (blocked) {
                illuminance = 0.0;
            }
        }
        v = falloff(illuminance);
    }
    textureStore(visibility, pixel, vec4<f32>(v, 0.0, 0.0, 1.0));
}
