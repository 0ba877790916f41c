// Coverage with occluder fusion on the GPU: the same rules as the core's
// `shadow_fins::coverage` through depth lists (`ReferenceCount::Raster`),
// function for function. One dispatch per camera and light
// (`coverage_lists.wgsl` fills the depth lists before, once per frame):
//
//  coverage_visibility  per pixel: the receiver from the prepasses, then
//                       walks over its cell's three lists
//                       (`EdgeIndex::gpu_lists`): the reference faces and
//                       edges correct D(c), the depth lists' count along a
//                       texel's ray, by those passed between that ray and
//                       the receiver's; the
//                       sample list adds each edge's Σ σ χ (C1) to every
//                       light sample at once, in bit-sliced counters, 8
//                       words of 32 samples. A sample is visible iff its sum
//                       equals −D(c) modulo 256, so D(c) need not come first.
//                       V = visible / above the horizon, into the visibility
//                       texture the fins also write.
//
// Why one pass: an edge's culling (footprint, clip, plane, σ) is most of a
// listed edge's cost, and most listed edges are culled; done once per pixel
// instead of once per 32-sample word and again for D(c), the walk costs a
// fraction (BENCHMARKS.md, issue 39). The per-word and per-face tests are
// unrolled by hand with literal word indices: llvmpipe ends a shader after
// 65535 loop iterations in all (a GPU's watchdog is similar), so the only
// loops are over the cell's lists and the few bounded ones beside them.
#import bevy_render::view::View
#import bevy_shadow_fins::coverage_types::{CoverageParams, Edge, Face, CHUNK, MAX_CHUNKS, list_stride, texel_center}
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
// Bevy's deferred G-buffer (`receiver_normal.wgsl`), zeros without one.
@group(0) @binding(11) var gbuffer: texture_2d<u32>;
// Each face of the edges once (`EdgeIndex::faces`): the reference faces' list indexes it.
@group(0) @binding(12) var<storage, read> listed_faces: array<Face>;

// `shadow_fins::coverage::MAX_REFERENCE_COUNT`: the count D(c) saturates here.
const MAX_REFERENCE: i32 = 127;

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

// The cell of map point m's three lists (`EdgeIndex::gpu_lists`), as
// [start, end) ranges into `cell_items`; empty outside the grid.
struct CellLists {
    samples: vec2<u32>,
    reference_edges: vec2<u32>,
    reference_faces: vec2<u32>,
}

fn cell_of(m: vec2<f32>) -> CellLists {
    let c = (m - params.grid.xy) * params.grid.zw;
    if (!(c.x >= 0.0 && c.y >= 0.0 && u32(c.x) < params.info.x && u32(c.y) < params.info.y)) {
        return CellLists(vec2<u32>(0u), vec2<u32>(0u), vec2<u32>(0u));
    }
    let cells = params.info.x * params.info.y;
    let cell = u32(c.y) * params.info.x + u32(c.x);
    let edges_at = cells + cell;
    let faces_at = 2u * cells + cell;
    return CellLists(vec2<u32>(cell_starts[cell], cell_starts[cell + 1u]),
        vec2<u32>(cell_starts[edges_at], cell_starts[edges_at + 1u]),
        vec2<u32>(cell_starts[faces_at], cell_starts[faces_at + 1u]));
}

// ±1 as the move from `start` to `stop` passes through face (a, b, c),
// leaving (+1) or entering (−1) its light side; 0 where it misses it
// (`CoverageModel::faces_passed`, for one face).
fn face_crossed(a: vec3<f32>, b: vec3<f32>, c: vec3<f32>, start: vec3<f32>, stop: vec3<f32>) -> i32 {
    let n = cross(b - a, c - a);
    let fa = dot(n, start - a);
    let fb = dot(n, stop - a);
    if ((fa >= 0.0) == (fb >= 0.0)) {
        return 0;
    }
    let x = start + (stop - start) * (fa / (fa - fb));
    if (!(dot(n, cross(b - a, x - a)) >= 0.0 && dot(n, cross(c - b, x - b)) >= 0.0
        && dot(n, cross(a - c, x - c)) >= 0.0)) {
        return 0;
    }
    let light_side = select(-n.z, dot(n, -a), perspective());
    return select(-1, 1, (fa >= 0.0) == (light_side >= 0.0));
}


fn at_depth(m: vec2<f32>, z: f32) -> vec3<f32> {
    return select(vec3<f32>(m, z), vec3<f32>(m * z, z), perspective());
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

// The samples of word `word` above the horizon (padding lanes never are,
// nor any lane of a word past the light's N samples).
fn word_above(word: u32, p: vec3<f32>, normal: vec3<f32>) -> u32 {
    if (word >= sample_words()) {
        return 0u;
    }
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

// `CoverageModel::raster_reference_count`'s edge term for one clipped edge
// `c` of `e`: ±σ when the move from the texel's ray point `p_t` to the
// receiver `p` crosses the edge's plane with the light's centre.
fn edge_crossed(e: Edge, c: Clipped, p_t: vec3<f32>, p: vec3<f32>) -> i32 {
    let n = select(cross(c.b - c.a, vec3<f32>(0.0, 0.0, 1.0)), cross(c.a, c.b), perspective());
    let was = dot(n, p_t - c.a) >= 0.0;
    let now = dot(n, p - c.a) >= 0.0;
    if (was == now) {
        return 0;
    }
    let m = select(cross(p - p_t, vec3<f32>(0.0, 0.0, 1.0)), cross(p_t, p), perspective());
    if ((dot(m, c.a - p_t) >= 0.0) == (dot(m, c.b - p_t) >= 0.0)) {
        return 0;
    }
    let sigma = face_sides(e, n, c.a);
    return select(-sigma, sigma, now);
}

// The depth-list texel whose centre ray stands for receiver p: of the four
// around it, the one most above p's surface (`raster_reference_count`), at
// p's depth.
struct ReferenceTexel {
    found: bool,
    texel: vec2<u32>,
    p_t: vec3<f32>,
}

fn reference_texel(p: vec3<f32>, normal: vec3<f32>) -> ReferenceTexel {
    let m_p = map_point(p);
    let res = params.counts.x;
    let corner = floor((m_p - params.lists.xy) / params.lists.z - 0.5);
    var r = ReferenceTexel(false, vec2<u32>(0u), p);
    var best = 0.0;
    for (var k = 0u; k < 4u; k++) {
        let xy = corner + vec2<f32>(f32(k & 1u), f32(k >> 1u));
        if (!(xy.x >= 0.0 && xy.y >= 0.0 && xy.x < f32(res) && xy.y < f32(res))) {
            continue;
        }
        let t = vec2<u32>(xy);
        let candidate = at_depth(texel_center(params, t.x, t.y), p.z);
        let clearance = dot(normal, candidate - p);
        if (!r.found || clearance > best) {
            r = ReferenceTexel(true, t, candidate);
            best = clearance;
        }
    }
    return r;
}

// Adds an edge's wedge to one word's counters, if any of its samples is
// above the horizon and moved.
fn add_wedge(planes: ptr<function, array<u32, 8>>, word: u32, above: u32, w: Wedge) {
    if (above == 0u) {
        return;
    }
    let mask = word_moved(word, w.edge_line, w.r_side, w.line_a, w.line_b);
    if (mask != 0u) {
        add_masked(planes, mask, w.step);
    }
}

// The lines that decide which samples an edge moves (see `quad_moved`) and by how much.
struct Wedge {
    edge_line: vec3<f32>,
    r_side: bool,
    line_a: vec3<f32>,
    line_b: vec3<f32>,
    step: i32,
}

// The samples of one word whose count is `wanted` modulo 256 (all eight
// planes equal its bits), among those above the horizon.
fn at_count(planes: ptr<function, array<u32, 8>>, wanted: u32, above: u32) -> u32 {
    var differs = 0u;
    differs |= (*planes)[0] ^ select(0u, 0xffffffffu, (wanted & 1u) != 0u);
    differs |= (*planes)[1] ^ select(0u, 0xffffffffu, (wanted & 2u) != 0u);
    differs |= (*planes)[2] ^ select(0u, 0xffffffffu, (wanted & 4u) != 0u);
    differs |= (*planes)[3] ^ select(0u, 0xffffffffu, (wanted & 8u) != 0u);
    differs |= (*planes)[4] ^ select(0u, 0xffffffffu, (wanted & 16u) != 0u);
    differs |= (*planes)[5] ^ select(0u, 0xffffffffu, (wanted & 32u) != 0u);
    differs |= (*planes)[6] ^ select(0u, 0xffffffffu, (wanted & 64u) != 0u);
    differs |= (*planes)[7] ^ select(0u, 0xffffffffu, (wanted & 128u) != 0u);
    return ~differs & above;
}

@compute @workgroup_size(8, 8, 1)
fn coverage_visibility(@builtin(global_invocation_id) id: vec3<u32>) {
    let size = textureDimensions(visibility);
    if (id.x >= size.x || id.y >= size.y) {
        return;
    }
    let r = receiver_at(id.xy);
    // Another cube face's receiver: that face's pass writes the pixel.
    if (r.kind == 3u) {
        return;
    }
    if (r.kind != 2u) {
        textureStore(visibility, vec2<i32>(id.xy), vec4<f32>(select(0.0, 1.0, r.kind == 0u), 0.0, 0.0, 1.0));
        return;
    }
    let p = r.p;
    // Per word, the samples above the horizon.
    let above0 = word_above(0u, p, r.normal);
    let above1 = word_above(1u, p, r.normal);
    let above2 = word_above(2u, p, r.normal);
    let above3 = word_above(3u, p, r.normal);
    let above4 = word_above(4u, p, r.normal);
    let above5 = word_above(5u, p, r.normal);
    let above6 = word_above(6u, p, r.normal);
    let above7 = word_above(7u, p, r.normal);
    if ((above0 | above1 | above2 | above3 | above4 | above5 | above6 | above7) == 0u) {
        textureStore(visibility, vec2<i32>(id.xy), vec4<f32>(0.0, 0.0, 0.0, 1.0));
        return;
    }
    let near = params.light.y;
    let lists = cell_of(map_point(p));
    // The reference count's walks (`EdgeIndex::reference_faces`, then
    // `reference_edges`): the faces and edges within the move's reach.
    // `passed`: D(c) − count_before, those passed from the texel's ray to p.
    let reference = reference_texel(p, r.normal);
    var passed = 0;
    if (reference.found) {
        for (var k = lists.reference_faces.x; k < lists.reference_faces.y; k++) {
            let f = listed_faces[cell_items[k]];
            passed += face_crossed(f.a.xyz, f.b.xyz, f.c.xyz, reference.p_t, p);
        }
        for (var k = lists.reference_edges.x; k < lists.reference_edges.y; k++) {
            let e = edges[cell_items[k]];
            let cl = clipped(e, near, p.z);
            if (cl.ok) {
                passed += edge_crossed(e, cl, reference.p_t, p);
            }
        }
    }
    // The sample walk: the edges that may be a silhouette within the
    // receiver's footprint (`EdgeIndex::cell`). Per word, Σ σ χ of each
    // sample modulo 256 in bit planes (plane i: bit i).
    var planes0: array<u32, 8>;
    var planes1: array<u32, 8>;
    var planes2: array<u32, 8>;
    var planes3: array<u32, 8>;
    var planes4: array<u32, 8>;
    var planes5: array<u32, 8>;
    var planes6: array<u32, 8>;
    var planes7: array<u32, 8>;
    let u_r = sample_vector(p, vec2<f32>(0.0));
    for (var k = lists.samples.x; k < lists.samples.y; k++) {
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
        let w = Wedge(edge_line, r_side, line_of(cross(da, u_r), p), line_of(cross(db, u_r), p), select(sigma, -sigma, r_side));
        add_wedge(&planes0, 0u, above0, w);
        add_wedge(&planes1, 1u, above1, w);
        add_wedge(&planes2, 2u, above2, w);
        add_wedge(&planes3, 3u, above3, w);
        add_wedge(&planes4, 4u, above4, w);
        add_wedge(&planes5, 5u, above5, w);
        add_wedge(&planes6, 6u, above6, w);
        add_wedge(&planes7, 7u, above7, w);
    }
    var d_c = 0;
    if (reference.found) {
        d_c = min(max(i32(count_before(reference.texel, p.z)) + passed, 0), MAX_REFERENCE);
    }
    // D(s) = D(c) + Σ σ χ = 0 ⟺ Σ σ χ ≡ −D(c) (mod 256): |Σ| and D(c) stay
    // below 128, as the counters' range assumes (`add_masked`).
    let wanted = u32(256 - d_c) & 255u;
    let visible = countOneBits(at_count(&planes0, wanted, above0)) + countOneBits(at_count(&planes1, wanted, above1))
        + countOneBits(at_count(&planes2, wanted, above2)) + countOneBits(at_count(&planes3, wanted, above3))
        + countOneBits(at_count(&planes4, wanted, above4)) + countOneBits(at_count(&planes5, wanted, above5))
        + countOneBits(at_count(&planes6, wanted, above6)) + countOneBits(at_count(&planes7, wanted, above7));
    let total = countOneBits(above0) + countOneBits(above1) + countOneBits(above2) + countOneBits(above3)
        + countOneBits(above4) + countOneBits(above5) + countOneBits(above6) + countOneBits(above7);
    textureStore(visibility, vec2<i32>(id.xy), vec4<f32>(f32(visible) / f32(max(total, 1u)), 0.0, 0.0, 1.0));
}
