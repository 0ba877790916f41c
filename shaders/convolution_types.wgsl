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
    // (mip bias: levels finer than the footprint's side, 1 a tap off the map
    // reads its border (a window onto casters going on) / 0 the empty plane,
    // unused, unused)
    lookup: vec4<f32>,
    // Per stored level: (resolution, offset in floats) in xy and zw of each
    // vec4 (levels 2i and 2i + 1).
    levels: array<vec4<u32>, 8>,
    // The basis of an empty texel (the far plane), channel by channel.
    empty: array<vec4<f32>, 17>,
}

// What the basis passes found: the nearest depth in the map (its f32 bits;
// depths are ≥ 0, so their bits order as the depths), `+∞` for an empty map.
struct ConvolutionState {
    near_bits: u32,
}

// The far end of the depth normalisation, just past the deepest receiver
// `L0` (`ConvolutionModel`'s `far`).
fn far_depth(reference_depth: f32) -> f32 {
    return reference_depth * (1.0 + 1e-4);
}

// The near end: the map's nearest depth, or half the far end for an empty map.
fn near_depth(near_bits: u32, far: f32) -> f32 {
    let near = bitcast<f32>(near_bits);
    return select(far * 0.5, near, near < far);
}

// A depth normalised into [0, span] (an empty range reads 1, never NaN).
fn normalised(z: f32, near: f32, far: f32, span: f32) -> f32 {
    return clamp((z - near) / max(far - near, 1e-30), 0.0, 1.0) * span;
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
