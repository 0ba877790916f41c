// Convolution soft shadow maps (Annen et al. 2008; the core's
// `shadow_fins::peers::convolution`): what the basis passes
// (`convolution_maps.wgsl`) and the per-pixel pass (`convolution.wgsl`) share.
#define_import_path bevy_shadow_fins::convolution_types

// One light frame's CSM constants (`ConvolutionUniform` in `render/convolution.rs`).
struct ConvolutionParams {
    // (order M, channels 1 + 4M, first stored mip level, mip levels of the full chain)
    counts: vec4<u32>,
    // (ringing scale α, depth shift δ, depth span, sharpening A)
    series: vec4<f32>,
    // (sharpening B, kernel half side x, kernel half side y, 1 rectangle light / 0 disk)
    kernel: vec4<f32>,
    // (mip bias: levels finer than the footprint's side, unused, unused, unused)
    lookup: vec4<f32>,
    // Per stored level: (resolution, offset in floats) in xy and zw of each
    // vec4 (levels 2i and 2i + 1).
    levels: array<vec4<u32>, 8>,
    // The basis of an empty texel (the far plane), channel by channel.
    empty: array<vec4<f32>, 17>,
}

// What the basis passes found: the nearest depth in the map (normalisation's near).
struct ConvolutionState {
    near: f32,
}

const PI: f32 = 3.14159265358979;

// c_k = π(2k − 1) (their eq. 10), k from 1.
fn c_k(k: u32) -> f32 {
    return PI * f32(2u * k - 1u);
}

fn level_resolution(p: ConvolutionParams, stored: u32) -> u32 {
    let v = p.levels[stored / 2u];
    return select(v.x, v.z, stored % 2u == 1u);
}

fn level_offset(p: ConvolutionParams, stored: u32) -> u32 {
    let v = p.levels[stored / 2u];
    return select(v.y, v.w, stored % 2u == 1u);
}

fn empty_channel(p: ConvolutionParams, ch: u32) -> f32 {
    return p.empty[ch / 4u][ch % 4u];
}
