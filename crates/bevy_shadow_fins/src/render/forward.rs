//! Fin shadows on forward-rendered `StandardMaterial`s (opaque and
//! alpha-masked), inside Bevy's own forward PBR shading.
//!
//! The compositing pass reaches deferred pixels through the G-buffer; a
//! forward material's BRDF inputs never leave its fragment shader, so the
//! fin shadow must be applied there. How, without a copy of Bevy's shaders:
//! - **WGSL**: `shaders/forward_hook.wgsl` overrides (naga_oil `override fn`)
//!   Bevy's per-light functions `lighting::point_light`, `spot_light`,
//!   `directional_light`, `rect_light` — times the light's visibility
//!   layer V at the fragment's pixel — and `shadows::fetch_*_shadow` — 1 for
//!   a fin-shadowed light, so V replaces Bevy's shadow S as the compositing
//!   pass makes it do; and `pbr_functions::apply_pbr_lighting` and
//!   `prepare_world_normal`, to know the surface being lit and to turn a
//!   deferred alpha-masked back face's prepass normal (`on_the_shaded_side`).
//!   The module is added to the imports of Bevy's
//!   `bevy_pbr::pbr_fragment` shader asset at run time (Bevy's text is not
//!   copied or edited: one import is added), and is empty unless a pipeline
//!   has the shader def `FIN_FORWARD`. Overriding a function Bevy did not
//!   declare `virtual` needs naga_oil's `override_any` feature, which this
//!   crate enables (it only lifts that check).
//! - **Pipelines**: every `StandardMaterial` whose main pass is opaque or
//!   alpha-masked gets, as Bevy prepares it, a specialisation that calls
//!   Bevy's own and adds `FIN_FORWARD` and bind group 4 (the compositing
//!   pass's: the visibility layers and the fin lights), and draw functions
//!   that set group 4 — the view's layers on a [`FinShadowView`] camera, a
//!   dummy of no light elsewhere, where Bevy's shading is untouched.
//!
//! What a Bevy upgrade can break, and the tests that would say so
//! (`tests/render/forward.rs`, `alpha_masked.rs`): the signatures of those nine WGSL functions,
//! `MaterialProperties`' public fields and the main pass's draw-function
//! labels. Five bind groups are needed (a device with fewer keeps the
//! forward limitation: Bevy's shadow, said once). Alpha-blended and
//! transmissive materials are drawn after the opaque passes over pixels the
//! visibility pass shaded for the surface behind them: they keep Bevy's
//! shadow (while its maps are kept) — documented, counted in
//! [`FinReceivers`](crate::FinReceivers).
//!
//! [`FinShadowView`]: crate::FinShadowView

use std::any::Any;

use bevy::asset::UntypedAssetId;
use bevy::{
    core_pipeline::core_3d::{AlphaMask3d, Opaque3d},
    ecs::system::{SystemParamItem, lifetimeless::SRes},
    material::{
        MaterialProperties, RenderPhaseType, key::ErasedMaterialPipelineKey, labels::DrawFunctionLabel,
        specialize::SpecializedMeshPipelineError,
    },
    mesh::MeshVertexBufferLayoutRef,
    pbr::{
        DrawMesh, MainPassAlphaMaskDrawFunction, MainPassOpaqueDrawFunction, Material, MaterialPipeline,
        MaterialPipelineKey, MeshPipelineKey, PreparedMaterial, SetMaterialBindGroup, SetMeshBindGroup,
        SetMeshViewBindGroup, SetMeshViewBindingArrayBindGroup, StandardMaterial, StandardMaterialKey,
    },
    prelude::*,
    render::{
        Render, RenderApp, RenderSystems,
        erased_render_asset::{ErasedRenderAssets, prepare_erased_assets},
        render_phase::{
            AddRenderCommand, DrawFunctions, PhaseItem, RenderCommand, RenderCommandResult, SetItemPipeline,
            TrackedRenderPass,
        },
        render_resource::*,
        renderer::RenderDevice,
    },
    shader::{Shader, ShaderDefVal, ShaderImport},
};
use naga_oil::compose::ImportDefinition;

use crate::forward_hook::{FinForwardShading, PbrFragment};
use crate::render::composite::{FinCompositeBindGroup, light_layout};

/// The import path of `shaders/forward_hook.wgsl`.
const HOOK: &str = "bevy_shadow_fins::forward_hook";

/// Bevy's forward fragment library, which the hook is imported into.
const PBR_FRAGMENT: &str = "embedded://bevy_pbr/render/pbr_fragment.wgsl";

/// The bind group the hook reads.
const FIN_GROUP: usize = 4;

pub(crate) fn build(app: &mut App) {
    bevy::shader::load_shader_library!(app, "shaders/forward_hook.wgsl");
    bevy::shader::load_shader_library!(app, "shaders/composite_types.wgsl");
}

pub(crate) fn finish(app: &mut App) {
    let Some(render_app) = app.get_sub_app_mut(RenderApp) else { return };
    let groups = render_app.world().get_resource::<RenderDevice>().map_or(0, |d| d.limits().max_bind_groups);
    if (groups as usize) <= FIN_GROUP {
        warn!(
            "fin shadows: this device binds {groups} groups; forward-rendered materials keep Bevy's shadows \
             (fin shadows need 5 there; deferred materials have them)"
        );
        app.insert_resource(FinForwardShading(false));
        return;
    }
    render_app
        .add_render_command::<Opaque3d, DrawMaterialWithFinShadows>()
        .add_render_command::<AlphaMask3d, DrawMaterialWithFinShadows>()
        .add_systems(bevy::render::RenderStartup, init_fallback)
        .add_systems(
            Render,
            use_fin_pipelines
                .in_set(RenderSystems::PrepareAssets)
                .after(prepare_erased_assets::<MeshMaterial3d<StandardMaterial>>),
        );
    let handle = app.world().resource::<AssetServer>().load::<Shader>(PBR_FRAGMENT);
    // On once the hook is in Bevy's shader (`import_hook_into_pbr_fragment`).
    app.insert_resource(PbrFragment(handle))
        .insert_resource(FinForwardShading(false))
        .add_systems(PostUpdate, import_hook_into_pbr_fragment.run_if(resource_exists::<PbrFragment>));
}

/// Adds the hook to `bevy_pbr::pbr_fragment`'s imports once it is loaded
/// (again if Bevy reloads it): naga_oil composes a module's
/// `additional_imports`, whose overrides then apply to every shader that
/// imports `pbr_fragment` (Bevy's `imports` list makes the shader cache
/// load the hook first).
///
/// Until it is in, `FinForwardShading` is off (forward meshes keep Bevy's
/// maps); if Bevy's shader is not where this Bevy version keeps it, that is
/// said once and the forward path stays Bevy's.
fn import_hook_into_pbr_fragment(
    mut commands: Commands,
    fragment: Res<PbrFragment>,
    asset_server: Res<AssetServer>,
    mut shaders: ResMut<Assets<Shader>>,
    mut forward: ResMut<FinForwardShading>,
    mut frames: Local<u32>,
) {
    let hooked = |s: &Shader| s.additional_imports.iter().any(|i| i.import == HOOK);
    match shaders.get(&fragment.0) {
        Some(shader) if hooked(shader) => {
            if !forward.0 {
                forward.0 = true;
            }
        }
        Some(_) => {
            if let Some(mut shader) = shaders.get_mut(&fragment.0) {
                shader.imports.push(ShaderImport::Custom(HOOK.into()));
                shader.additional_imports.push(ImportDefinition { import: HOOK.into(), items: vec![] });
            }
        }
        None => {
            *frames += 1;
            if asset_server.load_state(&fragment.0).is_failed() || *frames >= 600 {
                warn!(
                    "fin shadows: Bevy's forward shader {PBR_FRAGMENT} is not there to hook; forward-rendered \
                     materials keep Bevy's shadows (deferred ones have fin shadows)"
                );
                commands.remove_resource::<PbrFragment>();
            }
        }
    }
}

/// Bevy's `DrawMaterial` with the fin shadows' group 4.
type DrawMaterialWithFinShadows = (
    SetItemPipeline,
    SetMeshViewBindGroup<0>,
    SetMeshViewBindingArrayBindGroup<1>,
    SetMeshBindGroup<2>,
    SetMaterialBindGroup<3>,
    SetFinShadowsBindGroup<FIN_GROUP>,
    DrawMesh,
);

/// Group 4 for views without fin shadows: no light, one lit layer.
#[derive(Resource)]
struct FallbackFinGroup(BindGroup);

fn init_fallback(mut commands: Commands, device: Res<RenderDevice>, pipeline_cache: Res<PipelineCache>) {
    let texture = device.create_texture(&TextureDescriptor {
        label: Some("fin_forward_fallback_visibility"),
        size: Extent3d { width: 1, height: 1, depth_or_array_layers: 1 },
        mip_level_count: 1,
        sample_count: 1,
        dimension: TextureDimension::D2,
        format: TextureFormat::R32Float,
        usage: TextureUsages::TEXTURE_BINDING,
        view_formats: &[],
    });
    let view =
        texture.create_view(&TextureViewDescriptor { dimension: Some(TextureViewDimension::D2Array), ..default() });
    // Zero lights: the hook finds no slot and leaves Bevy's shading alone.
    let uniform = device.create_buffer_with_data(&BufferInitDescriptor {
        label: Some("fin_forward_fallback_lights"),
        contents: &vec![0u8; crate::render::composite::COMPOSITE_LIGHTS_BYTES],
        usage: BufferUsages::UNIFORM,
    });
    let bind_group = device.create_bind_group(
        "fin_forward_fallback",
        &pipeline_cache.get_bind_group_layout(&light_layout()),
        &BindGroupEntries::sequential((&view, uniform.as_entire_binding())),
    );
    commands.insert_resource(FallbackFinGroup(bind_group));
}

/// Sets group 4: the view's visibility layers and fin lights (the
/// compositing pass's bind group), or the fallback of no light.
struct SetFinShadowsBindGroup<const I: usize>;

impl<P: PhaseItem, const I: usize> RenderCommand<P> for SetFinShadowsBindGroup<I> {
    type Param = SRes<FallbackFinGroup>;
    type ViewQuery = Option<&'static FinCompositeBindGroup>;
    type ItemQuery = ();

    fn render<'w>(
        _item: &P,
        view: Option<&'w FinCompositeBindGroup>,
        _entity: Option<()>,
        fallback: SystemParamItem<'w, '_, Self::Param>,
        pass: &mut TrackedRenderPass<'w>,
    ) -> RenderCommandResult {
        let group = match view {
            Some(view) => &view.bind_group,
            None => &fallback.into_inner().0,
        };
        pass.set_bind_group(I, group, &[]);
        RenderCommandResult::Success
    }
}

/// Gives every prepared opaque or alpha-masked `StandardMaterial` the fin
/// shadows' specialisation and draw functions (before Bevy specialises its
/// pipelines this frame: a pipeline and its draw function must agree on
/// group 4).
fn use_fin_pipelines(
    mut materials: ResMut<ErasedRenderAssets<PreparedMaterial>>,
    opaque: Res<DrawFunctions<Opaque3d>>,
    alpha_mask: Res<DrawFunctions<AlphaMask3d>>,
    // The properties given to each material: a material whose properties are
    // not these any more was prepared again by Bevy.
    mut given: Local<std::collections::HashMap<UntypedAssetId, std::sync::Arc<MaterialProperties>>>,
) {
    let standard = std::any::TypeId::of::<StandardMaterial>();
    let (opaque, alpha_mask) =
        (opaque.read().id::<DrawMaterialWithFinShadows>(), alpha_mask.read().id::<DrawMaterialWithFinShadows>());
    given.retain(|id, _| materials.get(*id).is_some());
    for (id, material) in materials.iter_mut() {
        let p = &material.properties;
        let wanted = matches!(p.render_phase_type, RenderPhaseType::Opaque | RenderPhaseType::AlphaMask);
        let ours = given.get(&id).is_some_and(|g| std::sync::Arc::ptr_eq(g, p));
        if id.type_id() != standard || !wanted || ours {
            continue;
        }
        let mut draw_functions = p.draw_functions.clone();
        for (label, function) in draw_functions.iter_mut() {
            if *label == MainPassOpaqueDrawFunction.intern() {
                *function = opaque;
            } else if *label == MainPassAlphaMaskDrawFunction.intern() {
                *function = alpha_mask;
            }
        }
        material.properties = std::sync::Arc::new(MaterialProperties {
            render_method: p.render_method,
            alpha_mode: p.alpha_mode,
            mesh_pipeline_key_bits: p.mesh_pipeline_key_bits,
            depth_bias: p.depth_bias,
            reads_view_transmission_texture: p.reads_view_transmission_texture,
            render_phase_type: p.render_phase_type,
            material_layout: p.material_layout.clone(),
            draw_functions,
            shaders: p.shaders.clone(),
            bindless: p.bindless,
            base_specialize: p.base_specialize,
            prepass_specialize: p.prepass_specialize,
            user_specialize: Some(specialize_with_fin_shadows),
            material_key: p.material_key.clone(),
            shadows_enabled: p.shadows_enabled,
            prepass_enabled: p.prepass_enabled,
        });
        given.insert(id, material.properties.clone());
    }
}

/// Bevy's `StandardMaterial` specialisation, then `FIN_FORWARD` and group 4.
fn specialize_with_fin_shadows(
    pipeline: &dyn Any,
    descriptor: &mut RenderPipelineDescriptor,
    layout: &MeshVertexBufferLayoutRef,
    key: ErasedMaterialPipelineKey,
) -> Result<(), SpecializedMeshPipelineError> {
    // Bevy's own `user_specialize` does the same: the material pipeline is
    // what Bevy's specialiser always passes.
    let pipeline = pipeline.downcast_ref::<MaterialPipeline>().expect("Bevy passes its MaterialPipeline");
    let key = MaterialPipelineKey::<StandardMaterial> {
        mesh_key: key.mesh_key.downcast::<MeshPipelineKey>(),
        bind_group_data: key.material_key.to_key::<StandardMaterialKey>(),
    };
    <StandardMaterial as Material>::specialize(pipeline, descriptor, layout, key)?;
    // Bevy calls the same specialisation for the material's prepass
    // pipelines (marked by the shader def Bevy's prepass sets), which draw
    // without group 4: only the main pass gets it.
    let prepass = descriptor
        .vertex
        .shader_defs
        .iter()
        .any(|d| matches!(d, ShaderDefVal::Bool(name, true) if name == "PREPASS_PIPELINE"));
    if !prepass && descriptor.layout.len() == FIN_GROUP {
        descriptor.layout.push(light_layout());
        if let Some(fragment) = descriptor.fragment.as_mut() {
            fragment.shader_defs.push(ShaderDefVal::Bool("FIN_FORWARD".into(), true));
        }
    }
    Ok(())
}
