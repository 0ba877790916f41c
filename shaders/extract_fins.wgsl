// Fin extraction, stages 7–9 (Cai et al. §3.1, fig. 4; see
// `extract_common.wgsl` for the whole pipeline): per silhouette vertex its
// smooth end directions, fans, caps and junction sectors; per silhouette
// edge its inner and outer quads; the light-facing faces as map casters.

#import bevy_shadow_fins::fin_types::{Caster, CasterCutout, Fin, cross2}
#import bevy_shadow_fins::extract_common::{
    Instance, Silhouette, params, instances, control, state, cutouts, silhouettes, fins, casters,
    C_SILHOUETTES, C_FINS, C_CASTERS, C_HISTOGRAM, FACE_WORDS, NONE, G_VERTICES, G_FACES_AT, G_CSR_AT,
    G_FACE_UVS_AT, thread_index, finite, g, gf, vertex_normal_in_frame, frame_position, near_depth,
    map_point, map_direction, fin_width, support, cube_face, direction, valid, grow_region, item_of,
    append, records, histogram_bin, edge_silhouette_slot, first_silhouette
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
