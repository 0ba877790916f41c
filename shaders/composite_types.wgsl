// The fin-shadowed lights as the compositing pass and the forward hook read
// them (`CompositeLights` in `render/composite.rs`), and how to find a Bevy
// light of the view in them and them in the view's lists.
#define_import_path bevy_shadow_fins::composite_types

#import bevy_pbr::{mesh_view_bindings, mesh_view_types}

// Mirrors `FinLightUniform` in composite.rs.
struct FinLightUniform {
    // xyz: disk centre (world), w: radius.
    position_radius: vec4<f32>,
    // xyz: the direction the disk faces (into the scene), w: 1 / range².
    forward_inverse_square_range: vec4<f32>,
    // rgb: linear colour × luminous intensity (lm / 4π), as Bevy's lights.
    color: vec4<f32>,
};
// Mirrors `CompositeLight(s)` in composite.rs.
const KIND_OWN: u32 = 0u;
const KIND_BEVY: u32 = 1u;
const KIND_BEVY_DIRECTIONAL: u32 = 3u;
const KIND_BEVY_RECT: u32 = 4u;
const MAX_FIN_LIGHTS: u32 = 16u;
struct CompositeLight {
    own: FinLightUniform,
    // x: kind, y: Bevy's clustered light index, z: 1 when the layer was written.
    // A directional light's `own` holds its direction towards the light
    // (forward_inverse_square_range.xyz) and colour × illuminance (color); a
    // rectangle light's its position and width (position_radius) and height
    // (forward_inverse_square_range.w).
    info: vec4<u32>,
};
struct CompositeLights {
    // x: light slots in use, y: 1 while Bevy's own shadow maps of fin-shadowed lights are kept.
    count: vec4<u32>,
    lights: array<CompositeLight, MAX_FIN_LIGHTS>,
};
// The index in the view's directional lights of the fin-shadowed sun in
// `light`, or n_directional_lights when the view has none such: Bevy sorts
// its directional lights and leaves out those on render layers the view does
// not see, so the slot is found by what Bevy uploaded for it (the direction
// and colour the CPU read from Bevy's extracted light, exactly) and — unless
// Bevy's maps are kept — its shadow maps being off, as fin shadows turned them off.
fn bevy_directional_index(light: FinLightUniform, bevy_maps_kept: bool) -> u32 {
    let n = mesh_view_bindings::lights.n_directional_lights;
    for (var j = 0u; j < n; j += 1u) {
        let d = &mesh_view_bindings::lights.directional_lights[j];
        let shadowed = ((*d).flags & mesh_view_types::DIRECTIONAL_LIGHT_FLAGS_SHADOWS_ENABLED_BIT) != 0u;
        if ((bevy_maps_kept || !shadowed) && all((*d).direction_to_light == light.forward_inverse_square_range.xyz)
                && all((*d).color.rgb == light.color.rgb)) {
            return j;
        }
    }
    return n;
}

// The index in the view's rectangle lights of the fin-shadowed rectangle in
// `light`, or n_rect_lights when the view has none such: Bevy uploads at most
// eight, in its query's order, so the slot is found by what Bevy uploaded for
// it (position, width and height, as the CPU read them from Bevy's extracted
// light, exactly).
fn bevy_rect_index(light: FinLightUniform) -> u32 {
    let n = mesh_view_bindings::lights.n_rect_lights;
    for (var j = 0u; j < n; j += 1u) {
        let r = &mesh_view_bindings::lights.rect_lights[j];
        if (all((*r).position == light.position_radius.xyz) && (*r).width == light.position_radius.w
                && (*r).height == light.forward_inverse_square_range.w) {
            return j;
        }
    }
    return n;
}

