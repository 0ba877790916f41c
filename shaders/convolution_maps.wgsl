// The basis images of convolution shadow maps, from the hard shadow map the
// penumbra-map passes drew (`maps.wgsl`, one layer's slab depths at texel
// centres): the nearest depth, the Fourier basis at the first stored mip
// level, then each coarser level by 2×2 boxes — as
// `ConvolutionModel::on_depth_map` with `Prefilter::Mipmap` does.
#import bevy_shadow_fins::fin_types::{FinParams, FIRST_SLOT, page_index, pooled_texel_index}
#import bevy_shadow_fins::convolution_types::{
    ConvolutionParams, c_k, level_resolution, level_offset, far_depth, near_depth, normalised,
}

@group(0) @binding(0) var<uniform> params: FinParams;
@group(0) @binding(1) var<storage, read> maps: array<u32>;
@group(0) @binding(2) var<storage, read_write> basis: array<f32>;
@group(0) @binding(3) var<uniform> csm: ConvolutionParams;
// `ConvolutionState.near_bits`, found by atomicMin.
@group(0) @binding(4) var<storage, read_write> near_bits: atomic<u32>;
// The stored level a downsampling dispatch writes (a dynamic offset per level).
@group(0) @binding(5) var<uniform> level: vec4<u32>;

const REDUCE: u32 = 256u;
var<workgroup> partial: array<f32, REDUCE>;

// The nearest caster depth over the maps' layers at a texel (+∞ where none).
fn nearest_depth(x: u32, y: u32) -> f32 {
    var z = bitcast<f32>(0x7f800000u);
    for (var layer = 0u; layer < params.counts.y; layer++) {
        let page = maps[page_index(params, layer, x, y)];
        if (page >= FIRST_SLOT) {
            z = min(z, bitcast<f32>(maps[pooled_texel_index(params, page, x, y)]));
        }
    }
    return z;
}

@compute @workgroup_size(1, 1, 1)
fn reset_near() {
    atomicStore(&near_bits, 0x7f800000u);
}

// The least depth of the map, one texel an invocation, a workgroup's least
// into the buffer by atomicMin (no invocation loops over the whole map).
@compute @workgroup_size(256, 1, 1)
fn find_near(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let res = params.counts.x;
    let t = (wg.x + wg.y * 65535u) * REDUCE + lane;
    var z = bitcast<f32>(0x7f800000u);
    if (t < res * res) {
        z = nearest_depth(t % res, t / res);
    }
    partial[lane] = z;
    workgroupBarrier();
    for (var stride = REDUCE / 2u; stride > 0u; stride /= 2u) {
        if (lane < stride) {
            partial[lane] = min(partial[lane], partial[lane + stride]);
        }
        workgroupBarrier();
    }
    // Depths are ≥ 0 (an orthographic one clamps at 0): their bits order as they do.
    if (lane == 0u && partial[0] >= 0.0 && partial[0] < 3.0e38) {
        atomicMin(&near_bits, bitcast<u32>(max(partial[0], 0.0)));
    }
}

// The basis of normalised depth z (`shadow_fins::peers::convolution::basis`),
// added with weight w into the texel at `at`.
fn add_basis(at: u32, z: f32, w: f32) {
    let m = csm.counts.x;
    basis[at] += w * z;
    for (var k = 0u; k < m; k++) {
        let a = c_k(k + 1u) * z;
        let co = cos(a);
        let s = sin(a);
        basis[at + 1u + k] += w * co;
        basis[at + 1u + m + k] += w * s;
        basis[at + 1u + 2u * m + k] += w * z * co;
        basis[at + 1u + 3u * m + k] += w * z * s;
    }
}

// The first stored level: each texel the average basis of the map texels
// it covers (2^first per side; the map itself when nothing was dropped).
@compute @workgroup_size(8, 8, 1)
fn first_level(@builtin(global_invocation_id) id: vec3<u32>) {
    let r = level_resolution(csm, 0u);
    if (id.x >= r || id.y >= r) {
        return;
    }
    let channels = csm.counts.y;
    let at = level_offset(csm, 0u) + (id.y * r + id.x) * channels;
    for (var ch = 0u; ch < channels; ch++) {
        basis[at + ch] = 0.0;
    }
    let res = params.counts.x;
    let block = 1u << csm.counts.z;
    let x0 = id.x * block;
    let y0 = id.y * block;
    let x1 = min(x0 + block, res);
    let y1 = min(y0 + block, res);
    let w = 1.0 / f32((x1 - x0) * (y1 - y0));
    let far = far_depth(params.map.w);
    let near = near_depth(atomicLoad(&near_bits), far);
    let span = csm.series.z;
    for (var y = y0; y < y1; y++) {
        for (var x = x0; x < x1; x++) {
            let d = nearest_depth(x, y);
            // Empty texels hold the far plane: nothing in front of any receiver.
            var z = span;
            if (d < 3.0e38) {
                z = normalised(d, near, far, span);
            }
            add_basis(at, z, w);
        }
    }
}

// Stored level `level.x` from the one before: each texel the mean of the
// finer level's texels it covers (2×2, fewer on an odd level's last row).
@compute @workgroup_size(8, 8, 1)
fn downsample(@builtin(global_invocation_id) id: vec3<u32>) {
    let l = level.x;
    let r = level_resolution(csm, l);
    if (id.x >= r || id.y >= r) {
        return;
    }
    let channels = csm.counts.y;
    let fine = level_resolution(csm, l - 1u);
    let source = level_offset(csm, l - 1u);
    let at = level_offset(csm, l) + (id.y * r + id.x) * channels;
    var count = 0u;
    for (var ch = 0u; ch < channels; ch++) {
        basis[at + ch] = 0.0;
    }
    for (var dy = 0u; dy < 2u; dy++) {
        for (var dx = 0u; dx < 2u; dx++) {
            let x = 2u * id.x + dx;
            let y = 2u * id.y + dy;
            if (x < fine && y < fine) {
                count += 1u;
                let src = source + (y * fine + x) * channels;
                for (var ch = 0u; ch < channels; ch++) {
                    basis[at + ch] += basis[src + ch];
                }
            }
        }
    }
    let w = 1.0 / f32(count);
    for (var ch = 0u; ch < channels; ch++) {
        basis[at + ch] *= w;
    }
}
