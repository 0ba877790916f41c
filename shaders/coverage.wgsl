// Coverage with occluder fusion on the GPU: the same rules as the core's
// `shadow_fins::coverage` through depth lists (`ReferenceCount::Raster`),
// function for function. Three dispatches per camera:
//
//  (raster_lists, in coverage_lists.wgsl, fills the depth lists first)
//  coverage_reference   per pixel: the receiver from the prepasses; D(c) from
//                       the depth lists, corrected by the edges and faces
//                       passed between the texel's ray and the receiver's
//                       (or a sentinel: nothing to shade, nothing above the
//                       horizon); clears the pixel's tally
//  coverage_samples     per pixel and 32-sample word (z): D(s) = D(c) +
//                       Σ σ χ over the cell's potential silhouette edges, in
//                       bit-sliced counters; adds the word's visible and
//                       above-horizon counts to the pixel's tally
//  coverage_resolve     per pixel: V = visible / above, into the visibility
//                       texture the fins also write
//
// Why split: one invocation per word keeps 8 counter words live instead of
// 64, and no invocation loops longer than the cell's edges (llvmpipe ends a
// shader after 65535 loop iterations in all; a GPU's watchdog is similar).
// The per-sample and per-face tests are unrolled for the same reason.
#import bevy_render::view::View
#import bevy_shadow_fins::coverage_types::{CoverageParams, Edge, CHUNK, MAX_CHUNKS, list_stride, texel_center}
#import bevy_shadow_fins::fin_view::FinView
#import bevy_shadow_fins::receiver_normal::{clamped_to, receiver_normal}
#import bevy_shadow_fins::fin_types::in_face

@group(0) @binding(0) var<uniform> params: CoverageParams;
@group(0) @binding(1) var<storage, read> lists: array<u32>;
@group(0) @binding(2) var<storage, read> edges: array<Edge>;
@group(0) @binding(3) var<storage, read> cell_starts: array<u32>;
@group(0) @binding(4) var<storage, read> cell_items: array<u32>;
// Per quad of four samples: their x, then their y (`CoverageFrame::sample_planes`).
@group(0) @binding(5) var<storage, read> samples: array<vec4<f32>>;
@group(0) @binding(6) var depth_prepass: texture_depth_2d;
@group(0) @binding(7) var normal_prepass: texture_2d<f32>;
@group(0) @binding(8) var visibility: texture_storage_2d<r32float, write>;
@group(0) @binding(9) var<uniform> view: View;
@group(0) @binding(10) var<uniform> fin_view: FinView;
// Per pixel: D(c), or LIT / DARK.
@group(0) @binding(11) var<storage, read_write> reference: array<u32>;
// Per pixel: visible samples (low 16 bits) and samples above the horizon (high).
@group(0) @binding(12) var<storage, read_write> tally: array<atomic<u32>>;
// Bevy's deferred G-buffer (`receiver_normal.wgsl`), zeros without one.
@group(0) @binding(13) var gbuffer: texture_2d<u32>;

// `reference` sentinels: no receiver here (visibility 1); a receiver no
// sample is above, or one in front of the near plane (visibility 0).
// `shadow_fins::coverage::MAX_REFERENCE_COUNT`: the count D(c) saturates here.
const MAX_REFERENCE: i32 = 127;
const LIT: u32 = 0xffffffffu;
const DARK: u32 = 0xfffffffeu;
// A point light's cube face leaves a receiver in another face's frustum alone.
const OTHER_FACE: u32 = 0xfffffffdu;

// `FinParams.flags.w`'s code (`render::projection_code`): 0 a disk's or a
// rectangle's perspective, 1 the sun's orthographic, 2 a point light's cube face.
fn perspective() -> bool {
    return params.info.w != 1u;
}

// A point light's cube face: the light is the sphere's outline seen from
// each receiver (radius in axis_n.w), and the face shades its frustum only.
fn sphere() -> bool {
    return params.info.w == 2u;
}

// The light as receiver p sees it (perspective lights): a disk of centre
// `center` and radius `radius` spanned by e1, e2 — the disk light itself, or
// a sphere's outline (`light::outline_seen_from`: the tangent circle,
// its axes glam's `any_orthonormal_pair` of the direction to p, as the CPU's).
struct LightAt {
    center: vec3<f32>,
    radius: f32,
    e1: vec3<f32>,
    e2: vec3<f32>,
}

fn light_at(p: vec3<f32>) -> LightAt {
    if (!sphere()) {
        return LightAt(vec3<f32>(0.0), params.light.x, vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0));
    }
    let r = params.axis_n.w;
    let d2 = max(dot(p, p), r * r * (1.0 + 1e-6) + 1e-30);
    let a = p / sqrt(d2);
    let s = select(-1.0, 1.0, a.z >= 0.0);
    let k = -1.0 / (s + a.z);
    let b = a.x * a.y * k;
    let e1 = vec3<f32>(1.0 + s * a.x * a.x * k, s * b, -s * a.x);
    let e2 = vec3<f32>(b, s + a.y * a.y * k, -a.y);
    return LightAt(p * (r * r / d2), sqrt(max(r * r * (1.0 - r * r / d2), 0.0)), e1, e2);
}



fn map_point(p: vec3<f32>) -> vec2<f32> {
    return select(p.xy, p.xy / p.z, perspective());
}

// The vector from receiver p towards light sample q (unit-disk coordinates).
fn sample_vector(p: vec3<f32>, q: vec2<f32>) -> vec3<f32> {
    if (perspective()) {
        let l = light_at(p);
        return l.center + (l.e1 * q.x + l.e2 * q.y) * l.radius - p;
    }
    return vec3<f32>(q * params.light.x, -1.0);
}

// The plane test w · u(q) as a line in q: (n.x, n.y, c).
fn line_of(w: vec3<f32>, p: vec3<f32>) -> vec3<f32> {
    if (perspective()) {
        let l = light_at(p);
        return vec3<f32>(dot(w, l.e1) * l.radius, dot(w, l.e2) * l.radius, dot(w, l.center - p));
    }
    return vec3<f32>(w.xy * params.light.x, -w.z);
}

fn positive(l: vec3<f32>, q: vec2<f32>) -> bool {
    return dot(l.xy, q) + l.z >= 0.0;
}

// `CoverageEdge::clipped`: the part with near ≤ z < far, as (a, b, ok).
struct Clipped {
    a: vec3<f32>,
    b: vec3<f32>,
    ok: bool,
}

fn clipped(e: Edge, near: f32, far_in: f32) -> Clipped {
    var a = e.a.xyz;
    var b = e.b.xyz;
    if (a.z > b.z) {
        let t = a;
        a = b;
        b = t;
    }
    let far = far_in * (1.0 - 1e-6) - 1e-30;
    if (!(b.z >= near && a.z < far)) {
        return Clipped(a, b, false);
    }
    let a0 = a;
    let b0 = b;
    if (a.z < near) {
        a = a0 + (b0 - a0) * ((near - a0.z) / (b0.z - a0.z));
    }
    if (b.z > far) {
        b = a0 + (b0 - a0) * ((far - a0.z) / (b0.z - a0.z));
    }
    return Clipped(a, b, true);
}

fn segment_distance(q: vec2<f32>, a: vec2<f32>, b: vec2<f32>) -> f32 {
    let ab = b - a;
    let len2 = dot(ab, ab);
    var t = 0.0;
    if (len2 > 0.0) {
        t = clamp(dot(q - a, ab) / len2, 0.0, 1.0);
    }
    return length(a + ab * t - q);
}

// `EdgeIndex::may_reach`: within the receiver's footprint bound (C4).
fn may_reach(e: Edge, p: vec3<f32>) -> bool {
    let z = min(e.a.z, e.b.z);
    if (!(z < p.z)) {
        return false;
    }
    var reach = params.light.x * (p.z - z);
    if (perspective()) {
        let zz = max(z, p.z * 1e-6);
        reach = params.light.x * ((p.z - zz) / zz) / p.z;
    }
    return !(segment_distance(map_point(p), e.segment.xy, e.segment.zw) > reach * (1.0 + 1e-4) + 1e-12);
}

fn faces(e: Edge) -> u32 {
    return u32(e.a.w);
}

// σ of an edge seen from plane (n, at): +1 per face whose third vertex is on
// the plane's positive side, −1 per face on the other.
fn face_sides(e: Edge, n: vec3<f32>, at: vec3<f32>) -> i32 {
    var sigma = select(-1, 1, dot(n, e.third_a.xyz - at) >= 0.0);
    if (faces(e) == 2u) {
        sigma += select(-1, 1, dot(n, e.third_b.xyz - at) >= 0.0);
    }
    return sigma;
}

// The depth lists: how many casters texel t's centre ray crosses before z
// (`DepthLists::count_before`).
fn count_before(t: vec2<u32>, z: f32) -> u32 {
    let base = (t.y * params.counts.x + t.x) * list_stride(params);
    let near_depths = params.counts.y;
    var n = 0u;
    for (var i = 0u; i < near_depths; i++) {
        if (bitcast<f32>(lists[base + i]) < z) {
            n += 1u;
        } else {
            break;
        }
    }
    if (n < near_depths) {
        return n;
    }
    var behind = 0u;
    for (var i = 0u; i < params.counts.z; i++) {
        let v = lists[base + near_depths + i];
        if (v != 0u && bitcast<f32>(v) >= z) {
            behind += 1u;
        } else {
            break;
        }
    }
    let total = lists[base + near_depths + params.counts.z];
    return total - min(behind, total);
}

fn cell_of(m: vec2<f32>) -> vec2<u32> {
    let c = (m - params.grid.xy) * params.grid.zw;
    if (!(c.x >= 0.0 && c.y >= 0.0 && u32(c.x) < params.info.x && u32(c.y) < params.info.y)) {
        return vec2<u32>(0u, 0u); // an empty range
    }
    let cell = u32(c.y) * params.info.x + u32(c.x);
    return vec2<u32>(cell_starts[cell], cell_starts[cell + 1u]);
}

fn vertex_hash(v: vec3<f32>) -> u32 {
    let b = bitcast<vec3<u32>>(v);
    var h = b.x * 0x9e3779b1u;
    h = (h ^ b.y) * 0x85ebca77u;
    h = (h ^ b.z) * 0xc2b2ae3du;
    return h ^ (h >> 15u);
}

// Whether the move from `start` to `stop` passes through face (a, b, c):
// (.x = 1 if it does, .y = 1 if it leaves the face's light side) and the
// face's order-free key (by a hash of its corners).
struct Crossing {
    crossed: bool,
    leaves: bool,
    key: vec2<u32>,
}

fn face_crossing(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, start: vec3<f32>, stop: vec3<f32>) -> Crossing {
    let none = Crossing(false, false, vec2<u32>(0u));
    let n = cross(b - a, c - a);
    let fa = dot(n, start - a);
    let fb = dot(n, stop - a);
    if ((fa >= 0.0) == (fb >= 0.0)) {
        return none;
    }
    let x = start + (stop - start) * (fa / (fa - fb));
    if (!(dot(n, cross(b - a, x - a)) >= 0.0 && dot(n, cross(c - b, x - b)) >= 0.0
        && dot(n, cross(a - c, x - c)) >= 0.0)) {
        return none;
    }
    let ha = vertex_hash(a);
    let hb = vertex_hash(b);
    let hc = vertex_hash(c);
    let light_side = select(-n.z, dot(n, -a), perspective());
    return Crossing(true, (fa >= 0.0) == (light_side >= 0.0), vec2<u32>(ha + hb + hc, ha ^ hb ^ hc));
}

// Faces already counted by `faces_passed` (a face is shared by its edges);
// at most 32, as the core's `MAX_SEEN_FACES`. Keys are a 64-bit hash of the
// corners (the core compares the corners' bits: a collision is the only way
// the two can differ).
struct Seen {
    keys: array<vec2<u32>, 32>,
    n: u32,
}

// ±1 for a crossing not seen before, and records it.
fn count_crossing(seen: ptr<function, Seen>, x: Crossing) -> i32 {
    if (!x.crossed) {
        return 0;
    }
    for (var s = 0u; s < (*seen).n; s++) {
        if (all((*seen).keys[s] == x.key)) {
            return 0;
        }
    }
    if ((*seen).n < 32u) {
        (*seen).keys[(*seen).n] = x.key;
        (*seen).n += 1u;
    }
    return select(-1, 1, x.leaves);
}

// `CoverageModel::faces_passed`: faces of the cell's edges the move from
// `start` to `stop` passes through, each once, ±1 as it leaves or enters the
// face's light side (faces in the core's order: an edge's first, then second).
fn faces_passed(range: vec2<u32>, start: vec3<f32>, stop: vec3<f32>) -> i32 {
    var seen: Seen;
    seen.n = 0u;
    var change = 0;
    for (var k = range.x; k < range.y; k++) {
        let e = edges[cell_items[k]];
        let a = e.a.xyz;
        let b = e.b.xyz;
        change += count_crossing(&seen, face_crossing(a, b, e.third_a.xyz, start, stop));
        if (faces(e) == 2u) {
            change += count_crossing(&seen, face_crossing(a, b, e.third_b.xyz, start, stop));
        }
    }
    return change;
}

fn at_depth(m: vec2<f32>, z: f32) -> vec3<f32> {
    return select(vec3<f32>(m, z), vec3<f32>(m * z, z), perspective());
}

// `CoverageModel::raster_reference_count`: D(c) at receiver p.
fn reference_count(p: vec3<f32>, normal: vec3<f32>, range: vec2<u32>) -> i32 {
    let m_p = map_point(p);
    let res = params.counts.x;
    let corner = floor((m_p - params.lists.xy) / params.lists.z - 0.5);
    var found = false;
    var texel = vec2<u32>(0u);
    var p_t = p;
    var best = 0.0;
    for (var k = 0u; k < 4u; k++) {
        let xy = corner + vec2<f32>(f32(k & 1u), f32(k >> 1u));
        if (!(xy.x >= 0.0 && xy.y >= 0.0 && xy.x < f32(res) && xy.y < f32(res))) {
            continue;
        }
        let t = vec2<u32>(xy);
        let candidate = at_depth(texel_center(params, t.x, t.y), p.z);
        let clearance = dot(normal, candidate - p);
        if (!found || clearance > best) {
            found = true;
            best = clearance;
            texel = t;
            p_t = candidate;
        }
    }
    if (!found) {
        return 0;
    }
    var count = i32(count_before(texel, p.z)) + faces_passed(range, p_t, p);
    let near = params.light.y;
    for (var k = range.x; k < range.y; k++) {
        let e = edges[cell_items[k]];
        let c = clipped(e, near, p.z);
        if (!c.ok) {
            continue;
        }
        let n = select(cross(c.b - c.a, vec3<f32>(0.0, 0.0, 1.0)), cross(c.a, c.b), perspective());
        let was = dot(n, p_t - c.a) >= 0.0;
        let now = dot(n, p - c.a) >= 0.0;
        if (was == now) {
            continue;
        }
        let m = select(cross(p - p_t, vec3<f32>(0.0, 0.0, 1.0)), cross(p_t, p), perspective());
        if ((dot(m, c.a - p_t) >= 0.0) == (dot(m, c.b - p_t) >= 0.0)) {
            continue;
        }
        let sigma = face_sides(e, n, c.a);
        count += select(-sigma, sigma, now);
    }
    return max(count, 0);
}

fn view_to_frame(p: vec3<f32>) -> vec3<f32> {
    return fin_view.column_x.xyz * p.x + fin_view.column_y.xyz * p.y + fin_view.column_z.xyz * p.z
        + fin_view.translation.xyz;
}

fn dir_to_frame(d: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(d, params.axis_u.xyz), dot(d, params.axis_v.xyz), dot(d, params.axis_n.xyz));
}

// One stage of a bit-sliced ripple add (`up`) or subtract: (plane, carry out).
fn ripple(plane: u32, carry: u32, up: bool) -> vec2<u32> {
    return vec2<u32>(plane ^ carry, select(~plane & carry, plane & carry, up));
}

// Adds `step` (±1, ±2) to the bit-sliced counters of the samples in `mask`:
// plane i holds bit i of every sample's count, modulo 256 (unrolled: see the
// header). D(c) ≤ MAX_REFERENCE and |Σ steps| stay below 256, so zero
// modulo 256 is zero (the core clamps D(c) alike).
fn add_masked(planes: ptr<function, array<u32, 8>>, mask: u32, step: i32) {
    let up = step > 0;
    var r = vec2<u32>(0u, mask);
    if (abs(step) == 1) {
        r = ripple((*planes)[0], r.y, up);
        (*planes)[0] = r.x;
    }
    r = ripple((*planes)[1], r.y, up);
    (*planes)[1] = r.x;
    r = ripple((*planes)[2], r.y, up);
    (*planes)[2] = r.x;
    r = ripple((*planes)[3], r.y, up);
    (*planes)[3] = r.x;
    r = ripple((*planes)[4], r.y, up);
    (*planes)[4] = r.x;
    r = ripple((*planes)[5], r.y, up);
    (*planes)[5] = r.x;
    r = ripple((*planes)[6], r.y, up);
    (*planes)[6] = r.x;
    r = ripple((*planes)[7], r.y, up);
    (*planes)[7] = r.x;
}

fn bits_of(hit: vec4<bool>) -> u32 {
    let b = select(vec4<u32>(0u), vec4<u32>(1u, 2u, 4u, 8u), hit);
    return b.x | b.y | b.z | b.w;
}

// Samples of quad `i` on the positive side of line l, as vec4 of bools.
fn quad_positive(l: vec3<f32>, i: u32) -> vec4<bool> {
    return l.x * samples[2u * i] + l.y * samples[2u * i + 1u] + l.z >= vec4<f32>(0.0);
}

// The samples of quad `i` an edge's wedge moves: past its line from the
// receiver's centre side, between the lines through its ends (`positive`
// per sample, four at a time).
fn quad_moved(i: u32, edge_line: vec3<f32>, r_side: bool, line_a: vec3<f32>, line_b: vec3<f32>) -> u32 {
    let past = quad_positive(edge_line, i) != vec4<bool>(r_side);
    return bits_of(past & (quad_positive(line_a, i) != quad_positive(line_b, i)));
}

fn word_moved(word: u32, edge_line: vec3<f32>, r_side: bool, line_a: vec3<f32>, line_b: vec3<f32>) -> u32 {
    let q = word * 8u;
    return quad_moved(q, edge_line, r_side, line_a, line_b)
        | (quad_moved(q + 1u, edge_line, r_side, line_a, line_b) << 4u)
        | (quad_moved(q + 2u, edge_line, r_side, line_a, line_b) << 8u)
        | (quad_moved(q + 3u, edge_line, r_side, line_a, line_b) << 12u)
        | (quad_moved(q + 4u, edge_line, r_side, line_a, line_b) << 16u)
        | (quad_moved(q + 5u, edge_line, r_side, line_a, line_b) << 20u)
        | (quad_moved(q + 6u, edge_line, r_side, line_a, line_b) << 24u)
        | (quad_moved(q + 7u, edge_line, r_side, line_a, line_b) << 28u);
}

// The samples of quad `i` above the receiver's horizon: normal · u(q) ≥ 0.
fn quad_above(i: u32, p: vec3<f32>, normal: vec3<f32>) -> u32 {
    let x = samples[2u * i];
    let y = samples[2u * i + 1u];
    if (perspective()) {
        // normal · (centre + r (x e1 + y e2) − p)
        let l = light_at(p);
        let d = (dot(normal, l.e1) * x + dot(normal, l.e2) * y) * l.radius + vec4<f32>(dot(normal, l.center - p));
        return bits_of(d >= vec4<f32>(0.0));
    }
    let r = params.light.x;
    let d = normal.x * x * r + normal.y * y * r - vec4<f32>(normal.z);
    return bits_of(d >= vec4<f32>(0.0));
}

// The samples of word `word` above the horizon (padding lanes never are).
fn word_above(word: u32, p: vec3<f32>, normal: vec3<f32>) -> u32 {
    let q = word * 8u;
    let bits = quad_above(q, p, normal) | (quad_above(q + 1u, p, normal) << 4u)
        | (quad_above(q + 2u, p, normal) << 8u) | (quad_above(q + 3u, p, normal) << 12u)
        | (quad_above(q + 4u, p, normal) << 16u) | (quad_above(q + 5u, p, normal) << 20u)
        | (quad_above(q + 6u, p, normal) << 24u) | (quad_above(q + 7u, p, normal) << 28u);
    let n = min(params.info.z, MAX_CHUNKS * CHUNK);
    let valid = n - min(n, word * CHUNK);
    return select((1u << valid) - 1u, 0xffffffffu, valid >= CHUNK) & bits;
}

fn sample_words() -> u32 {
    return (min(params.info.z, MAX_CHUNKS * CHUNK) + CHUNK - 1u) / CHUNK;
}

// The receiver a pixel shades, in the light frame, lifted off its surface.
struct Receiver {
    // 0: none (background, outside the viewport, nothing casts, inside a
    // sphere light); 1: in front of the near plane; 2: a receiver; 3: in
    // another cube face's frustum
    kind: u32,
    p: vec3<f32>,
    normal: vec3<f32>,
}

fn receiver_at(id: vec2<u32>) -> Receiver {
    var r = Receiver(0u, vec3<f32>(0.0), vec3<f32>(0.0));
    let pixel = vec2<i32>(id);
    let depth = textureLoad(depth_prepass, pixel, 0);
    let in_viewport = all(vec2<f32>(id) >= view.viewport.xy) && all(vec2<f32>(id) < view.viewport.xy + view.viewport.zw);
    if (depth <= 0.0 || !in_viewport) {
        return r;
    }
    let uv = (vec2<f32>(id) + 0.5 - view.viewport.xy) / view.viewport.zw;
    let in_view = view.view_from_clip * vec4<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, depth, 1.0);
    let position = view_to_frame(in_view.xyz / in_view.w);
    let gbuffer_texel = textureLoad(gbuffer, clamped_to(textureDimensions(gbuffer), pixel), 0);
    r.normal = dir_to_frame(receiver_normal(textureLoad(normal_prepass, pixel, 0), gbuffer_texel));
    // The core's lift (`surface_epsilon`), and at least the rasteriser's own
    // f32 error in world space, 2ε·(|camera| + |p_view|) (FinView's w is the
    // camera's part): far from the origin a receiver rebuilt from the depth
    // buffer can lie below the surface the depth lists hold exactly, and
    // would count itself as a caster.
    let raster_error = fin_view.translation.w + 2.0 * 1.1920929e-7 * length(in_view.xyz / in_view.w);
    // The unlifted receiver picks the face, as the fins' pass and the CPU do.
    if (sphere() && !in_face(position)) {
        r.kind = 3u;
        return r;
    }
    let eps = max(max(params.light.w * length(position), params.light.z), raster_error);
    r.p = position + r.normal * eps;
    // No caster at all (no depth-list work and no edge): lit, as the fins'
    // pass; so is a receiver inside a sphere light (nothing comes between).
    if ((params.counts.w == 0u && params.lists.w == 0.0) || (sphere() && dot(r.p, r.p) <= params.axis_n.w * params.axis_n.w)) {
        r.kind = 0u;
        return r;
    }
    r.kind = select(2u, 1u, perspective() && !(r.p.z > params.light.y));
    return r;
}

fn pixel_index(id: vec2<u32>) -> u32 {
    return id.y * textureDimensions(visibility).x + id.x;
}

@compute @workgroup_size(8, 8, 1)
fn coverage_reference(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = textureDimensions(visibility);
    if (id.x >= size.x || id.y >= size.y) {
        return;
    }
    let at = pixel_index(id.xy);
    atomicStore(&tally[at], 0u);
    let r = receiver_at(id.xy);
    if (r.kind == 3u) {
        reference[at] = OTHER_FACE;
        return;
    }
    if (r.kind != 2u) {
        reference[at] = select(DARK, LIT, r.kind == 0u);
        return;
    }
    var above = 0u;
    for (var w = 0u; w < sample_words(); w++) {
        above |= word_above(w, r.p, r.normal);
    }
    if (above == 0u) {
        reference[at] = DARK;
        return;
    }
    let range = cell_of(map_point(r.p));
    reference[at] = u32(min(reference_count(r.p, r.normal, range), MAX_REFERENCE));
}

@compute @workgroup_size(8, 8, 1)
fn coverage_samples(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = textureDimensions(visibility);
    let word = id.z;
    if (id.x >= size.x || id.y >= size.y || word >= sample_words()) {
        return;
    }
    let at = pixel_index(id.xy);
    let d_c = reference[at];
    if (d_c >= OTHER_FACE) {
        return;
    }
    let r = receiver_at(id.xy);
    let p = r.p;
    let above = word_above(word, p, r.normal);
    if (above == 0u) {
        return;
    }
    // Every sample starts at D(c): plane i holds bit i of the count.
    var planes: array<u32, 8>;
    for (var i = 0u; i < 8u; i++) {
        planes[i] = select(0u, 0xffffffffu, ((d_c >> i) & 1u) != 0u);
    }
    let range = cell_of(map_point(p));
    let u_r = sample_vector(p, vec2<f32>(0.0));
    let near = params.light.y;
    for (var k = range.x; k < range.y; k++) {
        let e = edges[cell_items[k]];
        if (!may_reach(e, p)) {
            continue;
        }
        let cl = clipped(e, near, p.z);
        if (!cl.ok) {
            continue;
        }
        let da = cl.a - p;
        let db = cl.b - p;
        let plane_n = cross(da, db);
        let sigma = face_sides(e, plane_n, p);
        if (sigma == 0) {
            continue;
        }
        let edge_line = line_of(plane_n, p);
        let r_side = positive(edge_line, vec2<f32>(0.0));
        let mask = word_moved(word, edge_line, r_side, line_of(cross(da, u_r), p), line_of(cross(db, u_r), p));
        if (mask != 0u) {
            add_masked(&planes, mask, select(sigma, -sigma, r_side));
        }
    }
    let any = planes[0] | planes[1] | planes[2] | planes[3] | planes[4] | planes[5] | planes[6] | planes[7];
    atomicAdd(&tally[at], countOneBits(~any & above) | (countOneBits(above) << 16u));
}

@compute @workgroup_size(8, 8, 1)
fn coverage_resolve(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = textureDimensions(visibility);
    if (id.x >= size.x || id.y >= size.y) {
        return;
    }
    let at = pixel_index(id.xy);
    let d_c = reference[at];
    if (d_c == OTHER_FACE) {
        return;
    }
    let t = atomicLoad(&tally[at]);
    var v = f32(t & 0xffffu) / f32(max(t >> 16u, 1u));
    if (d_c == LIT) {
        v = 1.0;
    } else if (d_c == DARK) {
        v = 0.0;
    }
    textureStore(visibility, vec2<i32>(id.xy), vec4<f32>(v, 0.0, 0.0, 1.0));
}
