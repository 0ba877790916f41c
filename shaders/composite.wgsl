// Layered compositing (DESIGN §3 "Compositing"): Bevy's own deferred lighting
// of the G-buffer, then per fin-shadowed light its visibility layer V: a Bevy
// light, which Bevy just shaded with its own shadow S (1 when its map is off,
// as it is unless `BevyShadowMapsKept`), gets (V − S) of its own contribution,
// evaluated by Bevy's per-light function, so that V replaces S; a FinLight
// adds its direct contribution times V. It replaces Bevy's deferred lighting pass on
// fin-shadowed cameras, so the sum is exact before tonemapping, HDR or not.
//
// A FinLight is shaded exactly as Bevy shades a point light
// (`bevy_pbr::lighting::point_light`: representative-point specular with the
// light's radius, Burley diffuse, windowed inverse-square falloff), restricted
// to the half-space the disk faces, i.e. a `SpotLight` with a 90° cone.
#import bevy_pbr::{
    prepass_utils,
    pbr_types::{PbrInput, STANDARD_MATERIAL_FLAGS_UNLIT_BIT},
    pbr_functions,
    pbr_deferred_functions::pbr_input_from_deferred_gbuffer,
    lighting,
    mesh_types::MESH_FLAGS_SHADOW_RECEIVER_BIT,
    mesh_view_bindings::{deferred_prepass_texture, view},
    shadows,
}
#import bevy_pbr::{mesh_view_bindings, mesh_view_types, clustered_forward as clustering}
#import bevy_shadow_fins::composite_types::{
    FinLightUniform, CompositeLights, KIND_OWN, KIND_BEVY, KIND_BEVY_DIRECTIONAL, KIND_BEVY_RECT, MAX_FIN_LIGHTS,
    bevy_directional_index, bevy_rect_index,
}

#ifdef SCREEN_SPACE_AMBIENT_OCCLUSION
#import bevy_pbr::mesh_view_bindings::screen_space_ambient_occlusion_texture
#import bevy_pbr::ssao_utils::ssao_multibounce
#endif

struct FullscreenVertexOutput {
    @builtin(position) position: vec4<f32>,
    @location(0) uv: vec2<f32>,
};

// Bevy's deferred lighting pass id: the depth test selects the pixels whose
// material belongs to the default PBR lighting pass.
struct PbrDeferredLightingDepthId {
    depth_id: u32,
#ifdef SIXTEEN_BYTE_ALIGNMENT
    _webgl2_padding_0: f32,
    _webgl2_padding_1: f32,
    _webgl2_padding_2: f32,
#endif
}
@group(2) @binding(0) var<uniform> depth_id: PbrDeferredLightingDepthId;

@group(3) @binding(0) var fin_visibility: texture_2d_array<f32>;
@group(3) @binding(1) var<uniform> fin_lights: CompositeLights;

@vertex
fn vertex(@builtin(vertex_index) vertex_index: u32) -> FullscreenVertexOutput {
    let uv = vec2<f32>(f32(vertex_index >> 1u), f32(vertex_index & 1u)) * 2.0;
    // The depth is the pass id (u8 stored as unorm), compared for equality.
    let clip_position = vec4<f32>(uv * vec2<f32>(2.0, -2.0) + vec2<f32>(-1.0, 1.0), f32(depth_id.depth_id) / 255.0, 1.0);
    return FullscreenVertexOutput(clip_position, uv);
}

// The lighting input `apply_pbr_lighting` builds from a `PbrInput`.
fn lighting_input_of(in: PbrInput) -> lighting::LightingInput {
    let metallic = in.material.metallic;
    let perceptual_roughness = in.material.perceptual_roughness;
    let NdotV = max(dot(in.N, in.V), 0.0001);
    var input: lighting::LightingInput;
    input.layers[lighting::LAYER_BASE].NdotV = NdotV;
    input.layers[lighting::LAYER_BASE].N = in.N;
    input.layers[lighting::LAYER_BASE].R = reflect(-in.V, in.N);
    input.layers[lighting::LAYER_BASE].perceptual_roughness = perceptual_roughness;
    input.layers[lighting::LAYER_BASE].roughness = lighting::perceptualRoughnessToRoughness(perceptual_roughness);
    input.P = in.world_position.xyz;
    input.V = in.V;
    input.diffuse_color = pbr_functions::calculate_diffuse_color(
        in.material.base_color.rgb,
        metallic,
        in.material.specular_transmission,
        in.material.diffuse_transmission,
    );
    input.metallic = metallic;
    input.F0_dielectric = pbr_functions::calculate_F0_dielectric(in.material.reflectance);
    input.F0_metallic = in.material.base_color.rgb;
    input.F_ab = lighting::F_AB(perceptual_roughness, NdotV);
#ifdef STANDARD_MATERIAL_CLEARCOAT
    let clearcoat_N = in.clearcoat_N;
    input.layers[lighting::LAYER_CLEARCOAT].NdotV = max(dot(clearcoat_N, in.V), 0.0001);
    input.layers[lighting::LAYER_CLEARCOAT].N = clearcoat_N;
    input.layers[lighting::LAYER_CLEARCOAT].R = reflect(-in.V, clearcoat_N);
    input.layers[lighting::LAYER_CLEARCOAT].perceptual_roughness = in.material.clearcoat_perceptual_roughness;
    input.layers[lighting::LAYER_CLEARCOAT].roughness =
        lighting::perceptualRoughnessToRoughness(in.material.clearcoat_perceptual_roughness);
    input.clearcoat_strength = in.material.clearcoat;
#endif
    return input;
}

// Whether Bevy's lighting of this pixel went over clustered light `id`: the
// very list `apply_pbr_lighting` walks (point lights, then spot lights). A
// light Bevy did not add here — not yet clustered in its first frames, out of
// range, on render layers the view does not see — must not be taken away.
// The pixel's view-space z, as `apply_pbr_lighting` computes it.
fn view_z_of(in: PbrInput) -> f32 {
    return dot(vec4<f32>(
        view.view_from_world[0].z,
        view.view_from_world[1].z,
        view.view_from_world[2].z,
        view.view_from_world[3].z
    ), in.world_position);
}

fn bevy_lit_pixel_with(id: u32, in: PbrInput) -> bool {
    let cluster = clustering::view_fragment_cluster_index(in.frag_coord.xy, view_z_of(in), in.is_orthographic);
    let ranges = clustering::unpack_clusterable_object_index_ranges(cluster);
    for (var j = ranges.first_point_light_index_offset; j < ranges.first_reflection_probe_index_offset; j += 1u) {
        if (clustering::get_clusterable_object_id(j) == id) {
            return true;
        }
    }
    return false;
}

// `shadow` times Bevy's contact shadow towards `L` where Bevy applies one
// (`apply_pbr_lighting`: the view has contact shadows, the light enables
// them, the pixel is not already fully shadowed).
fn with_bevy_contact_shadow(shadow: f32, in: PbrInput, L: vec3<f32>, light_enables: bool) -> f32 {
#ifdef CONTACT_SHADOWS
#ifdef DEPTH_PREPASS
    let steps = mesh_view_bindings::contact_shadows_settings.linear_steps;
    if (steps > 0u && shadow > 0.0 && light_enables) {
        return shadow * pbr_functions::calculate_contact_shadow(in.world_position.xyz, in.frag_coord.xy, L, steps);
    }
#endif
#endif
    return shadow;
}

// Bevy's own shadow S of clustered light `id` at this pixel, exactly as
// `apply_pbr_lighting` computes it (its shadow map, then its contact shadow):
// 1 when the light's flags say both are off, as fin shadows turn them off
// unless Bevy's maps are kept for other cameras or unreached receivers.
fn bevy_clustered_shadow(id: u32, in: PbrInput) -> f32 {
    if ((in.flags & MESH_FLAGS_SHADOW_RECEIVER_BIT) == 0u) {
        return 1.0;
    }
    let light = &mesh_view_bindings::clustered_lights.data[id];
    var shadow = 1.0;
    if (((*light).flags & mesh_view_types::POINT_LIGHT_FLAGS_SHADOWS_ENABLED_BIT) != 0u) {
        if (((*light).flags & mesh_view_types::POINT_LIGHT_FLAGS_SPOT_LIGHT_BIT) != 0u) {
            shadow = shadows::fetch_spot_shadow(id, in.world_position, in.world_normal, (*light).shadow_map_near_z,
                in.frag_coord.xy);
        } else {
            shadow = shadows::fetch_point_shadow(id, in.world_position, in.world_normal, in.frag_coord.xy);
        }
    }
    let contact = ((*light).flags & mesh_view_types::POINT_LIGHT_FLAGS_CONTACT_SHADOWS_ENABLED_BIT) != 0u;
    return with_bevy_contact_shadow(shadow, in, normalize((*light).position_radius.xyz - in.world_position.xyz),
        contact);
}

// The same for directional light `j` of the view.
fn bevy_directional_shadow(j: u32, in: PbrInput) -> f32 {
    if ((in.flags & MESH_FLAGS_SHADOW_RECEIVER_BIT) == 0u) {
        return 1.0;
    }
    let light = &mesh_view_bindings::lights.directional_lights[j];
    var shadow = 1.0;
    if (((*light).flags & mesh_view_types::DIRECTIONAL_LIGHT_FLAGS_SHADOWS_ENABLED_BIT) != 0u) {
        shadow = shadows::fetch_directional_shadow(j, in.world_position, in.world_normal, view_z_of(in),
            in.frag_coord.xy);
    }
    let contact = ((*light).flags & mesh_view_types::DIRECTIONAL_LIGHT_FLAGS_CONTACT_SHADOWS_ENABLED_BIT) != 0u;
    return with_bevy_contact_shadow(shadow, in, (*light).direction_to_light, contact);
}

// A FinLight's unshadowed direct light at the surface (before exposure):
// `lighting::point_light` with the light's values from our uniform.
fn fin_light_direct(input: ptr<function, lighting::LightingInput>, fin_light: FinLightUniform) -> vec3<f32> {
    let P = (*input).P;
    let N = (*input).layers[lighting::LAYER_BASE].N;
    let V = (*input).V;
    let radius = fin_light.position_radius.w;
    let light_to_frag = fin_light.position_radius.xyz - P;
    let L = normalize(light_to_frag);
    let distance_square = dot(light_to_frag, light_to_frag);
    let distance = sqrt(distance_square);
    let range_attenuation = lighting::getDistanceAttenuation(distance_square, fin_light.forward_inverse_square_range.w);

    let a = (*input).layers[lighting::LAYER_BASE].roughness;
    let spec = lighting::compute_specular_layer_values_for_point_light(
        input, lighting::LAYER_BASE, V, light_to_frag, radius, distance);
    var specular_derived = lighting::derive_lighting_input(N, V, spec.xyz);
    let normalization = a / spec.w;
    let brdf_roughness = mix(a, spec.w, lighting::specular_fix_remap(a));
    var specular_light = lighting::specular(input, &specular_derived, brdf_roughness, normalization * normalization);
    if radius > 0.0 {
        let solid_angle = radius * radius / distance_square;
        specular_light *= saturate(specular_derived.NdotL / max(specular_derived.NdotL + solid_angle, 1e-4));
    }

    var derived = lighting::derive_lighting_input(N, V, L);
    let diffuse = (*input).diffuse_color * lighting::Fd_Burley(input, &derived);

#ifdef STANDARD_MATERIAL_CLEARCOAT
    let clearcoat_N = (*input).layers[lighting::LAYER_CLEARCOAT].N;
    let clearcoat_a = (*input).layers[lighting::LAYER_CLEARCOAT].roughness;
    let cc = lighting::compute_specular_layer_values_for_point_light(
        input, lighting::LAYER_CLEARCOAT, V, light_to_frag, radius, distance);
    var cc_derived = lighting::derive_lighting_input(clearcoat_N, V, cc.xyz);
    let cc_normalization = clearcoat_a / cc.w;
    let Fc_Frc = lighting::specular_clearcoat(
        input,
        &cc_derived,
        (*input).clearcoat_strength,
        mix(clearcoat_a, cc.w, lighting::specular_fix_remap(clearcoat_a)),
        cc_normalization * cc_normalization,
    );
    let inv_Fc = 1.0 - Fc_Frc.r;
    var Frc = Fc_Frc.g;
    if radius > 0.0 {
        let solid_angle = radius * radius / distance_square;
        Frc *= saturate(cc_derived.NdotL / max(cc_derived.NdotL + solid_angle, 1e-4));
    }
    let color_times_NdotL = (diffuse * derived.NdotL + specular_light * specular_derived.NdotL * inv_Fc) * inv_Fc
        + Frc * cc_derived.NdotL;
#else
    let color_times_NdotL = diffuse * derived.NdotL + specular_light * specular_derived.NdotL;
#endif

    // One-sided disk: only the half-space in front of it (a spot light whose
    // inner and outer angles are both 90°).
    let facing = saturate(dot(fin_light.forward_inverse_square_range.xyz, -L) * 1e4);
    return color_times_NdotL * fin_light.color.rgb * range_attenuation * facing * facing;
}

@fragment
fn fragment(in: FullscreenVertexOutput) -> @location(0) vec4<f32> {
    var frag_coord = vec4(in.position.xy, 0.0, 0.0);
    let deferred_data = textureLoad(deferred_prepass_texture, vec2<i32>(frag_coord.xy), 0);
#ifdef DEPTH_PREPASS
    frag_coord.z = prepass_utils::prepass_depth(in.position, 0u);
#endif
    var pbr_input = pbr_input_from_deferred_gbuffer(frag_coord, deferred_data);
    var output_color = vec4(0.0);
    if ((pbr_input.material.flags & STANDARD_MATERIAL_FLAGS_UNLIT_BIT) == 0u) {
#ifdef SCREEN_SPACE_AMBIENT_OCCLUSION
        let ssao = textureLoad(screen_space_ambient_occlusion_texture, vec2<i32>(in.position.xy), 0i).r;
        let ssao_multibounce = ssao_multibounce(ssao, pbr_input.material.base_color.rgb);
        pbr_input.diffuse_occlusion = min(pbr_input.diffuse_occlusion, ssao_multibounce);
        let NdotV = max(dot(pbr_input.N, pbr_input.V), 0.0001);
        let roughness = lighting::perceptualRoughnessToRoughness(pbr_input.material.perceptual_roughness);
        pbr_input.specular_occlusion = saturate(pow(NdotV + ssao, exp2(-16.0 * roughness - 1.0)) - 1.0 + ssao);
#endif
        output_color = pbr_functions::apply_pbr_lighting(pbr_input);

        let receiver = (pbr_input.flags & MESH_FLAGS_SHADOW_RECEIVER_BIT) != 0u;
        var input = lighting_input_of(pbr_input);
        var change = vec3(0.0);
        let bevy_maps_kept = fin_lights.count.y != 0u;
        for (var i = 0u; i < min(fin_lights.count.x, MAX_FIN_LIGHTS); i += 1u) {
            let light = fin_lights.lights[i];
            if (light.info.z == 0u) {
                continue;
            }
            // V from the visibility pass; 1 on meshes that do not receive shadows.
            var visibility = textureLoad(fin_visibility, vec2<i32>(in.position.xy), i32(i), 0).r;
            if (!receiver) {
                visibility = 1.0;
            }
            // A NaN must never reach the screen; compared by its bits, since WGSL
            // lets implementations assume floats are never NaN.
            if ((bitcast<u32>(visibility) & 0x7fffffffu) > 0x7f800000u) {
                visibility = 0.0;
            }
            visibility = clamp(visibility, 0.0, 1.0);
            // With Bevy's maps off S is 1, and a fully lit pixel has nothing to change.
            let may_change = bevy_maps_kept || visibility < 1.0;
            if (light.info.x == KIND_OWN) {
                change += visibility * fin_light_direct(&input, light.own);
            } else if (light.info.x == KIND_BEVY && may_change && bevy_lit_pixel_with(light.info.y, pbr_input)) {
                // Bevy added this light times S; clustered lights past the
                // point lights are spot lights (`first_spot_light_index_offset`).
                let shadow = bevy_clustered_shadow(light.info.y, pbr_input);
                if (visibility != shadow) {
                    let flags = mesh_view_bindings::clustered_lights.data[light.info.y].flags;
                    var bevy_light: vec3<f32>;
                    if ((flags & mesh_view_types::POINT_LIGHT_FLAGS_SPOT_LIGHT_BIT) != 0u) {
                        bevy_light = lighting::spot_light(light.info.y, &input, true);
                    } else {
                        bevy_light = lighting::point_light(light.info.y, &input, true, true);
                    }
                    change += (visibility - shadow) * bevy_light;
                }
            } else if (light.info.x == KIND_BEVY_DIRECTIONAL && may_change) {
                let j = bevy_directional_index(light.own, bevy_maps_kept);
                if (j < mesh_view_bindings::lights.n_directional_lights) {
                    let shadow = bevy_directional_shadow(j, pbr_input);
                    if (visibility != shadow) {
                        change += (visibility - shadow) * lighting::directional_light(j, &input, true);
                    }
                }
            }
#ifdef AREA_LIGHT_LUTS
            // Bevy gives a rectangle light no shadow: S is 1.
            else if (light.info.x == KIND_BEVY_RECT && visibility < 1.0) {
                let j = bevy_rect_index(light.own);
                if (j < mesh_view_bindings::lights.n_rect_lights) {
                    change -= (1.0 - visibility) * lighting::rect_light(j, &input, true);
                }
            }
#endif
        }
        // Never below black: what is taken away is at most what Bevy added.
        output_color = vec4(max(output_color.rgb + view.exposure * change, vec3(0.0)), output_color.a);
    } else {
        output_color = pbr_input.material.base_color;
    }
    return pbr_functions::main_pass_post_lighting_processing(pbr_input, output_color);
}
