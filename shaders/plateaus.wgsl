// The visibility buffer of one camera under plateaus (Haines 2001): the
// hard shadow from the light's shadow map everywhere, and on the receiver
// plane, outside it, the darkest cone or sheet of the silhouette edges
// through Haines' falloff — `PlateauTexture::value` beside the raster
// oracle's hard shadow, evaluated at each pixel instead of drawn into a
// texture (the same values at the pixels' own points, no texel grid).
#import bevy_render::view::View
#import bevy_shadow_fins::fin_types::{FinParams, FIRST_SLOT, orthographic, page_index, pooled_texel_index}
#import bevy_shadow_fins::fin_view::{FinView, prepass_normal, PIXEL_BACKGROUND, PIXEL_OTHER_FACE, pixel_receiver}

// `PlateauUniform` in `frame/plateaus.rs`.
struct PlateauParams {
    point: vec4<f32>,
    normal: vec4<f32>,
    axis_u: vec4<f32>,
    axis_v: vec4<f32>,
    // (grid origin x, y, cells per unit x, y)
    grid: vec4<f32>,
    // (cells in x, cells in y, sheets, 0)
    dims: vec4<u32>,
}

// Two cones (centres and radii on the plane) and the sheet between them;
// radii.z: 0 circles, 1 parallelograms of matrix `to_axes` (columns).
struct Sheet {
    ends: vec4<f32>,
    radii: vec4<f32>,
    to_axes: vec4<f32>,
}

@group(0) @binding(0) var<uniform> params: FinParams;
@group(0) @binding(1) var<storage, read> maps: array<u32>;
@group(0) @binding(2) var<uniform> plateau: PlateauParams;
@group(0) @binding(3) var<storage, read> sheets: array<Sheet>;
@group(0) @binding(4) var<storage, read> cell_starts: array<u32>;
@group(0) @binding(5) var<storage, read> cell_items: array<u32>;
@group(0) @binding(6) var depth_prepass: texture_depth_2d;
@group(0) @binding(7) var normal_prepass: texture_2d<f32>;
@group(0) @binding(8) var visibility: texture_storage_2d<r32float, write>;
@group(0) @binding(9) var<uniform> view: View;
@group(0) @binding(10) var<uniform> fin_view: FinView;

// Sheets one cell's pixels walk (`MAX_CELL_SHEETS` in `frame/plateaus.rs`,
// which reports a longer cell): llvmpipe stops an invocation after 65535
// loop iterations, so `sheet_tau` has no loop of its own.
const MAX_CELL_SHEETS: u32 = 16384u;

// The circles' |q − p(u)| / r(u) at u on the segment, +∞ off it.
fn circle_at(d: vec2<f32>, e: vec2<f32>, r1: f32, dr: f32, u: f32) -> f32 {
    let r = r1 + u * dr;
    if (!(u >= 0.0 && u <= 1.0 && r > 0.0)) {
        return 3.0e38;
    }
    return length(d - e * u) / r;
}

// The parallelograms' norm max |cᵢ(u)| / r(u) at u on the segment, +∞ off it.
fn box_at(c0: vec2<f32>, ce: vec2<f32>, r1: f32, dr: f32, u: f32) -> f32 {
    let r = r1 + u * dr;
    if (!(u >= 0.0 && u <= 1.0 && r > 0.0)) {
        return 3.0e38;
    }
    let c = c0 - ce * u;
    return max(abs(c.x), abs(c.y)) / r;
}

// Where num − den·u = 0, or −1 (off the segment) when den = 0.
fn root(num: f32, den: f32) -> f32 {
    return select(-1.0, num / den, den != 0.0);
}

// τ at which q enters the hull of the sheet's cross-sections of radii
// τ·r₁, τ·r₂ (`sheet_tau`, in f32 where the core has f64: a line light's
// sliver of a side loses τ to rounding): an end, the one stationary point
// (circles), or a kink of the parallelogram norm.
fn sheet_tau(s: Sheet, q: vec2<f32>) -> f32 {
    let p1 = s.ends.xy;
    let d = q - p1;
    let e = s.ends.zw - p1;
    let r1 = s.radii.x;
    let dr = s.radii.y - s.radii.x;
    if (s.radii.z > 0.5) {
        let m = mat2x2<f32>(s.to_axes.xy, s.to_axes.zw);
        let c0 = m * d;
        let ce = m * e;
        let ends = min(box_at(c0, ce, r1, dr, 0.0), box_at(c0, ce, r1, dr, 1.0));
        let kinks = min(
            min(box_at(c0, ce, r1, dr, root(c0.x, ce.x)), box_at(c0, ce, r1, dr, root(c0.y, ce.y))),
            min(
                box_at(c0, ce, r1, dr, root(c0.x - c0.y, ce.x - ce.y)),
                box_at(c0, ce, r1, dr, root(c0.x + c0.y, ce.x + ce.y)),
            ),
        );
        return min(ends, kinks);
    }
    let ends = min(circle_at(d, e, r1, dr, 0.0), circle_at(d, e, r1, dr, 1.0));
    let stationary = root(r1 * dot(d, e) + dr * dot(d, d), r1 * dot(e, e) + dr * dot(d, e));
    return min(ends, circle_at(d, e, r1, dr, stationary));
}

// The light's hard shadow at a receiver: its maps' slab depths looked up
// after the one-texel lift, as `RasterMaps::visibility` of the hard method.
fn hard_blocked(position: vec3<f32>, normal: vec3<f32>) -> bool {
    let near = params.light.y;
    let ortho = orthographic(params);
    let texel_world = select(params.map.z * max(position.z, near), params.map.z, ortho);
    let eps = max(params.light.w * length(position), params.light.z);
    let p = position + normal * (eps + texel_world);
    if (!(p.z > near)) {
        return true;
    }
    let q = select(p.xy / p.z, p.xy, ortho);
    let t = (q - params.map.xy) / params.map.z;
    let res = f32(params.counts.x);
    if (!(t.x >= 0.0 && t.y >= 0.0 && t.x < res && t.y < res)) {
        return false;
    }
    let limit = p.z * (1.0 - 1e-6);
    for (var layer = 0u; layer < params.counts.y; layer++) {
        let page = maps[page_index(params, layer, u32(t.x), u32(t.y))];
        if (page < FIRST_SLOT) {
            continue;
        }
        let slab = bitcast<f32>(maps[pooled_texel_index(params, page, u32(t.x), u32(t.y))]);
        if (slab < limit) {
            return true;
        }
    }
    return false;
}

// The texture on the plane at p (light frame): Haines' falloff 3τ² − 2τ³
// of the least τ over the cell's sheets.
fn texture_value(p: vec3<f32>) -> f32 {
    let rel = p - plateau.point.xyz;
    let q = vec2<f32>(dot(rel, plateau.axis_u.xyz), dot(rel, plateau.axis_v.xyz));
    let c = (q - plateau.grid.xy) * plateau.grid.zw;
    if (!(c.x >= 0.0 && c.y >= 0.0 && u32(c.x) < plateau.dims.x && u32(c.y) < plateau.dims.y)) {
        return 1.0;
    }
    let cell = u32(c.y) * plateau.dims.x + u32(c.x);
    let start = cell_starts[cell];
    let end = min(cell_starts[cell + 1u], start + MAX_CELL_SHEETS);
    var tau = 1.0;
    for (var i = start; i < end; i++) {
        tau = min(tau, sheet_tau(sheets[cell_items[i]], q));
    }
    let x = clamp(tau, 0.0, 1.0);
    return x * x * (3.0 - 2.0 * x);
}

@compute @workgroup_size(8, 8, 1)
fn plateaus_pass(@builtin(global_invocation_id) id: vec3<u32>) {
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
    var v = 1.0;
    if (params.counts.y > 0u && hard_blocked(position, normal)) {
        v = 0.0;
    } else {
        // On the plane: within ten surface epsilons of it (`PlateauTexture::holds`).
        let eps = max(params.light.w * length(position), params.light.z);
        if (abs(dot(position - plateau.point.xyz, plateau.normal.xyz)) <= 10.0 * eps) {
            v = texture_value(position);
        }
    }
    textureStore(visibility, pixel, vec4<f32>(v, 0.0, 0.0, 1.0));
}
