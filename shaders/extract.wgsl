// Fin extraction and layer assignment on the GPU (Cai et al. §3.1 and §4.1),
// the same semantics as the core crate's `FinExtractor` (silhouette.rs,
// fins.rs, layers.rs), stage for stage:
//
//  0. reset, begin         counters; whether this update may extract only the
//     forget_footprints    moved instances (below); their old footprints into
//                          the dirty rectangle
//  1. transform_vertices   every vertex into the light frame; deepest depth → L0
//  2. classify_faces       facing test against the light in object space
//  3. join_patches         patches = connected light-facing regions: lock-free
//                          union-find over non-silhouette edges
//  4. flatten_patches      every face points at its patch_id's root
//  5. find_silhouettes     per-edge silhouette test, oriented edges appended
//  6. silhouette_args      indirect dispatch sizes for the silhouette passes
//  7. silhouette_vertices  histogram of edge depths over the sub-layers; per
//                          silhouette vertex: smooth end directions, fans,
//                          caps, junction sectors (one owner thread per vertex)
//  8. silhouette_quads     inner and outer quads of every silhouette edge
//  9. map_casters          light-facing faces clipped at the near plane, in map space
// 10. plan_layers          prefix sum of the histogram cut at the k/N
//                          quantiles; map region; the maps' parameters and
//                          indirect arguments
// 11. assign_*_layers      every fin and caster to its patch_id's layer
// 12. gather_redraw_*      on a partial redraw, the casters and fins that
//     redraw_args          reach the redrawn rectangle, and the maps'
//                          dispatch sizes for them
//
// Caster geometry (`geometry`) is uploaded once per mesh; only `instances`
// (object → light-frame transforms) change when something moves. A skinned
// or morphed instance has its own copy of its mesh's geometry, which
// `pose.wgsl` poses before these passes run: a new pose is a changed
// instance record, not new geometry.
//
// Alpha-masked casters (issue 16, item 2) are extracted here too, with the
// CPU's semantics (`silhouette.rs`, `cutout.rs`): an instance's mesh is then
// packed with the outline of its opaque region (`pack_outlined`: the
// outline's vertices after the mesh's, its edges after the mesh's). Patches
// join across the mesh's edges only (`EDGE_PATCH_ONLY`), silhouettes come
// from the outline's edges only (`EDGE_OUTLINE`), the mesh counts as open
// (light through a hole meets its back faces), and each of its map casters
// gets a cut-out record at its own index in `cutouts` — the UVs at its
// (clipped) corners, their depths, its mask — which the maps alpha-test.
//
// Partial redraw (issue 16, item 3: only what depends on a moved caster is
// redone). Every instance's footprint — the map-space bounds of the casters
// and fins it emitted — is kept in `history` from frame to frame. When the
// CPU lists the instances whose records changed (`H_DIRTY_COUNT`, at most
// `MAX_DIRTY`) and the maps' plan comes out as last frame's (the same
// `FinParams` but for the counts, the same layer planes, nothing past a
// capacity), only the texels under those instances' old and new footprints
// are cleared and redrawn, from the casters and fins that reach them:
// texel for texel what a full redraw writes there, and the rest of the maps
// is what it was. Otherwise (`H_DIRTY_COUNT` = `FULL`, the plan moved) the
// maps are redrawn whole.
//
// Incremental extraction (the same item, one step up): stages 1–9 first run
// over the listed instances only (`STAGE_ATTEMPT`: a thread's item comes from
// the dirty table, `item_of`), appending to last frame's silhouettes, fins
// and casters. Everything else last frame extracted is still valid when
// what depends on all instances came out the same: L0 (the deepest vertex),
// the silhouette depth range the histogram's sub-layers divide, and nothing
// past a capacity — each instance keeps its deepest vertex and silhouette
// depth range in `history`, and `decide` compares their union with last
// frame's. Then (`STAGE_ACCEPTED`) the moved instances' old records are
// retired (`retire_moved`: marked `RETIRED_LAYER`, their silhouettes taken
// out of the histogram) and stages 10–12 run over every record, as after a
// full extraction: the output is record for record a full extraction's, in
// another order, with retired records among them (the maps skip those).
// Otherwise (`STAGE_FULL`) stages 1–9 run again over every instance, from
// nothing. Retired records take room until a full extraction drops them.
#import bevy_shadow_fins::fin_types::{Caster, CasterCutout, Fin, cross2, fin_bounds, CONTROL_LIST_CASTERS, CONTROL_LIST_FINS, RETIRED_LAYER}

struct ExtractParams {
    // (instances, instance vertices, caster faces, caster edges)
    totals: vec4<u32>,
    // (sub-layers S, layers N, layer capacity, map resolution)
    layering: vec4<u32>,
    // (silhouette capacity, fin capacity, caster capacity, method 0 hard 1 outer-fins 2 single 3 multi)
    capacity: vec4<u32>,
    // (light size: disk radius R or sun tan θ, scene extent, deepest receiver
    // the CPU knows of besides the casters' vertices, projection: 0 a disk's
    // perspective frame, 1 the sun's orthographic one, 2 the sun's with L0
    // fixed to z by the CPU — a frame placed at its view window, where far
    // vertices outside the window are no receivers of it)
    light: vec4<f32>,
    // (refinement, falloff, overlap, generation)
    flags: vec4<u32>,
    origin: vec4<f32>,
    axis_u: vec4<f32>,
    axis_v: vec4<f32>,
    axis_n: vec4<f32>,
    // The maps' region lies within (min x, min y, max x, max y): a sun's maps
    // fitted to what the cameras see (`sun_fit.rs`); none when min > max.
    window: vec4<f32>,
    // The light's support function: (half extents a, b of a rectangle light
    // in the unit bounding circle, 1, 0); a disk's (1, 1, 0, 0); a sphere
    // light's cube face (1/stretch, window, 2, 0): `Aperture::Sphere`.
    aperture: vec4<f32>,
}

struct Instance {
    // Object → light frame: linear part (columns) and translation.
    linear0: vec4<f32>,
    linear1: vec4<f32>,
    linear2: vec4<f32>,
    translation: vec4<f32>,
    // Normals: cofactor matrix (columns), sign-corrected for mirroring transforms.
    normal0: vec4<f32>,
    normal1: vec4<f32>,
    normal2: vec4<f32>,
    // The light in object space as a homogeneous point for the facing test
    // n·c > d·w: the disk's centre (w = 1) or the sun's direction towards
    // the light (w = 0).
    light: vec4<f32>,
    // (geometry word offset, first vertex, first caster face, first caster edge)
    ids: vec4<u32>,
    // (flags: 1 casts, 2 closed mesh, 4 mirrors; vertices; caster faces; caster edges)
    info: vec4<u32>,
    // (its pose's hash: low, high; its cut-out: 0 solid, else 1 + where its
    // mask starts in the maps' `mask_words`; 0): the hash changes with a pose
    // posed on the GPU (`pose.wgsl` has posed its copy of the geometry
    // before this runs).
    pose: vec4<u32>,
}

struct Silhouette {
    a: vec4<f32>,
    b: vec4<f32>,
    normal_a: vec4<f32>,
    normal_b: vec4<f32>,
    // (instance, local vertex a, local vertex b, patch_id)
    ids: vec4<u32>,
    // (crease, unused, unused, unused)
    info: vec4<u32>,
    // Fin directions at a and at b; zero when degenerate. Two fields, not one
    // vec4: the two ends are written by the owner threads of two different
    // vertices, and a read-modify-write of a shared vec4 let one thread's store
    // undo the other's (the whole edge then lost both fins).
    dir_a: vec2<f32>,
    dir_b: vec2<f32>,
}

@group(0) @binding(0) var<uniform> params: ExtractParams;
@group(0) @binding(1) var<storage, read> instances: array<Instance>;
@group(0) @binding(2) var<storage, read> geometry: array<u32>;
@group(0) @binding(3) var<storage, read_write> control: array<atomic<u32>>;
@group(0) @binding(4) var<storage, read_write> state: array<atomic<u32>>;
// Per caster record with a cut-out (an alpha-masked instance's), at the
// record's own index: the maps read it there (`cutout.wgsl`).
@group(0) @binding(5) var<storage, read_write> cutouts: array<CasterCutout>;
@group(0) @binding(6) var<storage, read_write> silhouettes: array<Silhouette>;
@group(0) @binding(7) var<storage, read_write> fins: array<Fin>;
@group(0) @binding(8) var<storage, read_write> casters: array<Caster>;

// `control` layout (u32 words). Keep in sync with `render/extraction.rs`.
// The live records (what a full extraction emits; read back as what the
// frame wanted) ...
const C_SILHOUETTES: u32 = 0u;
const C_FINS: u32 = 1u;
const C_CASTERS: u32 = 2u;
const C_DEPTH_MIN: u32 = 3u;
const C_DEPTH_MAX: u32 = 4u;
const C_DEEPEST: u32 = 5u;
const C_REGION: u32 = 6u; // min x, min y (ordered-key minima), max x, max y (maxima)
const C_LAYERS_WANTED: u32 = 10u;
const C_GENERATION: u32 = 11u;
const C_LAYERS: u32 = 12u;
const C_PARTIAL: u32 = 13u; // bit 0: this update redraws the maps in part; bit 1: it extracted the moved instances only
const C_REDRAWN: u32 = 14u; // texels (all layers) this update cleared and redrew
const C_UNBOUNDED: u32 = 15u; // 1: a primitive with bounds not finite (it may reach any texel)
const C_PARAMS: u32 = 16u; // 36 words: the maps' `FinParams`
const C_ARGS_CLEAR: u32 = 56u;
const C_ARGS_CASTERS: u32 = 59u;
const C_ARGS_FINS: u32 = 62u;
const C_ARGS_SILHOUETTES: u32 = 65u;
const C_ARGS_FIN_THREADS: u32 = 68u;
const C_ARGS_CASTER_THREADS: u32 = 71u;
const C_PLANES: u32 = 74u; // count, then up to 31 planes
// 106, 107: CONTROL_LIST_CASTERS, CONTROL_LIST_FINS (fin_types.wgsl)
const C_STAGE: u32 = 108u; // STAGE_*
// ... and the records in the buffers, retired ones included (where the next goes).
const C_CURSORS: u32 = 109u; // silhouettes, fins, casters
// Stages 1–9's dispatch sizes: vertices, faces, edges, then instances or
// sub-layers, whichever are more (`reset_footprints`); 3 words each.
const C_ARGS_ITEMS: u32 = 112u;
const C_ARGS_RETIRE: u32 = 124u;
const C_HISTOGRAM: u32 = 128u;

const STAGE_FULL: u32 = 0u;
const STAGE_ATTEMPT: u32 = 1u;
const STAGE_ACCEPTED: u32 = 2u;

// After the histogram, `control` keeps what a partial redraw needs from
// frame to frame (`history`, words relative to C_HISTOGRAM + sub-layers);
// keep in sync with `render/extraction.rs`:
const H_PLAN: u32 = 0u; // last frame's FinParams words 0..32, then its planes (count + 31)
const H_DIRTY_COUNT: u32 = 64u; // written by the CPU: dirty instances listed, or FULL
const H_VALID: u32 = 65u; // 1 once a plan is kept
const H_INCREMENTAL: u32 = 66u; // written by the CPU: 1 when the listed instances may be extracted alone
const H_DIRTY_RECT: u32 = 68u; // union of the dirty footprints (ordered keys: min x, min y, max x, max y)
const H_REDRAW_AREA: u32 = 72u; // the redrawn texel centres' map-space bounds (f32 bits)
// Last frame's C_CURSORS (3), then its `control` words 0..6: live counts
// (3), depth range keys (2), deepest key.
const H_KEPT: u32 = 76u;
// This frame's union of the instances' depth range keys and deepest key
// (as `control` words 3..6 and `H_KEPT` + 6..9).
const H_UNION: u32 = 85u;
const H_DIRTY_ITEMS: u32 = 88u; // the listed instances' vertices, faces, edges
const H_EPOCH: u32 = 91u; // counts updates; an instance listed this update is marked with it
// The maps' header after their last redraw (tiles wanted, before, pool;
// `maps.wgsl`), copied here by the render world (`extraction::copy_tile_header`).
const H_TILES: u32 = 92u;
const H_INSTANCES: u32 = 96u; // INSTANCE_WORDS per instance, then MAX_DIRTY
                              // dirty entries, then the redraw lists
// Per instance: its footprint (ordered keys: min x, min y, max x, max y),
// deepest vertex key, silhouette depth range keys (min, max), the epoch it
// was last listed in.
const INSTANCE_WORDS: u32 = 8u;
const I_DEEPEST: u32 = 4u;
const I_DEPTH_MIN: u32 = 5u;
const I_DEPTH_MAX: u32 = 6u;
const I_LISTED: u32 = 7u;
// A dirty entry: (instance, its first vertex, face, edge among the listed instances').
const DIRTY_WORDS: u32 = 4u;
const FULL: u32 = 0xffffffffu;
const MAX_DIRTY: u32 = 256u;

// `state` per caster face: parent (union-find), flags (1 facing, 2 in the
// maps), and the patch_id's silhouette-depth sum (64-bit fixed point) and count
// at its root; then per caster edge its silhouette index; then per instance
// vertex its light-frame position (f32 bits).
const FACE_WORDS: u32 = 5u;
const VERTEX_WORDS: u32 = 3u;
const FACING: u32 = 1u;
const IN_MAPS: u32 = 2u;
const NONE: u32 = 0xffffffffu;
const FIXED_ONE: f32 = 4194304.0; // 2^22

const WORKGROUP: u32 = 64u;
const MAX_GROUPS_X: u32 = 65535u;

// Geometry blob header (relative word offsets), see `GpuMeshGeometry`.
const G_VERTICES: u32 = 0u;
const G_FACES_AT: u32 = 3u;
const G_VERTICES_AT: u32 = 4u;
const G_EDGES_AT: u32 = 5u;
const G_CSR_AT: u32 = 6u;
const G_NON_MANIFOLD_AT: u32 = 7u;
const G_FACE_UVS_AT: u32 = 10u;
const EDGE_BACK_FACE_MISSING: u32 = 0xffffffffu;
const EDGE_FORWARD0: u32 = 1u;
const EDGE_FORWARD1: u32 = 2u;
const EDGE_CREASE: u32 = 4u;
const EDGE_NON_MANIFOLD: u32 = 8u;
// An alpha-masked mesh's packing (`GpuMeshGeometry::pack_outlined`): its
// mesh edges join patches only, its outline's edges are the silhouette
// candidates and join none.
const EDGE_PATCH_ONLY: u32 = 16u;
const EDGE_OUTLINE: u32 = 32u;

fn thread_index(wg: vec3<u32>, lane: u32) -> u32 {
    return (wg.y * MAX_GROUPS_X + wg.x) * WORKGROUP + lane;
}

// Floats as u32 keys whose unsigned order is the float order (atomic min/max).
fn order_key(f: f32) -> u32 {
    let b = bitcast<u32>(f);
    return select(b | 0x80000000u, ~b, (b & 0x80000000u) != 0u);
}

fn order_value(k: u32) -> f32 {
    return bitcast<f32>(select(~k, k & 0x7fffffffu, (k & 0x80000000u) != 0u));
}

// By its bits (not `x == x`): WGSL lets a compiler assume floats are never NaN.
fn finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7fffffffu) < 0x7f800000u && abs(x) <= 3.0e38;
}

// The instance whose range (`which`: 1 vertices, 2 faces, 3 edges) holds item i:
// the last one whose first item is ≤ i.
fn instance_of(i: u32, which: u32) -> u32 {
    var lo = 0u;
    var hi = params.totals.x;
    while (hi - lo > 1u) {
        let mid = (lo + hi) / 2u;
        if (instances[mid].ids[which] <= i) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

fn g(inst: Instance, word: u32) -> u32 {
    return geometry[inst.ids.x + word];
}

fn gf(inst: Instance, word: u32) -> f32 {
    return bitcast<f32>(geometry[inst.ids.x + word]);
}

fn vertex_position(inst: Instance, v: u32) -> vec3<f32> {
    let at = g(inst, G_VERTICES_AT) + 6u * v;
    return vec3<f32>(gf(inst, at), gf(inst, at + 1u), gf(inst, at + 2u));
}

fn vertex_normal_in_frame(inst: Instance, v: u32) -> vec3<f32> {
    let at = g(inst, G_VERTICES_AT) + 6u * v + 3u;
    let n = vec3<f32>(gf(inst, at), gf(inst, at + 1u), gf(inst, at + 2u));
    return inst.normal0.xyz * n.x + inst.normal1.xyz * n.y + inst.normal2.xyz * n.z;
}

fn position_slot(vertex: u32) -> u32 {
    return FACE_WORDS * params.totals.z + params.totals.w + VERTEX_WORDS * vertex;
}

fn frame_position(inst: Instance, v: u32) -> vec3<f32> {
    let at = position_slot(inst.ids.y + v);
    return vec3<f32>(
        bitcast<f32>(atomicLoad(&state[at])),
        bitcast<f32>(atomicLoad(&state[at + 1u])),
        bitcast<f32>(atomicLoad(&state[at + 2u])),
    );
}

// L0: the deepest receiver, so that no receiver lies beyond the plane the fins
// are built for (every mesh's vertices, and the bounds of meshes drawn but not
// readable on the CPU).
fn reference_depth() -> f32 {
    if (params.light.w > 1.5) {
        return params.light.z;
    }
    let deepest = max(order_value(atomicLoad(&control[C_DEEPEST])), params.light.z);
    return select(params.light.y, deepest, deepest > 0.0);
}

fn orthographic() -> bool {
    return params.light.w > 0.5;
}

// `shadow_fins::oracle::near_depth`: a disk's maps start just in front of its
// centre; the sun's have no near plane (its frame's origin is in front of
// everything drawn), the most negative finite float standing in for −∞.
const NO_NEAR: f32 = -3.0e38;
fn near_depth() -> f32 {
    return select(reference_depth() * 1e-5, NO_NEAR, orthographic());
}

// `LightFrame::map` and `map_direction`: perspective from a disk's centre,
// orthographic for the sun.
fn map_point(p: vec3<f32>) -> vec2<f32> {
    return select(p.xy / p.z, p.xy, orthographic());
}

fn map_direction(p: vec3<f32>, d: vec3<f32>) -> vec2<f32> {
    if (orthographic()) {
        return d.xy;
    }
    return (d.xy - p.xy / p.z * d.z) / p.z;
}

// Penumbra half-width on the reference plane, map units (eq. 3): a disk's
// R(1/z − 1/L0) without the cancellation of two nearby reciprocals, the sun's
// tan θ (L0 − z) (`LightFrame::fin_world_width`).
fn fin_width(z: f32) -> f32 {
    let l0 = reference_depth();
    var w = params.light.x * ((l0 - z) / z) / l0;
    if (orthographic()) {
        w = params.light.x * (l0 - z);
    }
    return select(0.0, w, w > 0.0);
}

// The light's support function across unit map direction d at map point m
// (`Aperture::support_at`): 1 for a disk or the sun, a|d_x| + b|d_y| for a
// rectangle light in its bounding circle, √(1 + (d·m)²)/stretch for a
// sphere light's cube face; it scales the fins' widths.
fn support(d: vec2<f32>, m: vec2<f32>) -> f32 {
    if (params.aperture.z > 1.5) {
        let dm = dot(d, m);
        return sqrt(1.0 + dm * dm) * params.aperture.x;
    }
    if (params.aperture.z < 0.5) {
        return 1.0;
    }
    return params.aperture.x * abs(d.x) + params.aperture.y * abs(d.y);
}

// A sphere light's cube face: its maps cover |x|, |y| ≤ window·z.
fn cube_face() -> bool {
    return params.aperture.z > 1.5;
}

// `LightFrame::outside_face_window`: a cube face leaves out a segment with
// both ends beyond one plane of its window frustum, or both at or behind the
// light's plane (no blocker of its receivers lies there; such an edge's fins
// would be hundreds of map units wide).
fn outside_face_window(a: vec3<f32>, b: vec3<f32>) -> bool {
    if (!cube_face()) {
        return false;
    }
    let w = params.aperture.y;
    return (a.x > w * a.z && b.x > w * b.z) || (-a.x > w * a.z && -b.x > w * b.z)
        || (a.y > w * a.z && b.y > w * b.z) || (-a.y > w * a.z && -b.y > w * b.z)
        || (a.z <= 0.0 && b.z <= 0.0);
}

// The maps' projection code in `FinParams.flags.w`: 0 a disk's perspective,
// 1 the sun's orthographic, 2 a sphere light's cube face (perspective; its
// visibility pass shades only the receivers in the face's frustum).
fn projection_code() -> u32 {
    if (orthographic()) {
        return 1u;
    }
    return select(0u, 2u, cube_face());
}

// Unit vector, or zero when it has no direction (the core's `normalize_or(NAN)`).
fn direction(v: vec2<f32>) -> vec2<f32> {
    let l = length(v);
    if (!(l > 0.0) || !finite(l)) {
        return vec2<f32>(0.0);
    }
    return v / l;
}

fn valid(d: vec2<f32>) -> bool {
    return dot(d, d) > 0.0;
}

// Grows the footprint of `instance`, which emitted the primitive, by the
// primitive's bounds (the maps' region is their union: `reduce_footprints`).
fn grow_region(lo: vec2<f32>, hi: vec2<f32>, instance: u32) {
    if (!(finite(lo.x) && finite(lo.y) && finite(hi.x) && finite(hi.y))) {
        // No footprint holds it: this frame and the next redraw whole.
        atomicStore(&control[C_UNBOUNDED], 1u);
        return;
    }
    grow_keys(instance_word(instance, 0u), order_key(lo.x), order_key(lo.y), order_key(hi.x), order_key(hi.y));
}

// `history` word i's index in `control`.
fn h(i: u32) -> u32 {
    return C_HISTOGRAM + params.layering.x + i;
}

// `history` word of instance k's word `word` (INSTANCE_WORDS per instance).
fn instance_word(k: u32, word: u32) -> u32 {
    return H_INSTANCES + INSTANCE_WORDS * k + word;
}

// The i-th dirty entry's word `word` (0 its instance; 1, 2, 3 its first
// vertex, face, edge among the listed instances').
fn dirty_entry(i: u32, word: u32) -> u32 {
    return atomicLoad(&control[h(H_INSTANCES + INSTANCE_WORDS * params.totals.x + DIRTY_WORDS * i + word)]);
}

// A partial redraw's caster list (count, then indices), and its fin list.
fn list_casters() -> u32 {
    return h(H_INSTANCES + INSTANCE_WORDS * params.totals.x + DIRTY_WORDS * MAX_DIRTY);
}

fn list_fins() -> u32 {
    return list_casters() + 1u + params.capacity.z;
}

// Grows the bounds at `history[at..at + 4]` (ordered keys) by another's.
fn grow_keys(at: u32, lo_x: u32, lo_y: u32, hi_x: u32, hi_y: u32) {
    atomicMin(&control[h(at)], lo_x);
    atomicMin(&control[h(at + 1u)], lo_y);
    atomicMax(&control[h(at + 2u)], hi_x);
    atomicMax(&control[h(at + 3u)], hi_y);
}

// No footprint, no vertex, no silhouette: what an instance starts from.
fn clear_instance(k: u32) {
    let at = instance_word(k, 0u);
    clear_keys(at);
    atomicStore(&control[h(at + I_DEEPEST)], 0u);
    atomicStore(&control[h(at + I_DEPTH_MIN)], 0xffffffffu);
    atomicStore(&control[h(at + I_DEPTH_MAX)], 0u);
}

fn clear_keys(at: u32) {
    atomicStore(&control[h(at)], 0xffffffffu);
    atomicStore(&control[h(at + 1u)], 0xffffffffu);
    atomicStore(&control[h(at + 2u)], 0u);
    atomicStore(&control[h(at + 3u)], 0u);
}

fn dirty_count() -> u32 {
    let n = atomicLoad(&control[h(H_DIRTY_COUNT)]);
    return select(min(n, MAX_DIRTY), 0u, n == FULL);
}

// The i-th dirty instance.
fn dirty_instance(i: u32) -> u32 {
    return dirty_entry(i, 0u);
}

fn grow_dirty_rect(instance: u32) {
    let at = instance_word(instance, 0u);
    grow_keys(
        H_DIRTY_RECT,
        atomicLoad(&control[h(at)]),
        atomicLoad(&control[h(at + 1u)]),
        atomicLoad(&control[h(at + 2u)]),
        atomicLoad(&control[h(at + 3u)]),
    );
}

fn stage() -> u32 {
    return atomicLoad(&control[C_STAGE]);
}

// Instance k was listed (it moved) this update.
fn listed(k: u32) -> bool {
    return atomicLoad(&control[h(instance_word(k, I_LISTED))]) == atomicLoad(&control[h(H_EPOCH)]);
}

// Thread t's item in range `which` (1 vertices, 2 faces, 3 edges) and its
// instance: every instance's items on a full extraction, the listed
// instances' while the update extracts those only; NONE past the last.
fn item_of(t: u32, which: u32) -> vec2<u32> {
    if (stage() == STAGE_FULL) {
        if (t >= params.totals[which]) {
            return vec2<u32>(NONE);
        }
        return vec2<u32>(t, instance_of(t, which));
    }
    if (t >= atomicLoad(&control[h(H_DIRTY_ITEMS + which - 1u)])) {
        return vec2<u32>(NONE);
    }
    // The last entry whose first item is ≤ t (entries with no item share
    // the next one's first item, which the search passes over).
    var lo = 0u;
    var hi = dirty_count();
    while (hi - lo > 1u) {
        let mid = (lo + hi) / 2u;
        if (dirty_entry(mid, which) <= t) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let k = dirty_entry(lo, 0u);
    return vec2<u32>(instances[k].ids[which] + t - dirty_entry(lo, which), k);
}

// Appends to a list: its live count (what a full extraction emits) and its
// cursor (live and retired records) both grow; returns the record's index.
fn append(list: u32) -> u32 {
    atomicAdd(&control[list], 1u);
    return atomicAdd(&control[C_CURSORS + list], 1u);
}

// The records in a list (`C_SILHOUETTES`, `C_FINS`, `C_CASTERS`), retired
// ones included, within its capacity.
fn records(list: u32) -> u32 {
    return min(atomicLoad(&control[C_CURSORS + list]), params.capacity[list]);
}

// ---------------------------------------------------------------- 0. reset

@compute @workgroup_size(64, 1, 1)
fn reset(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let i = thread_index(wg, lane);
    if (i < C_HISTOGRAM) {
        var value = 0u;
        if (i == C_DEPTH_MIN || i == C_REGION || i == C_REGION + 1u) {
            value = 0xffffffffu;
        }
        atomicStore(&control[i], value);
        if (i == 0u) {
            clear_keys(H_DIRTY_RECT);
        }
    }
    // The histogram stays: an update that extracts the listed instances
    // alone goes on from it; a full one clears it (`reset_footprints`).
}

// Last frame's extraction is there whole (`H_VALID`) and the CPU listed what
// moved since (the same light, settings, geometry and buffers), and lets
// the listed instances be extracted alone (`FinIncrementalExtraction`).
fn may_extract_listed() -> bool {
    return atomicLoad(&control[h(H_DIRTY_COUNT)]) != FULL && atomicLoad(&control[h(H_VALID)]) == 1u
        && atomicLoad(&control[h(H_INCREMENTAL)]) == 1u;
}

// Whether this update tries the listed instances only; if so, last frame's
// counts, cursors and depths come back, and stages 1–9 run over the listed
// instances' items.
@compute @workgroup_size(1, 1, 1)
fn begin() {
    if (atomicAdd(&control[h(H_EPOCH)], 1u) == 0xffffffffu) {
        atomicStore(&control[h(H_EPOCH)], 1u);
    }
    atomicStore(&control[h(H_UNION)], 0xffffffffu);
    atomicStore(&control[h(H_UNION + 1u)], 0u);
    atomicStore(&control[h(H_UNION + 2u)], 0u);
    if (!may_extract_listed()) {
        atomicStore(&control[C_STAGE], STAGE_FULL);
        return;
    }
    atomicStore(&control[C_STAGE], STAGE_ATTEMPT);
    for (var i = 0u; i < 3u; i++) {
        atomicStore(&control[C_CURSORS + i], atomicLoad(&control[h(H_KEPT + i)]));
    }
    for (var i = 0u; i <= C_DEEPEST; i++) {
        atomicStore(&control[i], atomicLoad(&control[h(H_KEPT + 3u + i)]));
    }
    let n = dirty_count();
    var items = vec3<u32>(0u);
    if (n > 0u) {
        let k = dirty_entry(n - 1u, 0u);
        items = vec3<u32>(dirty_entry(n - 1u, 1u), dirty_entry(n - 1u, 2u), dirty_entry(n - 1u, 3u)) + instances[k].info.yzw;
    }
    for (var i = 0u; i < 3u; i++) {
        atomicStore(&control[h(H_DIRTY_ITEMS + i)], items[i]);
        write_args(C_ARGS_ITEMS + 3u * i, items[i], WORKGROUP);
    }
    write_args(C_ARGS_ITEMS + 9u, 0u, WORKGROUP);
}

// Before anything is emitted: the dirty instances' old footprints go into
// the dirty rectangle (what they covered must be redrawn without them,
// however they are extracted) and, when the listed instances are extracted
// alone, they start anew, marked as listed in this update.
@compute @workgroup_size(64, 1, 1)
fn forget_footprints(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let i = thread_index(wg, lane);
    if (i < dirty_count()) {
        let instance = dirty_instance(i);
        if (instance < params.totals.x) {
            grow_dirty_rect(instance);
            if (stage() == STAGE_ATTEMPT) {
                clear_instance(instance);
                atomicStore(&control[h(instance_word(instance, I_LISTED))], atomicLoad(&control[h(H_EPOCH)]));
            }
        }
    }
}

// A full extraction: every instance starts anew (each emits again), listed
// in no update (the epoch is never 0; a word left from another layout of
// `control` must not pass for this update's mark), and the histogram empty.
@compute @workgroup_size(64, 1, 1)
fn reset_footprints(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let i = thread_index(wg, lane);
    if (i < params.totals.x) {
        clear_instance(i);
        atomicStore(&control[h(instance_word(i, I_LISTED))], 0u);
    }
    if (i < params.layering.x) {
        atomicStore(&control[C_HISTOGRAM + i], 0u);
    }
}

// The union of every instance's deepest vertex and silhouette depth range,
// kept and listed alike: what `decide` compares with last frame's.
@compute @workgroup_size(64, 1, 1)
fn reduce_instances(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let i = thread_index(wg, lane);
    if (i < params.totals.x && stage() == STAGE_ATTEMPT) {
        atomicMin(&control[h(H_UNION)], atomicLoad(&control[h(instance_word(i, I_DEPTH_MIN))]));
        atomicMax(&control[h(H_UNION + 1u)], atomicLoad(&control[h(instance_word(i, I_DEPTH_MAX))]));
        atomicMax(&control[h(H_UNION + 2u)], atomicLoad(&control[h(instance_word(i, I_DEEPEST))]));
    }
}

// Keeps the listed instances' extraction when L0, the silhouette depth range
// and the capacities allow (see the top of this file); else starts a full
// one: stages 1–9 again, over every instance, from nothing.
@compute @workgroup_size(1, 1, 1)
fn decide() {
    if (stage() == STAGE_ATTEMPT) {
        // Every primitive bounded, each list within its capacity, and the
        // instances' silhouette depth range and deepest vertex last frame's.
        var keep = atomicLoad(&control[C_UNBOUNDED]) == 0u;
        var most = 0u;
        for (var i = 0u; i < 3u; i++) {
            keep = keep && atomicLoad(&control[C_CURSORS + i]) <= params.capacity[i]
                && atomicLoad(&control[h(H_UNION + i)]) == atomicLoad(&control[h(H_KEPT + 6u + i)]);
            most = max(most, atomicLoad(&control[h(H_KEPT + i)]));
        }
        if (keep) {
            atomicStore(&control[C_STAGE], STAGE_ACCEPTED);
            for (var i = 0u; i < 4u; i++) {
                write_args(C_ARGS_ITEMS + 3u * i, 0u, WORKGROUP);
            }
            write_args(C_ARGS_RETIRE, most, WORKGROUP);
            return;
        }
    }
    atomicStore(&control[C_STAGE], STAGE_FULL);
    for (var i = 0u; i < 3u; i++) {
        atomicStore(&control[i], 0u);
        atomicStore(&control[C_CURSORS + i], 0u);
    }
    atomicStore(&control[C_DEPTH_MIN], 0xffffffffu);
    atomicStore(&control[C_DEPTH_MAX], 0u);
    atomicStore(&control[C_DEEPEST], 0u);
    atomicStore(&control[C_UNBOUNDED], 0u);
    // `reset_footprints` clears every instance and the histogram.
    for (var i = 0u; i < 3u; i++) {
        write_args(C_ARGS_ITEMS + 3u * i, params.totals[i + 1u], WORKGROUP);
    }
    write_args(C_ARGS_ITEMS + 9u, max(params.totals.x, params.layering.x), WORKGROUP);
    write_args(C_ARGS_RETIRE, 0u, WORKGROUP);
}

// The histogram bin of a silhouette edge's mid depth (§4.1's sub-layers).
fn histogram_bin(mid: f32) -> u32 {
    let lo = order_value(atomicLoad(&control[C_DEPTH_MIN]));
    let hi = order_value(atomicLoad(&control[C_DEPTH_MAX]));
    if (!(hi > lo)) {
        return 0u;
    }
    let step = (hi - lo) / f32(params.layering.x);
    return min(u32(max((mid - lo) / step, 0.0)), params.layering.x - 1u);
}

// The listed instances' records of last frame (they emitted anew): retired,
// their silhouettes out of the histogram, out of the live counts.
@compute @workgroup_size(64, 1, 1)
fn retire_moved(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let i = thread_index(wg, lane);
    if (i < atomicLoad(&control[h(H_KEPT)])) {
        let k = silhouettes[i].ids.x;
        if (k != NONE && listed(k)) {
            let mid = 0.5 * (silhouettes[i].a.z + silhouettes[i].b.z);
            atomicSub(&control[C_HISTOGRAM + histogram_bin(mid)], 1u);
            silhouettes[i].ids.x = NONE;
            atomicSub(&control[C_SILHOUETTES], 1u);
        }
    }
    if (i < atomicLoad(&control[h(H_KEPT + 1u)])) {
        if (fins[i].header.z != RETIRED_LAYER && listed(instance_of(fins[i].header.w, 2u))) {
            fins[i].header.z = RETIRED_LAYER;
            atomicSub(&control[C_FINS], 1u);
        }
    }
    if (i < atomicLoad(&control[h(H_KEPT + 2u)])) {
        if (casters[i].layer != RETIRED_LAYER && listed(instance_of(casters[i].patch_id, 2u))) {
            casters[i].layer = RETIRED_LAYER;
            atomicSub(&control[C_CASTERS], 1u);
        }
    }
}

// The maps' region: the union of every instance's footprint.
@compute @workgroup_size(64, 1, 1)
fn reduce_footprints(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let i = thread_index(wg, lane);
    if (i < params.totals.x) {
        let at = h(instance_word(i, 0u));
        atomicMin(&control[C_REGION], atomicLoad(&control[at]));
        atomicMin(&control[C_REGION + 1u], atomicLoad(&control[at + 1u]));
        atomicMax(&control[C_REGION + 2u], atomicLoad(&control[at + 2u]));
        atomicMax(&control[C_REGION + 3u], atomicLoad(&control[at + 3u]));
    }
}

// ---------------------------------------------------------------- 1. vertices

@compute @workgroup_size(64, 1, 1)
fn transform_vertices(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let item = item_of(thread_index(wg, lane), 1u);
    let i = item.x;
    if (i == NONE) {
        return;
    }
    let inst = instances[item.y];
    let p = vertex_position(inst, i - inst.ids.y);
    let q = inst.linear0.xyz * p.x + inst.linear1.xyz * p.y + inst.linear2.xyz * p.z + inst.translation.xyz;
    let at = position_slot(i);
    atomicStore(&state[at], bitcast<u32>(q.x));
    atomicStore(&state[at + 1u], bitcast<u32>(q.y));
    atomicStore(&state[at + 2u], bitcast<u32>(q.z));
    // L0 is the deepest receiver; every mesh receives.
    atomicMax(&control[C_DEEPEST], order_key(q.z));
    atomicMax(&control[h(instance_word(item.y, I_DEEPEST))], order_key(q.z));
}

// ---------------------------------------------------------------- 2. facing

@compute @workgroup_size(64, 1, 1)
fn classify_faces(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let item = item_of(thread_index(wg, lane), 2u);
    let i = item.x;
    if (i == NONE) {
        return;
    }
    let inst = instances[item.y];
    let at = g(inst, G_FACES_AT) + 7u * (i - inst.ids.z);
    let n = vec3<f32>(gf(inst, at + 3u), gf(inst, at + 4u), gf(inst, at + 5u));
    let facing = (dot(n, inst.light.xyz) > gf(inst, at + 6u) * inst.light.w) != ((inst.info.x & 4u) != 0u);
    // Back faces of closed meshes stay out of the maps.
    let in_maps = facing || (inst.info.x & 2u) == 0u;
    let s = FACE_WORDS * i;
    atomicStore(&state[s], select(NONE, i, in_maps));
    atomicStore(&state[s + 1u], select(0u, FACING, facing) | select(0u, IN_MAPS, in_maps));
    atomicStore(&state[s + 2u], 0u);
    atomicStore(&state[s + 3u], 0u);
    atomicStore(&state[s + 4u], 0u);
}

// ---------------------------------------------------------------- 3./4. patches

// The root of x's patch, halving the path on the way (each visited face is
// pointed at its grandparent): the trees stay shallow however the joins
// came, so the walk is short. Safe lock-free: a parent is never larger than
// its child (`join`) and a root's word is never touched, so the
// grandparent read is a smaller face of the same tree (no cycle, no set
// changed, roots unchanged), and a failed exchange only skips a step. With
// parents ever smaller a walk takes at most as many steps as faces, and
// halving keeps it far shorter; the guard is a GPU watchdog's backstop.
fn find_root(x: u32) -> u32 {
    var r = x;
    for (var guard = 0u; guard < 1000000u; guard++) {
        let p = atomicLoad(&state[FACE_WORDS * r]);
        if (p == r || p == NONE) {
            break;
        }
        let grandparent = atomicLoad(&state[FACE_WORDS * p]);
        if (grandparent == p || grandparent == NONE) {
            r = p;
            break;
        }
        _ = atomicCompareExchangeWeak(&state[FACE_WORDS * r], p, grandparent);
        r = grandparent;
    }
    return r;
}

// Hooks the larger root under the smaller one (so no cycle can form).
fn join(a: u32, b: u32) {
    var ra = a;
    var rb = b;
    for (var guard = 0u; guard < 1000000u; guard++) {
        ra = find_root(ra);
        rb = find_root(rb);
        if (ra == rb) {
            return;
        }
        if (ra < rb) {
            let t = ra;
            ra = rb;
            rb = t;
        }
        if (atomicCompareExchangeWeak(&state[FACE_WORDS * ra], ra, rb).exchanged) {
            return;
        }
    }
}

fn edge_at(inst: Instance, e: u32) -> u32 {
    return g(inst, G_EDGES_AT) + 5u * e;
}

@compute @workgroup_size(64, 1, 1)
fn join_patches(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let item = item_of(thread_index(wg, lane), 3u);
    let i = item.x;
    if (i == NONE) {
        return;
    }
    let inst = instances[item.y];
    let at = edge_at(inst, i - inst.ids.w);
    let f1 = g(inst, at + 3u);
    if ((g(inst, at + 4u) & (EDGE_NON_MANIFOLD | EDGE_OUTLINE)) != 0u || f1 == EDGE_BACK_FACE_MISSING) {
        return;
    }
    let a = inst.ids.z + g(inst, at + 2u);
    let b = inst.ids.z + f1;
    let sa = atomicLoad(&state[FACE_WORDS * a + 1u]);
    let sb = atomicLoad(&state[FACE_WORDS * b + 1u]);
    if ((sa & IN_MAPS) != 0u && (sb & IN_MAPS) != 0u && (sa & FACING) == (sb & FACING)) {
        join(a, b);
    }
}

@compute @workgroup_size(64, 1, 1)
fn flatten_patches(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let i = item_of(thread_index(wg, lane), 2u).x;
    if (i == NONE || atomicLoad(&state[FACE_WORDS * i]) == NONE) {
        return;
    }
    atomicStore(&state[FACE_WORDS * i], find_root(i));
}

// ---------------------------------------------------------------- 5. silhouettes

fn facing_face(f: u32) -> bool {
    return (atomicLoad(&state[FACE_WORDS * f + 1u]) & FACING) != 0u;
}

fn in_maps_face(f: u32) -> bool {
    return (atomicLoad(&state[FACE_WORDS * f + 1u]) & IN_MAPS) != 0u;
}

fn edge_silhouette_slot(edge: u32) -> u32 {
    return FACE_WORDS * params.totals.z + edge;
}

fn emit_silhouette(k: u32, inst: Instance, edge: u32, v0: u32, v1: u32, forward: bool, face: u32, crease: bool) {
    let va = select(v1, v0, forward);
    let vb = select(v0, v1, forward);
    let a = frame_position(inst, va);
    let b = frame_position(inst, vb);
    if (outside_face_window(a, b)) {
        return;
    }
    let patch_id = atomicLoad(&state[FACE_WORDS * (inst.ids.z + face)]);
    let index = append(C_SILHOUETTES);
    if (index >= params.capacity.x) {
        atomicStore(&state[edge_silhouette_slot(edge)], NONE);
        return;
    }
    silhouettes[index] = Silhouette(
        vec4<f32>(a, 0.0),
        vec4<f32>(b, 0.0),
        vec4<f32>(vertex_normal_in_frame(inst, va), 0.0),
        vec4<f32>(vertex_normal_in_frame(inst, vb), 0.0),
        vec4<u32>(k, va, vb, patch_id),
        vec4<u32>(select(0u, 1u, crease), 0u, 0u, 0u),
        vec2<f32>(0.0),
        vec2<f32>(0.0),
    );
    atomicStore(&state[edge_silhouette_slot(edge)], index);
    let mid = 0.5 * (a.z + b.z);
    atomicMin(&control[C_DEPTH_MIN], order_key(mid));
    atomicMax(&control[C_DEPTH_MAX], order_key(mid));
    atomicMin(&control[h(instance_word(k, I_DEPTH_MIN))], order_key(mid));
    atomicMax(&control[h(instance_word(k, I_DEPTH_MAX))], order_key(mid));
    // The patch_id's mean silhouette depth picks its layer: sum mid/L0 + 1 in
    // fixed point (64 bits: low word with carry into the high word).
    let q = u32(clamp(mid / reference_depth() + 1.0, 0.0, 2.0) * FIXED_ONE);
    let old = atomicAdd(&state[FACE_WORDS * patch_id + 2u], q);
    if (old + q < old) {
        atomicAdd(&state[FACE_WORDS * patch_id + 3u], 1u);
    }
    atomicAdd(&state[FACE_WORDS * patch_id + 4u], 1u);
}

@compute @workgroup_size(64, 1, 1)
fn find_silhouettes(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let item = item_of(thread_index(wg, lane), 3u);
    let i = item.x;
    if (i == NONE) {
        return;
    }
    let k = item.y;
    let inst = instances[k];
    let at = edge_at(inst, i - inst.ids.w);
    let v0 = g(inst, at);
    let v1 = g(inst, at + 1u);
    let flags = g(inst, at + 4u);
    atomicStore(&state[edge_silhouette_slot(i)], NONE);
    if ((flags & EDGE_PATCH_ONLY) != 0u) {
        return;
    }
    if ((flags & EDGE_NON_MANIFOLD) != 0u) {
        // Three or more faces: a silhouette when they disagree; the first
        // light-facing face orients it.
        let list = g(inst, G_NON_MANIFOLD_AT) + g(inst, at + 2u);
        let count = g(inst, at + 3u);
        var first = NONE;
        var any_back = false;
        for (var j = 0u; j < count; j++) {
            let entry = g(inst, list + j);
            let face = entry & 0x7fffffffu;
            if (facing_face(inst.ids.z + face)) {
                if (first == NONE) {
                    first = entry;
                }
            } else {
                any_back = true;
            }
        }
        if (first != NONE && any_back) {
            emit_silhouette(k, inst, i, v0, v1, (first >> 31u) != 0u, first & 0x7fffffffu, true);
        }
        return;
    }
    let f0 = g(inst, at + 2u);
    let f1 = g(inst, at + 3u);
    let facing0 = facing_face(inst.ids.z + f0);
    if (f1 == EDGE_BACK_FACE_MISSING) {
        // A boundary outlines its face's side towards the light: the face's
        // own, or an open mesh's back face's (in the maps too).
        let forward = (flags & EDGE_FORWARD0) != 0u;
        if (facing0) {
            emit_silhouette(k, inst, i, v0, v1, forward, f0, true);
        } else if (in_maps_face(inst.ids.z + f0)) {
            emit_silhouette(k, inst, i, v0, v1, !forward, f0, true);
        }
        return;
    }
    let facing1 = facing_face(inst.ids.z + f1);
    if (facing0 != facing1) {
        let crease = (flags & EDGE_CREASE) != 0u;
        if (facing0) {
            emit_silhouette(k, inst, i, v0, v1, (flags & EDGE_FORWARD0) != 0u, f0, crease);
        } else {
            emit_silhouette(k, inst, i, v0, v1, (flags & EDGE_FORWARD1) != 0u, f1, crease);
        }
    }
}

// Workgroups (x, y) for `n` items at `per_group` items a group.
fn write_args(at: u32, n: u32, per_group: u32) {
    let groups = (n + per_group - 1u) / per_group;
    let x = min(groups, MAX_GROUPS_X);
    let y = select(0u, (groups + MAX_GROUPS_X - 1u) / MAX_GROUPS_X, groups > 0u);
    atomicStore(&control[at], x);
    atomicStore(&control[at + 1u], y);
    atomicStore(&control[at + 2u], select(0u, 1u, groups > 0u));
}

// The first silhouette this stage found: past last frame's while the
// listed instances are extracted alone.
fn first_silhouette() -> u32 {
    return select(0u, atomicLoad(&control[h(H_KEPT)]), stage() == STAGE_ATTEMPT);
}

@compute @workgroup_size(1, 1, 1)
fn silhouette_args() {
    let n = select(records(C_SILHOUETTES) - min(first_silhouette(), records(C_SILHOUETTES)), 0u, stage() == STAGE_ACCEPTED);
    write_args(C_ARGS_SILHOUETTES, n, WORKGROUP);
}

// ---------------------------------------------------------------- 7. vertices of the silhouette

fn method_has_fins() -> bool {
    return params.capacity.w != 0u;
}

fn method_has_inner_fins() -> bool {
    return params.capacity.w >= 2u;
}

// Outer side 1, inner side 0, as in `maps.wgsl`.
fn emit_fin(kind: u32, outer: bool, patch_id: u32, instance: u32, data: array<f32, 12>, lo: vec2<f32>, hi: vec2<f32>) {
    if (!method_has_fins() || (!outer && !method_has_inner_fins())) {
        return;
    }
    let index = append(C_FINS);
    if (index < params.capacity.y) {
        // Its layer (z) is assigned once the plan is known; its patch (w) stays.
        fins[index] = Fin(vec4<u32>(kind, select(0u, 1u, outer), 0u, patch_id), data);
        grow_region(lo, hi, instance);
    }
}

fn emit_sector(center: vec2<f32>, radius: f32, from_dir: vec2<f32>, to_dir: vec2<f32>, depth: f32, outer: bool, patch_id: u32, instance: u32) {
    // Skip empty or degenerate sectors (collinear fins need no fan).
    if (!valid(from_dir) || !valid(to_dir) || (abs(cross2(from_dir, to_dir)) < 1e-6 && dot(from_dir, to_dir) > 0.0)) {
        return;
    }
    // A rectangle light's fan is a circle as wide as the light across the
    // sector's middle (`FinBuilder`: its bounding circle would reach past
    // both quads; a disk's is exactly its width; a sphere's, at the vertex).
    var mid = from_dir + to_dir;
    mid = select(vec2<f32>(-from_dir.y, from_dir.x), normalize(mid), dot(mid, mid) > 0.0);
    let r = radius * support(mid, center);
    let data = array<f32, 12>(center.x, center.y, from_dir.x, from_dir.y, to_dir.x, to_dir.y, r, depth, 0.0, 0.0, 0.0, 0.0);
    emit_fin(1u, outer, patch_id, instance, data, center - r, center + r);
}

// Unit left normal of the projected edge (the fins' outward direction), zero if degenerate.
fn edge_direction(s: Silhouette) -> vec2<f32> {
    return edge_direction_of(s.a.xyz, s.b.xyz);
}

fn edge_direction_of(a: vec3<f32>, b: vec3<f32>) -> vec2<f32> {
    let m0 = map_point(a);
    let m1 = map_point(b);
    return direction(vec2<f32>(m0.y - m1.y, m1.x - m0.x));
}

// While the vertex pass runs, other threads write silhouettes' `dir_a`/`dir_b`:
// read only the fields written before it (a whole-struct load would race).
fn end_a(s: u32) -> vec3<f32> {
    return silhouettes[s].a.xyz;
}

fn end_b(s: u32) -> vec3<f32> {
    return silhouettes[s].b.xyz;
}

fn direction_at(s: u32) -> vec2<f32> {
    return edge_direction_of(end_a(s), end_b(s));
}

// Only the owner thread of the end's vertex writes that end (`owns_vertex`),
// and only that end's own field.
fn set_end_direction(s: u32, end: u32, d: vec2<f32>) {
    if (end == 0u) {
        silhouettes[s].dir_a = d;
    } else {
        silhouettes[s].dir_b = d;
    }
}

// Visits every silhouette edge at local vertex `v` of instance `k`: through the
// mesh's vertex → edge lists. Returns (first in, first out, n in, n out), the
// smallest silhouette indices of the edges ending and starting at v.
fn vertex_silhouettes(inst: Instance, v: u32) -> vec4<u32> {
    let csr = g(inst, G_CSR_AT);
    let start = g(inst, csr + v);
    let end = g(inst, csr + v + 1u);
    let list = csr + g(inst, G_VERTICES) + 1u;
    var r = vec4<u32>(NONE, NONE, 0u, 0u);
    for (var j = start; j < end; j++) {
        let s = atomicLoad(&state[edge_silhouette_slot(inst.ids.w + g(inst, list + j))]);
        if (s == NONE) {
            continue;
        }
        if (silhouettes[s].ids.z == v) {
            r.x = min(r.x, s);
            r.z += 1u;
        }
        if (silhouettes[s].ids.y == v) {
            r.y = min(r.y, s);
            r.w += 1u;
        }
    }
    return r;
}

// Fin ends, fans, caps and junction sectors at one silhouette vertex (the core's
// `FinBuilder::build`, first loop). Run by the vertex's lowest silhouette.
fn process_vertex(s: u32, inst: Instance, v: u32) {
    let instance = silhouettes[s].ids.x;
    let csr = g(inst, G_CSR_AT);
    let start = g(inst, csr + v);
    let end = g(inst, csr + v + 1u);
    let list = csr + g(inst, G_VERTICES) + 1u;
    // Every incident silhouette's end starts with its own edge normal.
    for (var j = start; j < end; j++) {
        let t = atomicLoad(&state[edge_silhouette_slot(inst.ids.w + g(inst, list + j))]);
        if (t != NONE) {
            set_end_direction(t, select(1u, 0u, silhouettes[t].ids.y == v), direction_at(t));
        }
    }
    let incident = vertex_silhouettes(inst, v);
    let pos = frame_position(inst, v);
    if (pos.z <= near_depth()) {
        return;
    }
    let normal = vertex_normal_in_frame(inst, v);
    let n_in = incident.z;
    let n_out = incident.w;
    if (n_in == 1u && n_out == 1u) {
        let a = incident.x;
        let b = incident.y;
        let da = direction_at(a);
        let db = direction_at(b);
        if (silhouettes[a].info.x == 0u && silhouettes[b].info.x == 0u) {
            // Smooth vertex: both quads bend to the projected vertex normal.
            var d = direction(map_direction(pos, normal));
            if (!(dot(d, da) > 0.05 && dot(d, db) > 0.05)) {
                d = direction(da + db);
                if (!valid(da) || !valid(db)) {
                    d = vec2<f32>(0.0);
                }
            }
            if (valid(d)) {
                set_end_direction(a, 1u, d);
                set_end_direction(b, 0u, d);
                return;
            }
        }
    }
    let radius = fin_width(pos.z);
    if (!(radius > 0.0)) {
        return;
    }
    let center = map_point(pos);
    // The vertex's sectors soften the patch of smallest id among its
    // silhouettes (`FinBuilder`): a rule of the geometry, not of thread order.
    let patch_id = vertex_patch(inst, v);
    if (n_in == 1u && n_out == 1u) {
        let a = incident.x;
        let b = incident.y;
        let ea = map_point(end_b(a)) - map_point(end_a(a));
        let eb = map_point(end_b(b)) - map_point(end_a(b));
        let da = direction_at(a);
        let db = direction_at(b);
        // Interior is on the right: a right turn (negative cross) is convex.
        let turn = cross2(ea, eb);
        if (turn < 0.0) {
            emit_sector(center, radius, da, db, pos.z, true, patch_id, instance);
        } else if (turn > 0.0) {
            emit_sector(center, radius, -da, -db, pos.z, false, patch_id, instance);
        }
    } else if (n_in + n_out == 1u) {
        // Open chain end: outer half-disk cap around the edge's extension.
        let only = select(incident.y, incident.x, n_in == 1u);
        let m0 = map_point(end_a(only));
        let m1 = map_point(end_b(only));
        let d = direction_at(only);
        let along = direction(m1 - m0);
        let ext = select(along, -along, n_in == 0u);
        emit_sector(center, radius, d, ext, pos.z, true, patch_id, instance);
        emit_sector(center, radius, ext, -d, pos.z, true, patch_id, instance);
    } else {
        // Junction: sectors from each fin to the projected averaged normal.
        let avg = direction(map_direction(pos, normal));
        for (var j = start; j < end; j++) {
            let t = atomicLoad(&state[edge_silhouette_slot(inst.ids.w + g(inst, list + j))]);
            if (t == NONE) {
                continue;
            }
            let d = direction_at(t);
            if (dot(d, avg) > -0.999) {
                emit_sector(center, radius, d, avg, pos.z, true, patch_id, instance);
                emit_sector(center, radius, -d, -avg, pos.z, false, patch_id, instance);
            }
        }
    }
}

// The smallest patch id among the silhouettes at local vertex `v`.
fn vertex_patch(inst: Instance, v: u32) -> u32 {
    let csr = g(inst, G_CSR_AT);
    let list = csr + g(inst, G_VERTICES) + 1u;
    var patch_id = NONE;
    for (var j = g(inst, csr + v); j < g(inst, csr + v + 1u); j++) {
        let t = atomicLoad(&state[edge_silhouette_slot(inst.ids.w + g(inst, list + j))]);
        if (t != NONE) {
            patch_id = min(patch_id, silhouettes[t].ids.w);
        }
    }
    return patch_id;
}

fn owns_vertex(s: u32, inst: Instance, v: u32) -> bool {
    let incident = vertex_silhouettes(inst, v);
    return min(incident.x, incident.y) == s;
}

@compute @workgroup_size(64, 1, 1)
fn silhouette_vertices(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let s = first_silhouette() + thread_index(wg, lane);
    if (s >= records(C_SILHOUETTES)) {
        return;
    }
    let ids = silhouettes[s].ids;
    // Sub-layer histogram of edge midpoints (§4.1).
    atomicAdd(&control[C_HISTOGRAM + histogram_bin(0.5 * (end_a(s).z + end_b(s).z))], 1u);
    let inst = instances[ids.x];
    for (var e = 0u; e < 2u; e++) {
        let v = select(ids.z, ids.y, e == 0u);
        if (owns_vertex(s, inst, v)) {
            process_vertex(s, inst, v);
        }
    }
}

// ---------------------------------------------------------------- 8. quads

@compute @workgroup_size(64, 1, 1)
fn silhouette_quads(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let s = first_silhouette() + thread_index(wg, lane);
    if (s >= records(C_SILHOUETTES)) {
        return;
    }
    let sil = silhouettes[s];
    let near = near_depth();
    let dir = edge_direction(sil);
    if (sil.a.z <= near || sil.b.z <= near || !valid(dir)) {
        return;
    }
    let d0 = sil.dir_a;
    let d1 = sil.dir_b;
    let m0 = map_point(sil.a.xyz);
    let m1 = map_point(sil.b.xyz);
    // Eq. 3's width, times the light's support across the fin.
    let w0 = fin_width(sil.a.z) * support(d0, m0);
    let w1 = fin_width(sil.b.z) * support(d1, m1);
    if (!(w0 > 0.0 || w1 > 0.0)) {
        return;
    }
    // A staircase step almost along the fin direction spans no area.
    let along = direction(m1 - m0);
    if (abs(cross2(along, d0)) < 0.05 || abs(cross2(along, d1)) < 0.05) {
        return;
    }
    for (var side = 0u; side < 2u; side++) {
        let sign = select(-1.0, 1.0, side == 1u);
        let a0 = d0 * sign;
        let a1 = d1 * sign;
        let data = array<f32, 12>(m0.x, m0.y, m1.x, m1.y, a0.x, a0.y, a1.x, a1.y, w0, w1, sil.a.z, sil.b.z);
        let p2 = m0 + a0 * w0;
        let p3 = m1 + a1 * w1;
        emit_fin(0u, side == 1u, sil.ids.w, sil.ids.x, data, min(min(m0, m1), min(p2, p3)), max(max(m0, m1), max(p2, p3)));
    }
}

// ---------------------------------------------------------------- 9. casters

// What a caster of an alpha-masked instance's face cuts out with: the face's
// light-frame corners and their UVs, and where its mask starts (1 + it;
// 0: solid).
struct FaceCutout {
    corners: array<vec3<f32>, 3>,
    uvs: array<vec2<f32>, 3>,
    mask: u32,
}

// The UV at `q` on the face (`MapTriangle::clipped_with_cutout`: by `q`'s
// barycentrics in the face, which it lies on; the first corner's on a
// degenerate face).
fn face_uv(f: FaceCutout, q: vec3<f32>) -> vec2<f32> {
    let e1 = f.corners[1] - f.corners[0];
    let e2 = f.corners[2] - f.corners[0];
    let ep = q - f.corners[0];
    let d11 = dot(e1, e1);
    let d12 = dot(e1, e2);
    let d22 = dot(e2, e2);
    let det = d11 * d22 - d12 * d12;
    if (!(abs(det) > 0.0)) {
        return f.uvs[0];
    }
    let v = (d22 * dot(ep, e1) - d12 * dot(ep, e2)) / det;
    let w = (d11 * dot(ep, e2) - d12 * dot(ep, e1)) / det;
    return f.uvs[0] * (1.0 - v - w) + f.uvs[1] * v + f.uvs[2] * w;
}

fn emit_caster(
    p0: vec3<f32>,
    p1: vec3<f32>,
    p2: vec3<f32>,
    normal: vec3<f32>,
    offset: f32,
    patch_id: u32,
    instance: u32,
    face: FaceCutout,
) {
    let c0 = map_point(p0);
    let c1 = map_point(p1);
    let c2 = map_point(p2);
    let area = cross2(c1 - c0, c2 - c0);
    if (!(abs(area) > 0.0) || !finite(area)) {
        return;
    }
    let index = append(C_CASTERS);
    if (index >= params.capacity.z) {
        return;
    }
    var cutout = 0u;
    if (face.mask != 0u) {
        let uv0 = face_uv(face, p0);
        let uv1 = face_uv(face, p1);
        let uv2 = face_uv(face, p2);
        cutouts[index] = CasterCutout(
            array<f32, 6>(uv0.x, uv0.y, uv1.x, uv1.y, uv2.x, uv2.y),
            array<f32, 3>(p0.z, p1.z, p2.z),
            face.mask - 1u,
        );
        cutout = index + 1u;
    }
    casters[index] = Caster(
        array<f32, 6>(c0.x, c0.y, c1.x, c1.y, c2.x, c2.y),
        array<f32, 3>(normal.x, normal.y, normal.z),
        offset,
        min(p0.z, min(p1.z, p2.z)),
        max(p0.z, max(p1.z, p2.z)),
        0u, // its layer, once the plan is known
        cutout,
        patch_id,
    );
    grow_region(min(c0, min(c1, c2)), max(c0, max(c1, c2)), instance);
}

@compute @workgroup_size(64, 1, 1)
fn map_casters(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let item = item_of(thread_index(wg, lane), 2u);
    let i = item.x;
    if (i == NONE) {
        return;
    }
    let patch_id = atomicLoad(&state[FACE_WORDS * i]);
    if (patch_id == NONE) {
        return;
    }
    let instance = item.y;
    let inst = instances[instance];
    let at = g(inst, G_FACES_AT) + 7u * (i - inst.ids.z);
    let p = array<vec3<f32>, 3>(
        frame_position(inst, g(inst, at)),
        frame_position(inst, g(inst, at + 1u)),
        frame_position(inst, g(inst, at + 2u)),
    );
    let normal = cross(p[1] - p[0], p[2] - p[0]);
    let offset = dot(normal, p[0]);
    var face = FaceCutout(p, array<vec2<f32>, 3>(vec2<f32>(0.0), vec2<f32>(0.0), vec2<f32>(0.0)), inst.pose.z);
    if (face.mask != 0u) {
        let uvs = g(inst, G_FACE_UVS_AT) + 6u * (i - inst.ids.z);
        for (var k = 0u; k < 3u; k++) {
            face.uvs[k] = vec2<f32>(gf(inst, uvs + 2u * k), gf(inst, uvs + 2u * k + 1u));
        }
    }
    let near = near_depth();
    // Clipped to z ≥ near and, on a sphere light's cube face, to its window
    // frustum (`MapTriangle::clipped`): planes (a, b) with a·p + b ≥ 0 inside.
    let w = params.aperture.y;
    let planes = array<vec4<f32>, 5>(
        vec4<f32>(0.0, 0.0, 1.0, -near),
        vec4<f32>(-1.0, 0.0, w, 0.0),
        vec4<f32>(1.0, 0.0, w, 0.0),
        vec4<f32>(0.0, -1.0, w, 0.0),
        vec4<f32>(0.0, 1.0, w, 0.0),
    );
    let n_planes = select(1u, 5u, cube_face());
    var inside = true;
    for (var j = 0u; j < n_planes; j++) {
        for (var k = 0u; k < 3u; k++) {
            inside = inside && dot(planes[j].xyz, p[k]) + planes[j].w >= 0.0;
        }
    }
    if (inside) {
        emit_caster(p[0], p[1], p[2], normal, offset, patch_id, instance, face);
        return;
    }
    // Sutherland–Hodgman, one plane after another: at most 3 + 5 corners.
    var poly = array<vec3<f32>, 8>(p[0], p[1], p[2], vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0), vec3<f32>(0.0));
    var n = 3u;
    for (var j = 0u; j < n_planes; j++) {
        var out: array<vec3<f32>, 8>;
        var m = 0u;
        for (var k = 0u; k < n; k++) {
            let a = poly[k];
            let b = poly[(k + 1u) % n];
            let sa = dot(planes[j].xyz, a) + planes[j].w;
            let sb = dot(planes[j].xyz, b) + planes[j].w;
            if (sa >= 0.0 && m < 8u) {
                out[m] = a;
                m += 1u;
            }
            if ((sa >= 0.0) != (sb >= 0.0) && m < 8u) {
                out[m] = a + (b - a) * (sa / (sa - sb));
                m += 1u;
            }
        }
        poly = out;
        n = m;
    }
    for (var k = 1u; k + 1u < n; k++) {
        emit_caster(poly[0], poly[k], poly[k + 1u], normal, offset, patch_id, instance, face);
    }
}

// ---------------------------------------------------------------- 10. plan

const MAP_LIMIT: f32 = 8.0;

fn plane(j: u32) -> f32 {
    return bitcast<f32>(atomicLoad(&control[C_PLANES + 1u + j]));
}

@compute @workgroup_size(1, 1, 1)
fn plan_layers() {
    // The histogram holds the live silhouettes within the capacity.
    let total = min(atomicLoad(&control[C_SILHOUETTES]), params.capacity.x);
    let lo = order_value(atomicLoad(&control[C_DEPTH_MIN]));
    let hi = order_value(atomicLoad(&control[C_DEPTH_MAX]));
    let bins = params.layering.x;
    let layers = params.layering.y;
    let capacity = max(params.layering.z, 1u);
    // Cut the cumulative histogram at the k/N quantiles (`LayerPlan::from_edge_depths`).
    var planes = 0u;
    var wanted = 0u;
    var last = 0.0;
    if (layers > 1u && hi > lo && total > 0u) {
        let step = (hi - lo) / f32(bins);
        var cumulative = 0u;
        var next_cut = 1u;
        for (var i = 0u; i < bins; i++) {
            cumulative += atomicLoad(&control[C_HISTOGRAM + i]);
            var reached = false;
            while (next_cut < layers && cumulative * layers >= next_cut * total) {
                next_cut += 1u;
                reached = true;
            }
            if (reached && cumulative < total && i + 1u < bins) {
                let p = lo + step * f32(i + 1u);
                if (wanted == 0u || p != last) {
                    wanted += 1u;
                    last = p;
                    // Past the allocated layers the deepest ones merge (the
                    // CPU grows the maps once it reads `wanted` back).
                    if (planes + 1u < capacity) {
                        atomicStore(&control[C_PLANES + 1u + planes], bitcast<u32>(p));
                        planes += 1u;
                    }
                }
            }
        }
    }
    atomicStore(&control[C_PLANES], planes);
    // The maps raster every record (they skip the retired ones).
    let n_casters = records(C_CASTERS);
    let n_fins = records(C_FINS);
    // Nothing casts: no layer, no map.
    let used = select(planes + 1u, 0u, atomicLoad(&control[C_CASTERS]) == 0u && atomicLoad(&control[C_FINS]) == 0u);
    atomicStore(&control[C_LAYERS_WANTED], select(wanted + 1u, 0u, used == 0u));
    atomicStore(&control[C_LAYERS], used);
    atomicStore(&control[C_GENERATION], params.flags.w);

    // Map region: the bounds of every caster and fin (`RasterMaps::covering_region`).
    var rlo = vec2<f32>(order_value(atomicLoad(&control[C_REGION])), order_value(atomicLoad(&control[C_REGION + 1u])));
    var rhi = vec2<f32>(order_value(atomicLoad(&control[C_REGION + 2u])), order_value(atomicLoad(&control[C_REGION + 3u])));
    // A perspective map stops ~83° off axis (a cube face's at its window);
    // the sun's is in world units.
    if (!orthographic()) {
        let limit = select(MAP_LIMIT, min(MAP_LIMIT, params.aperture.y), cube_face());
        rlo = max(rlo, vec2<f32>(-limit));
        rhi = min(rhi, vec2<f32>(limit));
    }
    if (params.window.x <= params.window.z) {
        rlo = max(rlo, params.window.xy);
        rhi = min(rhi, params.window.zw);
    }
    if (!(rlo.x <= rhi.x && rlo.y <= rhi.y)) {
        rlo = vec2<f32>(0.0);
        rhi = vec2<f32>(1.0);
    }
    let size = max(max(rhi.x - rlo.x, rhi.y - rlo.y), 1e-9) * 1.001;
    let region_min = (rlo + rhi) * 0.5 - vec2<f32>(size * 0.5);
    let resolution = params.layering.w;
    let l0 = reference_depth();

    // The maps' `FinParams` (fin_types.wgsl), copied into their uniform; its
    // last four words, the texels redrawn, are `plan_redraw`'s.
    let p = array<u32, 32>(
        bitcast<u32>(region_min.x), bitcast<u32>(region_min.y), bitcast<u32>(size / f32(resolution)), bitcast<u32>(l0),
        resolution, used, n_casters, n_fins,
        bitcast<u32>(params.light.x), bitcast<u32>(near_depth()), bitcast<u32>(params.light.y * 1e-7), bitcast<u32>(1e-5),
        params.flags.x, params.flags.y, params.flags.z, projection_code(),
        bitcast<u32>(params.origin.x), bitcast<u32>(params.origin.y), bitcast<u32>(params.origin.z), 0u,
        bitcast<u32>(params.axis_u.x), bitcast<u32>(params.axis_u.y), bitcast<u32>(params.axis_u.z), 0u,
        bitcast<u32>(params.axis_v.x), bitcast<u32>(params.axis_v.y), bitcast<u32>(params.axis_v.z), 0u,
        bitcast<u32>(params.axis_n.x), bitcast<u32>(params.axis_n.y), bitcast<u32>(params.axis_n.z), 0u,
    );
    for (var i = 0u; i < 32u; i++) {
        atomicStore(&control[C_PARAMS + i], p[i]);
    }
    let rect = plan_redraw(p, region_min, size / f32(resolution), resolution);
    let redrawn = (rect.y - rect.x + 1u) * (rect.w - rect.z + 1u) * used;
    atomicStore(&control[C_REDRAWN], select(0u, redrawn, rect.x <= rect.y && rect.z <= rect.w));
    // A full redraw clears nothing: its maps' tiles are all new, and
    // `allocate_tiles` (maps.wgsl) clears each as it hands it out.
    let whole = all(rect == vec4<u32>(0u, resolution - 1u, 0u, resolution - 1u));
    write_args(C_ARGS_CLEAR, select(atomicLoad(&control[C_REDRAWN]), 0u, whole), WORKGROUP);
    // A partial redraw's raster arguments are `redraw_args`'.
    write_args(C_ARGS_CASTERS, n_casters, 1u);
    write_args(C_ARGS_FINS, n_fins, 1u);
    write_args(C_ARGS_FIN_THREADS, n_fins, WORKGROUP);
    write_args(C_ARGS_CASTER_THREADS, n_casters, WORKGROUP);
}

// Full or partial redraw (see the top of this file): writes the texels to
// redraw, inclusive (x0, x1, y0, y1), into the maps' `FinParams.redraw`, and
// keeps this frame's plan for the next. `p`: the plan's first 32 words.
// The sparse maps' pool kept an eighth free in their last redraw (it is
// sized with a fifth free, `map_tiles::TileDemand::tiles_at`). A partial
// redraw never frees a tile (those it no longer draws stay allocated), so a
// pool filling up, or one that overflowed, is emptied by a full redraw.
// `maps.wgsl` says 0xffffffff for a pool of every tile, which cannot overflow.
fn tiles_to_spare() -> bool {
    let used = atomicLoad(&control[h(H_TILES)]);
    let pool = atomicLoad(&control[h(H_TILES + 2u)]);
    return pool == 0u || pool == 0xffffffffu || used <= pool - pool / 8u;
}

fn plan_redraw(p: array<u32, 32>, region_min: vec2<f32>, texel: f32, resolution: u32) -> vec4<u32> {
    let full_rect = vec4<u32>(0u, resolution - 1u, 0u, resolution - 1u);
    var partial = atomicLoad(&control[h(H_DIRTY_COUNT)]) != FULL && atomicLoad(&control[h(H_VALID)]) == 1u;
    // The same plan: every word but the caster and fin counts (6, 7), the same planes.
    for (var i = 0u; i < 32u; i++) {
        let same = atomicLoad(&control[h(H_PLAN + i)]) == p[i];
        partial = partial && (same || i == 6u || i == 7u);
        atomicStore(&control[h(H_PLAN + i)], p[i]);
    }
    for (var i = 0u; i < 32u; i++) {
        let plane = atomicLoad(&control[C_PLANES + i]);
        partial = partial && atomicLoad(&control[h(H_PLAN + 32u + i)]) == plane;
        atomicStore(&control[h(H_PLAN + 32u + i)], plane);
    }
    // Nothing dropped for want of room (which primitives are dropped may
    // differ frame to frame) and every primitive inside a footprint: else
    // this frame is redrawn whole, and its maps are no base for the next.
    let complete = atomicLoad(&control[C_CURSORS + C_SILHOUETTES]) <= params.capacity.x
        && atomicLoad(&control[C_CURSORS + C_FINS]) <= params.capacity.y
        && atomicLoad(&control[C_CURSORS + C_CASTERS]) <= params.capacity.z
        && atomicLoad(&control[C_LAYERS_WANTED]) <= params.layering.z
        && atomicLoad(&control[C_UNBOUNDED]) == 0u
        && tiles_to_spare();
    atomicStore(&control[h(H_VALID)], select(0u, 1u, complete));
    partial = partial && complete;
    var rect = full_rect;
    if (partial) {
        // The dirty instances' new footprints join their old ones.
        for (var i = 0u; i < dirty_count(); i++) {
            let instance = dirty_instance(i);
            if (instance < params.totals.x) {
                grow_dirty_rect(instance);
            }
        }
        let lo = vec2<f32>(order_value(atomicLoad(&control[h(H_DIRTY_RECT)])), order_value(atomicLoad(&control[h(H_DIRTY_RECT + 1u)])));
        let hi = vec2<f32>(order_value(atomicLoad(&control[h(H_DIRTY_RECT + 2u)])), order_value(atomicLoad(&control[h(H_DIRTY_RECT + 3u)])));
        // Texels whose centres may lie in [lo, hi] (`texel_range` in maps.wgsl), one more each side.
        let r = f32(resolution) - 1.0;
        let a = clamp(ceil((lo - region_min) / texel - 0.5) - 1.0, vec2<f32>(0.0), vec2<f32>(r + 1.0));
        let b = clamp(floor((hi - region_min) / texel - 0.5) + 1.0, vec2<f32>(-1.0), vec2<f32>(r));
        if (!(lo.x <= hi.x && lo.y <= hi.y)) {
            rect = vec4<u32>(1u, 0u, 1u, 0u); // nothing dirty covered a texel, before or now
        } else if (a.x <= b.x && a.y <= b.y) {
            rect = vec4<u32>(u32(a.x), u32(b.x), u32(a.y), u32(b.y));
        } else {
            rect = vec4<u32>(1u, 0u, 1u, 0u); // wholly off the maps
        }
        partial = any(rect != full_rect);
    }
    for (var i = 0u; i < 4u; i++) {
        atomicStore(&control[C_PARAMS + 32u + i], rect[i]);
    }
    atomicStore(&control[C_PARTIAL], select(0u, 1u, partial) | select(0u, 2u, stage() == STAGE_ACCEPTED));
    // What the next update starts from if it extracts its listed instances only.
    for (var i = 0u; i < 3u; i++) {
        atomicStore(&control[h(H_KEPT + i)], atomicLoad(&control[C_CURSORS + i]));
    }
    for (var i = 0u; i <= C_DEEPEST; i++) {
        atomicStore(&control[h(H_KEPT + 3u + i)], atomicLoad(&control[i]));
    }
    // The redrawn texel centres' map-space bounds, for `gather_redraw_*`,
    // widened by half a texel: `texel_range` divides where this multiplies,
    // and a primitive gathered in excess is clipped by the raster anyway.
    let area_lo = region_min + vec2<f32>(f32(rect.x), f32(rect.z)) * texel;
    let area_hi = region_min + (vec2<f32>(f32(rect.y), f32(rect.w)) + 1.0) * texel;
    atomicStore(&control[h(H_REDRAW_AREA)], bitcast<u32>(area_lo.x));
    atomicStore(&control[h(H_REDRAW_AREA + 1u)], bitcast<u32>(area_lo.y));
    atomicStore(&control[h(H_REDRAW_AREA + 2u)], bitcast<u32>(area_hi.x));
    atomicStore(&control[h(H_REDRAW_AREA + 3u)], bitcast<u32>(area_hi.y));
    atomicStore(&control[list_casters()], 0u);
    atomicStore(&control[list_fins()], 0u);
    atomicStore(&control[CONTROL_LIST_CASTERS], list_casters());
    atomicStore(&control[CONTROL_LIST_FINS], list_fins());
    return rect;
}

// ---------------------------------------------------------------- 11. layers

// A patch_id's layer: that of its mean silhouette depth; patches with no
// silhouette (a closed mesh seen from inside) go to the last layer.
fn patch_layer(patch_id: u32) -> u32 {
    let planes = atomicLoad(&control[C_PLANES]);
    let count = atomicLoad(&state[FACE_WORDS * patch_id + 4u]);
    if (count == 0u) {
        return planes;
    }
    let sum = f32(atomicLoad(&state[FACE_WORDS * patch_id + 3u])) * 4294967296.0
        + f32(atomicLoad(&state[FACE_WORDS * patch_id + 2u]));
    let mean = (sum / f32(count) / FIXED_ONE - 1.0) * reference_depth();
    var layer = 0u;
    for (var j = 0u; j < planes; j++) {
        if (plane(j) <= mean) {
            layer = j + 1u;
        }
    }
    return layer;
}

@compute @workgroup_size(64, 1, 1)
fn assign_fin_layers(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let i = thread_index(wg, lane);
    if (i >= records(C_FINS) || fins[i].header.z == RETIRED_LAYER) {
        return;
    }
    fins[i].header.z = patch_layer(fins[i].header.w);
}

@compute @workgroup_size(64, 1, 1)
fn assign_caster_layers(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let i = thread_index(wg, lane);
    if (i >= records(C_CASTERS) || casters[i].layer == RETIRED_LAYER) {
        return;
    }
    casters[i].layer = patch_layer(casters[i].patch_id);
}

// ---------------------------------------------------------------- 12. partial redraw

fn partial_redraw() -> bool {
    return (atomicLoad(&control[C_PARTIAL]) & 1u) != 0u;
}

// Whether bounds [lo, hi] reach the centre of a redrawn texel.
fn reaches_redraw_area(lo: vec2<f32>, hi: vec2<f32>) -> bool {
    let a = vec2<f32>(bitcast<f32>(atomicLoad(&control[h(H_REDRAW_AREA)])), bitcast<f32>(atomicLoad(&control[h(H_REDRAW_AREA + 1u)])));
    let b = vec2<f32>(bitcast<f32>(atomicLoad(&control[h(H_REDRAW_AREA + 2u)])), bitcast<f32>(atomicLoad(&control[h(H_REDRAW_AREA + 3u)])));
    // Not finite bounds reach everything (the raster clips them to the area).
    return !(hi.x < a.x || hi.y < a.y || lo.x > b.x || lo.y > b.y);
}

@compute @workgroup_size(64, 1, 1)
fn gather_redraw_fins(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let i = thread_index(wg, lane);
    if (!partial_redraw() || i >= records(C_FINS) || fins[i].header.z == RETIRED_LAYER) {
        return;
    }
    let bounds = fin_bounds(fins[i]);
    if (reaches_redraw_area(bounds.xy, bounds.zw)) {
        atomicStore(&control[list_fins() + 1u + atomicAdd(&control[list_fins()], 1u)], i);
    }
}

@compute @workgroup_size(64, 1, 1)
fn gather_redraw_casters(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let i = thread_index(wg, lane);
    if (!partial_redraw() || i >= records(C_CASTERS) || casters[i].layer == RETIRED_LAYER) {
        return;
    }
    let c = casters[i];
    let a = vec2<f32>(c.corners[0], c.corners[1]);
    let b = vec2<f32>(c.corners[2], c.corners[3]);
    let d = vec2<f32>(c.corners[4], c.corners[5]);
    if (reaches_redraw_area(min(a, min(b, d)), max(a, max(b, d)))) {
        atomicStore(&control[list_casters() + 1u + atomicAdd(&control[list_casters()], 1u)], i);
    }
}

// A partial redraw rasters the gathered casters and fins only.
@compute @workgroup_size(1, 1, 1)
fn redraw_args() {
    if (partial_redraw()) {
        write_args(C_ARGS_CASTERS, atomicLoad(&control[list_casters()]), 1u);
        write_args(C_ARGS_FINS, atomicLoad(&control[list_fins()]), 1u);
    }
}
