// Fin extraction, the stages that decide what an update does (see
// `extract_common.wgsl` for the whole pipeline): 0. counters reset, whether
// the moved instances may be extracted alone, their old footprints; 10. the
// layer plan (Cai et al. §4.1: the histogram of silhouette depths cut at the
// k/N quantiles), the map region and the maps' parameters; 11. every record
// to its patch's layer; 12. on a partial redraw, the records that reach the
// redrawn rectangle, and the maps' dispatch sizes.

#import bevy_shadow_fins::fin_types::{fin_bounds, CONTROL_LIST_CASTERS, CONTROL_LIST_FINS, RETIRED_LAYER}
#import bevy_shadow_fins::extract_common::{
    params, instances, control, state, silhouettes, fins, casters, C_SILHOUETTES, C_FINS, C_CASTERS,
    C_DEPTH_MIN, C_DEPTH_MAX, C_DEEPEST, C_REGION, C_LAYERS_WANTED, C_GENERATION, C_LAYERS, C_PARTIAL,
    C_REDRAWN, C_UNBOUNDED, C_PARAMS, C_ARGS_CLEAR, C_ARGS_CASTERS, C_ARGS_FINS, C_ARGS_FIN_THREADS,
    C_ARGS_CASTER_THREADS, C_PLANES, C_STAGE, C_CURSORS, C_ARGS_ITEMS, C_ARGS_RETIRE, C_HISTOGRAM,
    STAGE_FULL, STAGE_ATTEMPT, STAGE_ACCEPTED, H_PLAN, H_DIRTY_COUNT, H_VALID, H_INCREMENTAL,
    H_DIRTY_RECT, H_REDRAW_AREA, H_KEPT, H_UNION, H_DIRTY_ITEMS, H_EPOCH, H_TILES, I_DEEPEST,
    I_DEPTH_MIN, I_DEPTH_MAX, I_LISTED, FULL, FACE_WORDS, NONE, FIXED_ONE, WORKGROUP, thread_index,
    order_value, instance_of, reference_depth, orthographic, near_depth, cube_face, projection_code, h,
    instance_word, dirty_entry, list_casters, list_fins, clear_instance, clear_keys, dirty_count,
    dirty_instance, grow_dirty_rect, stage, listed, records, histogram_bin, write_args
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
