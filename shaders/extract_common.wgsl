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
//
// This module holds what every stage shares: the records, the bindings, the
// `control` and `history` layout, and the helpers. The stages are three
// shaders over the same bind group layout: `extract_plan.wgsl` (0, 10–12),
// `extract_silhouettes.wgsl` (1–6) and `extract_fins.wgsl` (7–9).
#define_import_path bevy_shadow_fins::extract_common

#import bevy_shadow_fins::fin_types::{Caster, CasterCutout, Fin}

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
    linear_x: vec4<f32>,
    linear_y: vec4<f32>,
    linear_z: vec4<f32>,
    translation: vec4<f32>,
    // Normals: cofactor matrix (columns), sign-corrected for mirroring transforms.
    normal_x: vec4<f32>,
    normal_y: vec4<f32>,
    normal_z: vec4<f32>,
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
const EDGE_FORWARD_FIRST: u32 = 1u;
const EDGE_FORWARD_SECOND: u32 = 2u;
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
    return inst.normal_x.xyz * n.x + inst.normal_y.xyz * n.y + inst.normal_z.xyz * n.z;
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

fn edge_silhouette_slot(edge: u32) -> u32 {
    return FACE_WORDS * params.totals.z + edge;
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
