// Posing on the GPU (issue 16, item 2: casters as they are drawn): each
// skinned or morphed caster instance has its own copy of its mesh's packed
// geometry at rest (`GpuMeshGeometry::pack_posable`), less the pose section,
// which its mesh's shared packing holds once.
// These passes pose the copy in place before the extraction (`extract_*.wgsl`)
// reads it, the way Bevy's vertex shader poses what it draws (`morph.wgsl`,
// `skinning.wgsl`) and `pose.rs` poses the CPU's copy:
//
//  1. pose_vertices   p = bind + Σₜ wₜ Δₜ (morph targets), then, when skinned,
//                     Σᵢ wᵢ (Jᵢ · IBPᵢ) p over the vertex's four joints
//  2. pose_faces      each face's plane from the posed positions
//  3. pose_outline    an alpha-masked mesh's outline vertices (points of its
//                     faces, fixed there by the UVs): each at its barycentrics
//                     in its posed face, with that face's normal
//  4. pose_normals    each mesh vertex's area-weighted normal: the sum of its
//     pose_creases    faces' normals; each two-face edge's crease flag
//
// The topology (welded vertices, faces, edges, vertex → edge lists) is the
// mesh's at rest, which the main world checked is the posed mesh's too.
// Dispatched as (x, jobs) — past 65 535 jobs as (x, 65 535, z): `job_of`;
// each thread strides over its job's items.

// `poses` layout (u32 words), see `GpuSceneBuilder::pose_buffer`.
const P_JOBS: u32 = 0u;
const P_COS_CREASE: u32 = 4u;
const P_HEADER: u32 = 8u;
const JOB_WORDS: u32 = 8u;
// A job: its copy's offset in `geometry`, its data's offset in `poses`, its
// joints, its morph weights, 1 when skinned, the offset of its mesh's shared
// packing (whose pose section the copy, which has none, is posed from).
const J_GEOMETRY: u32 = 0u;
const J_DATA: u32 = 1u;
const J_JOINTS: u32 = 2u;
const J_MORPHS: u32 = 3u;
const J_SKINNED: u32 = 4u;
const J_SOURCE: u32 = 5u;

// Geometry blob header (relative word offsets), see `GpuMeshGeometry`.
const G_VERTICES: u32 = 0u;
const G_FACES: u32 = 1u;
const G_EDGES: u32 = 2u;
const G_FACES_AT: u32 = 3u;
const G_VERTICES_AT: u32 = 4u;
const G_EDGES_AT: u32 = 5u;
const G_CSR_AT: u32 = 6u;
const G_NON_MANIFOLD_AT: u32 = 7u;
const G_POSE_AT: u32 = 8u;
const G_MORPH_TARGETS: u32 = 9u;
// An outlined packing's own mesh vertices (its outline's come after them); 0: none.
const G_MESH_VERTICES: u32 = 11u;
const POSE_VERTEX_WORDS: u32 = 9u;
// Per outline vertex, after the morph targets: its face, its barycentrics
// w1, w2 there (the point a + w1 (b − a) + w2 (c − a)).
const OUTLINE_VERTEX_WORDS: u32 = 3u;
const VERTEX_WORDS: u32 = 6u;
const FACE_WORDS: u32 = 7u;
const EDGE_WORDS: u32 = 5u;
const NO_FACE: u32 = 0xffffffffu;
const EDGE_CREASE: u32 = 4u;
const EDGE_NON_MANIFOLD: u32 = 8u;
const FACE_MASK: u32 = 0x7fffffffu;

const WORKGROUP: u32 = 64u;

@group(0) @binding(0) var<storage, read> poses: array<u32>;
@group(0) @binding(1) var<storage, read_write> geometry: array<u32>;

// The job of a workgroup, or none past the last.
fn job_of(wg: vec3<u32>) -> u32 {
    let job = wg.z * 65535u + wg.y;
    return select(NO_JOB, job, job < poses[P_JOBS]);
}

const NO_JOB: u32 = 0xffffffffu;

fn job_word(job: u32, word: u32) -> u32 {
    return poses[P_HEADER + job * JOB_WORDS + word];
}

fn pf(word: u32) -> f32 {
    return bitcast<f32>(poses[word]);
}

// Word `word` of job `job`'s geometry copy, and as a float.
fn g(job: u32, word: u32) -> u32 {
    return geometry[job_word(job, J_GEOMETRY) + word];
}

fn gf(job: u32, word: u32) -> f32 {
    return bitcast<f32>(g(job, word));
}

// Word `word` of the job's shared packing (its pose section is there), as a float.
fn sf(job: u32, word: u32) -> f32 {
    return bitcast<f32>(geometry[job_word(job, J_SOURCE) + word]);
}

fn s3(job: u32, word: u32) -> vec3<f32> {
    return vec3(sf(job, word), sf(job, word + 1u), sf(job, word + 2u));
}

fn set_gf(job: u32, word: u32, x: f32) {
    geometry[job_word(job, J_GEOMETRY) + word] = bitcast<u32>(x);
}

fn g3(job: u32, word: u32) -> vec3<f32> {
    return vec3(gf(job, word), gf(job, word + 1u), gf(job, word + 2u));
}

fn set_g3(job: u32, word: u32, v: vec3<f32>) {
    set_gf(job, word, v.x);
    set_gf(job, word + 1u, v.y);
    set_gf(job, word + 2u, v.z);
}

fn position(job: u32, v: u32) -> vec3<f32> {
    return g3(job, g(job, G_VERTICES_AT) + v * VERTEX_WORDS);
}

// Column `c` (0..4) of joint `j`'s matrix; column 3's w is 1 when it is finite.
fn joint_column(job: u32, j: u32, c: u32) -> vec4<f32> {
    let at = job_word(job, J_DATA) + j * 16u + c * 4u;
    return vec4(pf(at), pf(at + 1u), pf(at + 2u), pf(at + 3u));
}

// `pose::skinned`: Σ wᵢ Mᵢ p over the vertex's joints; a joint out of range
// or not finite counts for nothing and the others are renormalised; a vertex
// left with no weight stays where it is.
fn skinned(job: u32, p: vec3<f32>, joints: vec4<u32>, weights: vec4<f32>) -> vec3<f32> {
    var sum = array<vec3<f32>, 4>(vec3(0.0), vec3(0.0), vec3(0.0), vec3(0.0));
    var total = 0.0;
    var skipped = false;
    for (var k = 0u; k < 4u; k++) {
        let w = weights[k];
        if (w == 0.0) {
            continue;
        }
        let j = joints[k];
        if (j >= job_word(job, J_JOINTS) || joint_column(job, j, 3u).w != 1.0) {
            skipped = true;
            continue;
        }
        for (var c = 0u; c < 4u; c++) {
            sum[c] += joint_column(job, j, c).xyz * w;
        }
        total += w;
    }
    if (!(abs(total) > 0.0)) {
        return p;
    }
    let scale = select(1.0, 1.0 / total, skipped);
    return (sum[0] * p.x + sum[1] * p.y + sum[2] * p.z + sum[3]) * scale;
}

// The vertices posed from the pose section: the mesh's own (an outlined
// packing's outline vertices follow them, `pose_outline`).
fn mesh_vertices(job: u32) -> u32 {
    let m = g(job, G_MESH_VERTICES);
    return select(g(job, G_VERTICES), m, m != 0u);
}

@compute @workgroup_size(64)
fn pose_vertices(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32,
                 @builtin(num_workgroups) groups: vec3<u32>) {
    let job = job_of(wg);
    if (job == NO_JOB) {
        return;
    }
    let n = mesh_vertices(job);
    let source = job_word(job, J_SOURCE);
    let pose_at = geometry[source + G_POSE_AT];
    let targets = min(geometry[source + G_MORPH_TARGETS], job_word(job, J_MORPHS));
    let weights_at = job_word(job, J_DATA) + job_word(job, J_JOINTS) * 16u;
    let deltas = pose_at + n * POSE_VERTEX_WORDS;
    for (var v = wg.x * WORKGROUP + lane; v < n; v += groups.x * WORKGROUP) {
        let at = pose_at + v * POSE_VERTEX_WORDS;
        var p = s3(job, at);
        for (var t = 0u; t < targets; t++) {
            let w = pf(weights_at + t);
            if (w != 0.0) {
                p += s3(job, deltas + (t * n + v) * 3u) * w;
            }
        }
        if (job_word(job, J_SKINNED) != 0u) {
            let j01 = geometry[source + at + 3u];
            let j23 = geometry[source + at + 4u];
            let joints = vec4(j01 & 0xffffu, j01 >> 16u, j23 & 0xffffu, j23 >> 16u);
            let weights = vec4(sf(job, at + 5u), sf(job, at + 6u), sf(job, at + 7u), sf(job, at + 8u));
            p = skinned(job, p, joints, weights);
        }
        set_g3(job, g(job, G_VERTICES_AT) + v * VERTEX_WORDS, p);
    }
}

// The unnormalised face normal (b − a) × (c − a) and its offset n·a
// (`Topology::face_planes`).
@compute @workgroup_size(64)
fn pose_faces(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32,
              @builtin(num_workgroups) groups: vec3<u32>) {
    let job = job_of(wg);
    if (job == NO_JOB) {
        return;
    }
    for (var f = wg.x * WORKGROUP + lane; f < g(job, G_FACES); f += groups.x * WORKGROUP) {
        let at = g(job, G_FACES_AT) + f * FACE_WORDS;
        let a = position(job, g(job, at));
        let b = position(job, g(job, at + 1u));
        let c = position(job, g(job, at + 2u));
        let n = cross(b - a, c - a);
        set_g3(job, at + 3u, n);
        set_gf(job, at + 6u, dot(n, a));
    }
}

fn face_normal(job: u32, f: u32) -> vec3<f32> {
    return g3(job, g(job, G_FACES_AT) + f * FACE_WORDS + 3u);
}

// An outlined packing's outline vertices (`Outline::faces`), each where its
// barycentrics put it in its posed face, its normal that face's (as the
// core's outline of the posed mesh has them).
@compute @workgroup_size(64)
fn pose_outline(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32,
                @builtin(num_workgroups) groups: vec3<u32>) {
    let job = job_of(wg);
    if (job == NO_JOB || g(job, G_MESH_VERTICES) == 0u) {
        return;
    }
    let m = g(job, G_MESH_VERTICES);
    let source = job_word(job, J_SOURCE);
    let at = geometry[source + G_POSE_AT] + m * POSE_VERTEX_WORDS + geometry[source + G_MORPH_TARGETS] * m * 3u;
    for (var k = wg.x * WORKGROUP + lane; k < g(job, G_VERTICES) - m; k += groups.x * WORKGROUP) {
        let record = at + k * OUTLINE_VERTEX_WORDS;
        let f = geometry[source + record];
        let face = g(job, G_FACES_AT) + f * FACE_WORDS;
        let a = position(job, g(job, face));
        let b = position(job, g(job, face + 1u));
        let c = position(job, g(job, face + 2u));
        let p = a + (b - a) * sf(job, record + 1u) + (c - a) * sf(job, record + 2u);
        let v = g(job, G_VERTICES_AT) + (m + k) * VERTEX_WORDS;
        set_g3(job, v, p);
        set_g3(job, v + 3u, face_normal(job, f));
    }
}

// Each vertex's normal: its faces' normals summed (`Topology::vertex_normals`).
// A face meets the vertex at two of its edges, so the sum over the vertex's
// edges of their faces counts each face twice.
@compute @workgroup_size(64)
fn pose_normals(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32,
                @builtin(num_workgroups) groups: vec3<u32>) {
    let job = job_of(wg);
    if (job == NO_JOB) {
        return;
    }
    let n = g(job, G_VERTICES);
    let csr = g(job, G_CSR_AT);
    // (An outline vertex's normal is its face's: `pose_outline`.)
    for (var v = wg.x * WORKGROUP + lane; v < mesh_vertices(job); v += groups.x * WORKGROUP) {
        var sum = vec3(0.0);
        for (var k = g(job, csr + v); k < g(job, csr + v + 1u); k++) {
            let e = g(job, csr + n + 1u + k);
            let at = g(job, G_EDGES_AT) + e * EDGE_WORDS;
            if ((g(job, at + 4u) & EDGE_NON_MANIFOLD) != 0u) {
                let list = g(job, G_NON_MANIFOLD_AT) + g(job, at + 2u);
                for (var i = 0u; i < g(job, at + 3u); i++) {
                    sum += face_normal(job, g(job, list + i) & FACE_MASK);
                }
            } else {
                sum += face_normal(job, g(job, at + 2u));
                if (g(job, at + 3u) != NO_FACE) {
                    sum += face_normal(job, g(job, at + 3u));
                }
            }
        }
        set_g3(job, g(job, G_VERTICES_AT) + v * VERTEX_WORDS + 3u, sum * 0.5);
    }
}

fn normalize_or_zero(v: vec3<f32>) -> vec3<f32> {
    let l = length(v);
    return select(vec3(0.0), v / l, l > 0.0 && l <= 3.0e38);
}

// A two-face edge is a crease where its faces meet at more than the crease
// angle (`Topology::crease`); one-face and non-manifold edges always are.
@compute @workgroup_size(64)
fn pose_creases(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32,
                @builtin(num_workgroups) groups: vec3<u32>) {
    let job = job_of(wg);
    if (job == NO_JOB) {
        return;
    }
    let cos_crease = pf(P_COS_CREASE);
    for (var e = wg.x * WORKGROUP + lane; e < g(job, G_EDGES); e += groups.x * WORKGROUP) {
        let at = g(job, G_EDGES_AT) + e * EDGE_WORDS;
        let flags = g(job, at + 4u);
        if ((flags & EDGE_NON_MANIFOLD) != 0u || g(job, at + 3u) == NO_FACE) {
            continue;
        }
        let a = normalize_or_zero(face_normal(job, g(job, at + 2u)));
        let b = normalize_or_zero(face_normal(job, g(job, at + 3u)));
        let crease = dot(a, b) < cos_crease;
        geometry[job_word(job, J_GEOMETRY) + at + 4u] = select(flags & ~EDGE_CREASE, flags | EDGE_CREASE, crease);
    }
}
