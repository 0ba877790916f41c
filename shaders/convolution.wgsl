// The visibility buffer of one camera under convolution soft shadow maps
// (Annen et al. 2008, §3–4): per pixel, the average blocker depth by CSM-Z
// over the light's search footprint, the penumbra's footprint at that depth,
// and the filtered shadow test over it — function for function
// `ConvolutionModel::visibility` with the mipmap prefilter.
#import bevy_render::view::View
#import bevy_shadow_fins::fin_types::{FinParams, orthographic, penumbra_half_width}
#import bevy_shadow_fins::fin_view::{FinView, prepass_normal, PIXEL_BACKGROUND, PIXEL_OTHER_FACE, pixel_receiver}
#import bevy_shadow_fins::convolution_types::{
    ConvolutionParams, ConvolutionState, c_k, level_resolution, level_offset, empty_channel, far_depth, near_depth,
    normalised,
}

@group(0) @binding(0) var<uniform> params: FinParams;
@group(0) @binding(1) var<storage, read> basis: array<f32>;
@group(0) @binding(2) var<uniform> csm: ConvolutionParams;
@group(0) @binding(3) var<storage, read> state: ConvolutionState;
@group(0) @binding(4) var depth_prepass: texture_depth_2d;
@group(0) @binding(5) var normal_prepass: texture_2d<f32>;
@group(0) @binding(6) var visibility: texture_storage_2d<r32float, write>;
@group(0) @binding(7) var<uniform> view: View;
@group(0) @binding(8) var<uniform> fin_view: FinView;

// The series' coefficients at one receiver depth d: the filtered
// complementary test ½ + 2 Σ_k sin(c_k (d − z))/c_k (eq. 10) is
// ½ + Σ_k (a_k [w∗cos(c_k z)] − b_k [w∗sin(c_k z)]) with a_k = 2 sin(c_k d)/c_k,
// b_k = 2 cos(c_k d)/c_k, and CSM-Z's numerator the same over z·cos, z·sin
// plus ½ [w∗z] (eq. 11).
struct Series {
    a: array<f32, 16>,
    b: array<f32, 16>,
}

// (f̄ less its constant ½, CSM-Z numerator) of one texel's basis, `at` its first float.
fn texel_terms(at: u32, s: ptr<function, Series>) -> vec2<f32> {
    let m = csm.counts.x;
    var out = vec2<f32>(0.0, 0.5 * basis[at]);
    for (var k = 0u; k < m; k++) {
        out.x += (*s).a[k] * basis[at + 1u + k] - (*s).b[k] * basis[at + 1u + m + k];
        out.y += (*s).a[k] * basis[at + 1u + 2u * m + k] - (*s).b[k] * basis[at + 1u + 3u * m + k];
    }
    return out;
}

fn empty_terms(s: ptr<function, Series>) -> vec2<f32> {
    let m = csm.counts.x;
    var out = vec2<f32>(0.0, 0.5 * empty_channel(csm, 0u));
    for (var k = 0u; k < m; k++) {
        out.x += (*s).a[k] * empty_channel(csm, 1u + k) - (*s).b[k] * empty_channel(csm, 1u + m + k);
        out.y += (*s).a[k] * empty_channel(csm, 1u + 2u * m + k) - (*s).b[k] * empty_channel(csm, 1u + 3u * m + k);
    }
    return out;
}

// One stored level's bilinear lookup between texel centres at level-0 texel
// position `centre`; a tap off the level is an empty texel, or the border's
// for a map that is a window onto casters going on past it (`OffMap`).
fn level_terms(stored: u32, centre: vec2<f32>, s: ptr<function, Series>, empty: vec2<f32>) -> vec2<f32> {
    let r = i32(level_resolution(csm, stored));
    let offset = level_offset(csm, stored);
    let scale = f32(1u << (stored + csm.counts.z));
    let border = csm.lookup.y > 0.5;
    let lowest = select(vec2<f32>(-1.0), vec2<f32>(0.0), border);
    let highest = select(vec2<f32>(f32(r)), vec2<f32>(f32(r - 1)), border);
    let q = clamp(centre / scale - 0.5, lowest, highest);
    let i = vec2<i32>(floor(q));
    let f = q - floor(q);
    var out = vec2<f32>(0.0);
    for (var t = 0u; t < 4u; t++) {
        let o = vec2<i32>(i32(t & 1u), i32(t >> 1u));
        var at = i + o;
        if (border) {
            at = clamp(at, vec2<i32>(0), vec2<i32>(r - 1));
        }
        let w = select(1.0 - f.x, f.x, o.x == 1) * select(1.0 - f.y, f.y, o.y == 1);
        if (w == 0.0) {
            continue;
        }
        var terms = empty;
        if (at.x >= 0 && at.y >= 0 && at.x < r && at.y < r) {
            terms = texel_terms(offset + u32(at.y * r + at.x) * csm.counts.y, s);
        }
        out += w * terms;
    }
    return out;
}

// `(f̄ − ½, z_avg numerator, 1)` over the map-space box `q ± half`
// (`filtered`), or z = 0 when the box misses the map.
fn filtered(q: vec2<f32>, half: vec2<f32>, s: ptr<function, Series>, empty: vec2<f32>) -> vec3<f32> {
    let res = f32(params.counts.x);
    let centre = (q - params.map.xy) / params.map.z;
    let h = max(half / params.map.z, vec2<f32>(0.5));
    let lo = centre - h;
    let hi = centre + h;
    if (!(hi.x > 0.0 && hi.y > 0.0 && lo.x < res && lo.y < res)) {
        return vec3<f32>(0.0);
    }
    // A mipmap is isotropic: the disk's square takes its side, a rectangle
    // light the side of the square of its area; read `lookup.x` levels finer
    // (`VARIANCE_MATCHED_MIP_BIAS`: the trilinear blur as wide as the box).
    var side = max(hi.x - lo.x, hi.y - lo.y);
    if (csm.kernel.w > 0.5) {
        side = 2.0 * sqrt(h.x * h.y);
    }
    let chain = f32(csm.counts.w);
    let level = clamp(log2(max(side, 1.0)) - csm.lookup.x, f32(csm.counts.z), chain - 1.0);
    let l0 = u32(floor(level));
    let t = level - floor(level);
    let first = csm.counts.z;
    var out = (1.0 - t) * level_terms(l0 - first, centre, s, empty);
    if (t > 0.0) {
        out += t * level_terms(min(l0 + 1u, csm.counts.w - 1u) - first, centre, s, empty);
    }
    return vec3<f32>(out, 1.0);
}

@compute @workgroup_size(8, 8, 1)
fn convolution_pass(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = textureDimensions(visibility);
    if (id.x >= size.x || id.y >= size.y) {
        return;
    }
    let pixel = vec2<i32>(id.xy);
    let r = pixel_receiver(view, fin_view, params, id.xy, textureLoad(depth_prepass, pixel, 0),
        prepass_normal(textureLoad(normal_prepass, pixel, 0)));
    if (r.kind == PIXEL_BACKGROUND) {
        textureStore(visibility, pixel, vec4<f32>(1.0));
        return;
    }
    if (r.kind == PIXEL_OTHER_FACE) {
        return;
    }
    let position = r.position;
    let normal = r.normal;
    // Lifted by the surface epsilon and 1.5 texels (the core's CSM lift).
    let ortho = orthographic(params);
    let texel_world = select(params.map.z * position.z, params.map.z, ortho);
    let eps = max(params.light.w * length(position), params.light.z);
    let p = position + normal * (eps + 1.5 * texel_world);
    if (!ortho && !(p.z > params.map.w * 1e-5)) {
        textureStore(visibility, pixel, vec4<f32>(0.0));
        return;
    }
    let q = select(p.xy / p.z, p.xy, ortho);
    let far = far_depth(params.map.w);
    let near = near_depth(state.near_bits, far);
    let span = csm.series.z;
    let d = normalised(p.z, near, far, span);
    var s: Series;
    let dd = d - csm.series.y;
    for (var k = 0u; k < csm.counts.x; k++) {
        let ck = c_k(k + 1u);
        s.a[k] = 2.0 / ck * sin(ck * dd);
        s.b[k] = 2.0 / ck * cos(ck * dd);
    }
    let empty = empty_terms(&s);
    let shape = csm.kernel.yz;
    // 1. The search box: the cone to the light cut at the nearest depth.
    let search = penumbra_half_width(params, near, p.z);
    // 2. The average blocker depth (CSM-Z, eq. 11).
    let blockers = filtered(q, shape * search, &s, empty);
    var v = 1.0;
    if (blockers.z > 0.0) {
        let complement = 0.5 + blockers.x;
        var z_avg = d;
        if (complement > 1e-3) {
            z_avg = clamp(blockers.y / complement, 0.0, d);
        }
        let z_avg_frame = near + z_avg / span * (far - near);
        // 3. The penumbra's half-width at that depth; 4. the filtered test (eq. 3).
        var half = penumbra_half_width(params, max(z_avg_frame, near), p.z);
        if (!(half < 3.0e38)) {
            half = search;
        }
        let test = filtered(q, shape * half, &s, empty);
        if (test.z > 0.0) {
            // Ringing suppression (§3.3), then sharpening (eq. 9).
            var sf = clamp(csm.series.x * (0.5 - (0.5 + test.x)) + 0.5, 0.0, 1.0);
            if (sf > 0.0) {
                sf = pow(sf, 1.0 + csm.series.w * exp(-csm.kernel.x * max(d - z_avg, 0.0)));
            }
            // Radius 0 keeps the point lookup's test.
            if (params.light.x == 0.0) {
                sf = select(0.0, 1.0, sf >= 0.5);
            }
            v = sf;
        }
    }
    textureStore(visibility, pixel, vec4<f32>(v, 0.0, 0.0, 1.0));
}
