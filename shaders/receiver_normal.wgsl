// The side of a surface a visibility pass shades: the fins' (`visibility.wgsl`)
// and the coverage method's (`coverage.wgsl`), which read Bevy's deferred
// G-buffer beside its prepasses.
//
// Bevy shades the back face of a double-sided material with the normal turned
// to the camera (`pbr_functions::prepare_world_normal`), and writes that
// normal to the G-buffer and to the forward prepass's normal. Its deferred
// prepass, though, writes the vertex normal unturned
// (`pbr_deferred_functions::deferred_output`): lifted along it, the receiver
// would sink behind its own card and shadow itself.
//
// The convolution and plateaus peers' passes do not import this module: with
// it in their shaders, lavapipe (Mesa 22.3) crashed running them (a segfault
// in its queue thread), whether or not they read the G-buffer, while these
// two passes run it fine; the cause was not found. Their deferred
// double-sided back faces keep the prepass normal, and shadow themselves.
#define_import_path bevy_shadow_fins::receiver_normal
#import bevy_shadow_fins::fin_view::prepass_normal
#import bevy_pbr::{
    pbr_deferred_types::{DEFERRED_MESH_FLAGS_SHADOW_RECEIVER_BIT, unpack_24bit_normal, unpack_flags},
    utils::octahedral_decode,
}

// The world normal of the side of the surface that Bevy shades at a pixel,
// from its prepass normal (`encoded_normal`) and its G-buffer texel. Where the
// G-buffer holds a shadow receiver, the G-buffer's normal decides the side,
// and the prepass normal stays the direction (no normal map, full
// precision). Anywhere else — a forward pixel, whose G-buffer texel is Bevy's
// clear value (0, 0, 0, 1) and whose prepass normal is on the side Bevy
// shades, or a camera without a G-buffer (`NoGBuffer`: zeros) — the prepass
// normal is it. (A deferred pixel that receives no shadow has no visibility
// to get right.) One known gap: with occlusion culling, a forward mesh drawn
// only in the late prepass, after the early deferred prepass, over a
// deferred receiver keeps that receiver's texel, for about a frame.
fn receiver_normal(encoded_normal: vec4<f32>, gbuffer: vec4<u32>) -> vec3<f32> {
    let n = prepass_normal(encoded_normal);
    if ((unpack_flags(gbuffer.a) & DEFERRED_MESH_FLAGS_SHADOW_RECEIVER_BIT) == 0u) {
        return n;
    }
    let shaded = octahedral_decode(unpack_24bit_normal(gbuffer.a));
    return select(n, -n, dot(n, shaded) < 0.0);
}

// Target pixel `pixel` clamped into a G-buffer of `size`: `NoGBuffer`'s one
// texel stands for every pixel (a load outside a texture is undefined).
fn clamped_to(size: vec2<u32>, pixel: vec2<i32>) -> vec2<i32> {
    return min(pixel, vec2<i32>(size) - 1);
}
