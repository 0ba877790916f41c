// Fin shadows on forward-rendered materials: hooked into Bevy's own forward
// PBR shading (`render/forward.rs` adds this module to `bevy_pbr::pbr_fragment`'s
// imports, and the shader def `FIN_FORWARD` and bind group 4 to the main-pass
// pipelines of opaque and alpha-masked `StandardMaterial`s). Without the def
// the module is empty: every other shader that imports `pbr_fragment` — the
// prepasses, Bevy's deferred lighting, the plugin's own compositing pass — is
// untouched.
//
// With it, naga_oil overrides redirect `apply_pbr_lighting`'s calls: a
// fin-shadowed Bevy light's direct contribution is multiplied by its
// visibility layer V at the fragment's pixel (`lighting::point_light`,
// `spot_light`, `directional_light`, `rect_light`), and
// Bevy's own shadow of it — computed while its maps are kept for cameras or
// receivers fin shadows do not reach — is 1 (`shadows::fetch_*_shadow`): V
// replaces S, as the compositing pass does for deferred pixels. A light
// without a layer this frame (not fin-shadowed, no fin view, its passes not
// ready) keeps Bevy's shading and shadow bit for bit. Two differences from
// the deferred path, both only while Bevy's maps are kept for other cameras
// or unreached receivers: Bevy's contact shadow of the light (applied after
// `fetch_*_shadow`, which these overrides cannot reach) still darkens
// contacts, and a fin-shadowed sun's fog in-scattering is unshadowed.
#define_import_path bevy_shadow_fins::forward_hook

#ifdef FIN_FORWARD
#import bevy_pbr::{lighting, shadows, mesh_view_bindings, mesh_view_types, pbr_functions, pbr_types}
#import bevy_pbr::mesh_types::MESH_FLAGS_SHADOW_RECEIVER_BIT
#import bevy_shadow_fins::composite_types::{
    CompositeLights, KIND_BEVY, KIND_BEVY_DIRECTIONAL, KIND_BEVY_RECT, MAX_FIN_LIGHTS, bevy_directional_index,
    bevy_rect_index,
}

@group(4) @binding(0) var fin_visibility: texture_2d_array<f32>;
@group(4) @binding(1) var<uniform> fin_lights: CompositeLights;

// No slot.
const NONE: u32 = 0xffffffffu;

// What `apply_pbr_lighting` is shading: whether the mesh receives shadows
// (`NotShadowReceiver`, `NotFinShadowReceiver`: no fin shadow, as the
// compositing pass gives it none) and the surface point the visibility pass
// shaded. A light evaluated elsewhere — the diffuse-transmission lobe, inside
// the mesh — gets no V (and, with its Bevy shadow made 1, no shadow there).
var<private> fin_receiver: bool = false;
var<private> fin_surface: vec3<f32>;

override fn pbr_functions::apply_pbr_lighting(in: pbr_types::PbrInput) -> vec4<f32> {
    fin_receiver = (in.flags & MESH_FLAGS_SHADOW_RECEIVER_BIT) != 0u;
    fin_surface = in.world_position.xyz;
    return pbr_functions::apply_pbr_lighting(on_the_shaded_side(in));
}

// Whether the fragment is a double-sided material's back face, and its
// vertex normal before Bevy turns it, as Bevy's `prepare_world_normal` is
// told (once, by `pbr_input_from_vertex_output`, before the lighting).
var<private> fin_back_face: bool = false;
var<private> fin_vertex_normal: vec3<f32>;

override fn pbr_functions::prepare_world_normal(world_normal: vec3<f32>, double_sided: bool, is_front: bool) -> vec3<f32> {
    fin_back_face = double_sided && !is_front;
    fin_vertex_normal = world_normal;
    return pbr_functions::prepare_world_normal(world_normal, double_sided, is_front);
}

// `in` with N on the side of the surface Bevy shades. An alpha-masked
// material drawn deferred is drawn again by Bevy 0.19 in its main pass,
// where, with the normal prepass that `FinShadowView` adds, N is loaded from
// it (`LOAD_PREPASS_NORMALS`): the deferred prepass's normal, the vertex
// normal never turned to the camera on a double-sided back face
// (`pbr_deferred_functions::deferred_output`), so the face would read as
// facing away from every light (a lit leaf's back drawn dark). There N is
// turned, as Bevy turns it everywhere else. Which prepass wrote N is told by
// N itself, not by a shader def (a pipeline of a forward and one of a
// deferred material can be the same cached pipeline): on a back face the
// forward prepass's N is turned (`pbr_prepass.wgsl`, its normal map
// included), against the vertex normal; the deferred prepass's is the
// vertex normal.
fn on_the_shaded_side(in: pbr_types::PbrInput) -> pbr_types::PbrInput {
    var out = in;
#ifdef LOAD_PREPASS_NORMALS
    if (fin_back_face && dot(in.N, fin_vertex_normal) > 0.0) {
        out.N = -in.N;
    }
#endif
    return out;
}

// Whether V applies to a light evaluated at `p`: a receiving mesh's own surface.
fn fin_applies(p: vec3<f32>) -> bool {
    return fin_receiver && all(p == fin_surface);
}

// The slot (= visibility layer) of a fin-shadowed light, written this frame,
// of `kind` whose Bevy index is `id` — a clustered light's index in Bevy's
// list, or a directional or rectangle light's in the view's list, found by
// what Bevy uploaded for it as the compositing pass finds it.
fn fin_slot(kind: u32, id: u32) -> u32 {
    let kept = fin_lights.count.y != 0u;
    for (var i = 0u; i < min(fin_lights.count.x, MAX_FIN_LIGHTS); i += 1u) {
        let light = fin_lights.lights[i];
        if (light.info.z == 0u || light.info.x != kind) {
            continue;
        }
        if (kind == KIND_BEVY && light.info.y == id) {
            return i;
        }
        if (kind == KIND_BEVY_DIRECTIONAL && bevy_directional_index(light.own, kept) == id) {
            return i;
        }
#ifdef AREA_LIGHT_LUTS
        if (kind == KIND_BEVY_RECT && bevy_rect_index(light.own) == id) {
            return i;
        }
#endif
    }
    return NONE;
}

// V of slot `slot` at the pixel world point `p` is drawn on (the fragment's
// own: a forward fragment that passed the depth test is the surface the
// visibility pass rebuilt from the depth prepass), clamped, never NaN.
fn fin_visibility_at(slot: u32, p: vec3<f32>) -> f32 {
    let view = mesh_view_bindings::view;
    let clip = view.clip_from_world * vec4<f32>(p, 1.0);
    let ndc = clip.xy / clip.w;
    let uv = vec2<f32>(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5);
    let size = vec2<i32>(textureDimensions(fin_visibility));
    let pixel = clamp(vec2<i32>(floor(view.viewport.xy + uv * view.viewport.zw)), vec2<i32>(0), size - 1);
    let v = textureLoad(fin_visibility, pixel, i32(slot), 0).r;
    if ((bitcast<u32>(v) & 0x7fffffffu) > 0x7f800000u) {
        return 0.0;
    }
    return clamp(v, 0.0, 1.0);
}

// A Bevy light's contribution `light` at the fragment, times V when it is
// the fin-shadowed light of `kind` and index `id` and V applies there.
fn fin_shadowed(light: vec3<f32>, kind: u32, id: u32, p: vec3<f32>) -> vec3<f32> {
    let slot = fin_slot(kind, id);
    if (slot == NONE || !fin_applies(p)) {
        return light;
    }
    return light * fin_visibility_at(slot, p);
}

// Point lights. Bevy's `spot_light` calls `point_light` too, and whether
// naga_oil redirects that call inside `bevy_pbr::lighting` is its business:
// a spot gets V in the `spot_light` override below, never here, so it gets
// it once either way.
override fn lighting::point_light(
    light_id: u32,
    input: ptr<function, lighting::LightingInput>,
    enable_diffuse: bool,
    enable_texture: bool,
) -> vec3<f32> {
    let light = lighting::point_light(light_id, input, enable_diffuse, enable_texture);
    let spot = (mesh_view_bindings::clustered_lights.data[light_id].flags
        & mesh_view_types::POINT_LIGHT_FLAGS_SPOT_LIGHT_BIT) != 0u;
    if (spot) {
        return light;
    }
    return fin_shadowed(light, KIND_BEVY, light_id, (*input).P);
}

override fn lighting::spot_light(
    light_id: u32,
    input: ptr<function, lighting::LightingInput>,
    enable_diffuse: bool,
) -> vec3<f32> {
    let light = lighting::spot_light(light_id, input, enable_diffuse);
    return fin_shadowed(light, KIND_BEVY, light_id, (*input).P);
}

override fn shadows::fetch_point_shadow(
    light_id: u32,
    frag_position: vec4<f32>,
    surface_normal: vec3<f32>,
    frag_coord_xy: vec2<f32>,
) -> f32 {
    if (fin_slot(KIND_BEVY, light_id) != NONE) {
        return 1.0;
    }
    return shadows::fetch_point_shadow(light_id, frag_position, surface_normal, frag_coord_xy);
}

override fn shadows::fetch_spot_shadow(
    light_id: u32,
    frag_position: vec4<f32>,
    surface_normal: vec3<f32>,
    near_z: f32,
    frag_coord_xy: vec2<f32>,
) -> f32 {
    if (fin_slot(KIND_BEVY, light_id) != NONE) {
        return 1.0;
    }
    return shadows::fetch_spot_shadow(light_id, frag_position, surface_normal, near_z, frag_coord_xy);
}

override fn lighting::directional_light(
    light_id: u32,
    input: ptr<function, lighting::LightingInput>,
    enable_diffuse: bool,
) -> vec3<f32> {
    let light = lighting::directional_light(light_id, input, enable_diffuse);
    return fin_shadowed(light, KIND_BEVY_DIRECTIONAL, light_id, (*input).P);
}

override fn shadows::fetch_directional_shadow(
    light_id: u32,
    frag_position: vec4<f32>,
    surface_normal: vec3<f32>,
    view_z: f32,
    frag_coord_xy: vec2<f32>,
) -> f32 {
    if (fin_slot(KIND_BEVY_DIRECTIONAL, light_id) != NONE) {
        return 1.0;
    }
    return shadows::fetch_directional_shadow(light_id, frag_position, surface_normal, view_z, frag_coord_xy);
}

#ifdef AREA_LIGHT_LUTS
// Bevy gives a rectangle light no shadow: V alone.
override fn lighting::rect_light(
    light_id: u32,
    input: ptr<function, lighting::LightingInput>,
    enable_diffuse: bool,
) -> vec3<f32> {
    let light = lighting::rect_light(light_id, input, enable_diffuse);
    return fin_shadowed(light, KIND_BEVY_RECT, light_id, (*input).P);
}
#endif
#endif
