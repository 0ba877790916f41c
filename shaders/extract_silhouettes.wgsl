// Fin extraction, stages 1–6 (Cai et al. §3.1; see `extract_common.wgsl` for
// the whole pipeline): vertices into the light frame, the facing test,
// patches (connected light-facing regions, by union-find), silhouette edges
// and the dispatch sizes of the passes over them.

#import bevy_shadow_fins::extract_common::{
    Instance, Silhouette, params, instances, control, state, silhouettes, C_SILHOUETTES, C_DEPTH_MIN,
    C_DEPTH_MAX, C_DEEPEST, C_ARGS_SILHOUETTES, STAGE_ACCEPTED, I_DEEPEST, I_DEPTH_MIN, I_DEPTH_MAX,
    FACE_WORDS, FACING, IN_MAPS, NONE, FIXED_ONE, WORKGROUP, G_FACES_AT, G_EDGES_AT, G_NON_MANIFOLD_AT,
    EDGE_BACK_FACE_MISSING, EDGE_FORWARD_FIRST, EDGE_FORWARD_SECOND, EDGE_CREASE, EDGE_NON_MANIFOLD,
    EDGE_PATCH_ONLY, EDGE_OUTLINE, thread_index, order_key, g, gf, vertex_position,
    vertex_normal_in_frame, position_slot, frame_position, reference_depth, outside_face_window, h,
    instance_word, stage, item_of, append, records, edge_silhouette_slot, write_args, first_silhouette
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
    let q = inst.linear_x.xyz * p.x + inst.linear_y.xyz * p.y + inst.linear_z.xyz * p.z + inst.translation.xyz;
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
        let forward = (flags & EDGE_FORWARD_FIRST) != 0u;
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
            emit_silhouette(k, inst, i, v0, v1, (flags & EDGE_FORWARD_FIRST) != 0u, f0, crease);
        } else {
            emit_silhouette(k, inst, i, v0, v1, (flags & EDGE_FORWARD_SECOND) != 0u, f1, crease);
        }
    }
}

@compute @workgroup_size(1, 1, 1)
fn silhouette_args() {
    let n = select(records(C_SILHOUETTES) - min(first_silhouette(), records(C_SILHOUETTES)), 0u, stage() == STAGE_ACCEPTED);
    write_args(C_ARGS_SILHOUETTES, n, WORKGROUP);
}
