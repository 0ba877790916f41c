//! Layered compositing: the fin light's direct light times the visibility
//! buffer, on top of everything else Bevy lights.
//!
//! On a fin-shadowed camera this pass takes the place of Bevy's deferred
//! lighting pass: it runs Bevy's own `apply_pbr_lighting` on the G-buffer (so
//! every Bevy light, probe, SSAO and fog is unchanged) and adds the fin light,
//! shaded by Bevy's point-light BRDF functions, times `V`. Doing both in one
//! pass keeps the sum exact before tonemapping, with HDR on or off. The
//! pipeline is Bevy's deferred lighting pipeline, specialised for the same
//! view key, with our shader and one more bind group.

use std::collections::{HashMap, HashSet};

use bevy::{
    asset::{embedded_asset, load_embedded_asset},
    core_pipeline::{
        core_3d::main_opaque_pass_3d,
        deferred::copy_lighting_id::DeferredLightingIdDepthTexture,
        prepass::DeferredPrepass,
        schedule::{Core3d, Core3dSystems},
    },
    pbr::{
        MeshPipelineKey, MeshViewBindGroup, ViewKeyCache,
        deferred::{
            DeferredLightingLayout, PbrDeferredLightingDepthId, SkipDeferredLighting, deferred_lighting,
            prepare_deferred_lighting_pipelines,
        },
    },
    prelude::*,
    render::{
        Render, RenderApp, RenderSystems,
        diagnostic::RecordDiagnostics,
        extract_component::ComponentUniforms,
        extract_resource::{ExtractResource, ExtractResourcePlugin},
        render_resource::{
            binding_types::{texture_2d, uniform_buffer_sized},
            *,
        },
        renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery},
        view::{ExtractedView, ViewTarget},
    },
    shader::Shader,
};

use super::FinViewTexture;
use crate::light::{FinLight, FinShadowView};

/// The fin light as the compositing shader reads it (`FinLightUniform` in
/// `composite.wgsl`); the same numbers Bevy's `GpuClusteredLight` holds.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct FinLightUniform {
    position_radius: [f32; 4],
    forward_inverse_square_range: [f32; 4],
    color: [f32; 4],
}

impl FinLightUniform {
    /// The uniform of `light` at `transform`; `None` when the transform has no
    /// finite position or direction (a zero scale, a NaN): no light rather than
    /// a NaN on screen. Negative or non-finite intensity, colour and range are
    /// clamped.
    pub(crate) fn new(light: &FinLight, transform: &GlobalTransform) -> Option<Self> {
        let position = transform.translation();
        let forward: Vec3 = (transform.affine().matrix3 * bevy::math::Vec3A::NEG_Z).try_normalize()?.into();
        if !position.is_finite() {
            return None;
        }
        let finite = |x: f32| if x.is_finite() { x.max(0.0) } else { 0.0 };
        // Lumens → luminous intensity, as Bevy does for point and spot lights.
        let intensity = finite(light.intensity) / (4.0 * std::f32::consts::PI);
        let color = LinearRgba::from(light.color);
        let range = finite(light.range).max(1e-6);
        Some(Self {
            position_radius: position.extend(light.effective_radius()).to_array(),
            forward_inverse_square_range: forward.extend(1.0 / (range * range)).to_array(),
            color: [
                finite(color.red) * intensity,
                finite(color.green) * intensity,
                finite(color.blue) * intensity,
                1.0,
            ],
        })
    }
}

/// The fin light's shading for this frame (`None` without a fin light).
#[derive(Resource, Clone, Default, ExtractResource)]
pub(crate) struct FinLightShading(pub Option<FinLightUniform>);

pub(crate) fn build(app: &mut App) {
    embedded_asset!(app, "composite.wgsl");
    app.init_resource::<FinLightShading>()
        .add_plugins(ExtractResourcePlugin::<FinLightShading>::default())
        .add_systems(PostUpdate, update_light_shading.after(TransformSystems::Propagate));
}

pub(crate) fn finish(app: &mut App) {
    let Some(render_app) = app.get_sub_app_mut(RenderApp) else { return };
    render_app
        .init_resource::<CompositedViews>()
        .add_systems(bevy::render::RenderStartup, init_composite)
        .add_systems(
            Render,
            (
                // Before Bevy decides whether to run its own lighting pass, and
                // before the resources and bind groups that follow from it.
                prepare_composite_pipelines
                    .in_set(RenderSystems::Prepare)
                    .before(prepare_deferred_lighting_pipelines)
                    .before(RenderSystems::PrepareResources),
                prepare_light_uniform.in_set(RenderSystems::PrepareResources),
                prepare_composite_bind_groups.in_set(RenderSystems::PrepareBindGroups),
            ),
        )
        .add_systems(
            Core3d,
            fin_composite
                .after(deferred_lighting)
                // SSR reads the lit image: it must see ours, not overwrite it.
                .before(bevy::pbr::screen_space_reflections)
                .before(main_opaque_pass_3d)
                .in_set(Core3dSystems::MainPass),
        );
}

/// The same light the fin frame uses: the first `FinLight`.
fn update_light_shading(lights: Query<(&FinLight, &GlobalTransform)>, mut shading: ResMut<FinLightShading>) {
    let next = lights.iter().next().and_then(|(light, transform)| FinLightUniform::new(light, transform));
    if shading.0 != next {
        shading.0 = next;
    }
}

/// Compositing pipelines per view key, the light's uniform buffer.
#[derive(Resource)]
struct FinCompositePipelines {
    shader: Handle<Shader>,
    light_layout: BindGroupLayoutDescriptor,
    specialized: HashMap<MeshPipelineKey, (CachedRenderPipelineId, BindGroupLayoutDescriptor)>,
    light: Option<Buffer>,
}

/// Loads the shader at startup, so the pipeline is ready as soon as a fin light appears.
fn init_composite(mut commands: Commands, asset_server: Res<AssetServer>) {
    commands.insert_resource(FinCompositePipelines {
        shader: load_embedded_asset!(asset_server.as_ref(), "composite.wgsl"),
        light_layout: light_layout(),
        specialized: HashMap::new(),
        light: None,
    });
}

/// Views whose compositing pass ran last frame: from the next frame on Bevy's
/// own deferred lighting pass is skipped for them. (Skipping only after we ran
/// once means a view is never left unlit while our pipeline compiles.)
#[derive(Resource, Default)]
struct CompositedViews(HashSet<Entity>);

/// The compositing pipeline of one view and the layout of Bevy's group 2.
#[derive(Component)]
pub struct FinCompositePipeline {
    id: CachedRenderPipelineId,
    pass_id_layout: BindGroupLayoutDescriptor,
}

#[derive(Component)]
pub struct FinCompositeBindGroup(BindGroup);

fn light_layout() -> BindGroupLayoutDescriptor {
    BindGroupLayoutDescriptor::new(
        "fin_composite_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::FRAGMENT,
            (texture_2d(TextureSampleType::Float { filterable: false }), uniform_buffer_sized(false, None)),
        ),
    )
}

#[allow(clippy::too_many_arguments)]
fn prepare_composite_pipelines(
    mut commands: Commands,
    pipeline_cache: Res<PipelineCache>,
    view_key_cache: Res<ViewKeyCache>,
    deferred_layout: Option<Res<DeferredLightingLayout>>,
    shading: Res<FinLightShading>,
    pipelines: Option<ResMut<FinCompositePipelines>>,
    mut composited: ResMut<CompositedViews>,
    views: Query<(Entity, &ExtractedView, Has<DeferredPrepass>), With<FinShadowView>>,
) {
    let Some(mut pipelines) = pipelines else { return };
    let pipelines = &mut *pipelines;
    let ran_last_frame = std::mem::take(&mut composited.0);
    for (entity, view, deferred) in &views {
        let key = view_key_cache.get(&view.retained_view_entity).copied();
        let (Some(layout), Some(key), true, true) = (deferred_layout.as_deref(), key, deferred, shading.0.is_some())
        else {
            if !deferred {
                warn_once!("fin shadows: the camera needs DeferredPrepass (FinShadowView adds it)");
            }
            commands.entity(entity).remove::<(FinCompositePipeline, SkipDeferredLighting)>();
            continue;
        };
        let (light_layout, shader) = (&pipelines.light_layout, &pipelines.shader);
        let (id, pass_id_layout) = pipelines
            .specialized
            .entry(key)
            .or_insert_with(|| {
                let mut descriptor = layout.specialize(key);
                let pass_id_layout = descriptor.layout[2].clone();
                descriptor.label = Some("fin_composite_pipeline".into());
                descriptor.layout.push(light_layout.clone());
                descriptor.vertex.shader = shader.clone();
                if let Some(fragment) = descriptor.fragment.as_mut() {
                    fragment.shader = shader.clone();
                }
                (pipeline_cache.queue_render_pipeline(descriptor), pass_id_layout)
            })
            .clone();
        let ready = pipeline_cache.get_render_pipeline(id).is_some();
        let mut e = commands.entity(entity);
        e.insert(FinCompositePipeline { id, pass_id_layout });
        if ran_last_frame.contains(&entity) && ready {
            e.insert(SkipDeferredLighting);
        } else {
            e.remove::<SkipDeferredLighting>();
        }
    }
}

fn prepare_light_uniform(
    shading: Res<FinLightShading>,
    pipelines: Option<ResMut<FinCompositePipelines>>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
) {
    let (Some(uniform), Some(mut pipelines)) = (shading.0, pipelines) else { return };
    let buffer = pipelines.light.get_or_insert_with(|| {
        device.create_buffer(&BufferDescriptor {
            label: Some("fin_light_uniform"),
            size: size_of::<FinLightUniform>() as u64,
            usage: BufferUsages::UNIFORM | BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    });
    queue.write_buffer(buffer, 0, bytemuck::bytes_of(&uniform));
}

fn prepare_composite_bind_groups(
    mut commands: Commands,
    device: Res<RenderDevice>,
    pipeline_cache: Res<PipelineCache>,
    pipelines: Option<Res<FinCompositePipelines>>,
    views: Query<(Entity, &FinViewTexture), With<FinCompositePipeline>>,
) {
    let Some(pipelines) = pipelines else { return };
    let (Some(light), layout) = (pipelines.light.as_ref(), &pipelines.light_layout) else { return };
    for (entity, texture) in &views {
        let bind_group = device.create_bind_group(
            "fin_composite_bind_group",
            &pipeline_cache.get_bind_group_layout(layout),
            &BindGroupEntries::sequential((&texture.0.default_view, light.as_entire_binding())),
        );
        commands.entity(entity).insert(FinCompositeBindGroup(bind_group));
    }
}

/// Per view: Bevy's deferred lighting plus `V ×` the fin light, into the view
/// target (only the pixels of materials in Bevy's default lighting pass).
#[allow(clippy::too_many_arguments)]
fn fin_composite(
    view: ViewQuery<(
        Entity,
        &MeshViewBindGroup,
        &ViewTarget,
        &DeferredLightingIdDepthTexture,
        &FinCompositePipeline,
        &FinCompositeBindGroup,
    )>,
    written: Res<super::ViewsWithVisibility>,
    pipeline_cache: Res<PipelineCache>,
    pass_ids: Res<ComponentUniforms<PbrDeferredLightingDepthId>>,
    mut composited: ResMut<CompositedViews>,
    mut ctx: RenderContext,
) {
    let (entity, mesh_view_bind_group, target, pass_id_depth, pipeline, bind_group) = view.into_inner();
    // Without this frame's visibility the buffer holds stale values: let
    // Bevy's own lighting show instead.
    if !written.0.contains(&entity) {
        return;
    }
    let Some(render_pipeline) = pipeline_cache.get_render_pipeline(pipeline.id) else { return };
    let Some(pass_id_binding) = pass_ids.uniforms().binding() else { return };
    let pass_id_bind_group = ctx.render_device().create_bind_group(
        "fin_composite_pass_id",
        &pipeline_cache.get_bind_group_layout(&pipeline.pass_id_layout),
        &BindGroupEntries::single(pass_id_binding),
    );
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    // An encoder-level span: pass-level timestamps are rarer on adapters.
    let span = diagnostics.time_span(ctx.command_encoder(), "fin_shadows/composite");
    let mut pass = ctx.begin_tracked_render_pass(RenderPassDescriptor {
        label: Some("fin_composite"),
        color_attachments: &[Some(target.get_color_attachment())],
        depth_stencil_attachment: Some(RenderPassDepthStencilAttachment {
            view: &pass_id_depth.texture.default_view,
            depth_ops: Some(Operations { load: LoadOp::Load, store: StoreOp::Discard }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    pass.set_render_pipeline(render_pipeline);
    pass.set_bind_group(0, &mesh_view_bind_group.main, &mesh_view_bind_group.main_offsets);
    pass.set_bind_group(1, &mesh_view_bind_group.binding_array, &[]);
    pass.set_bind_group(2, &pass_id_bind_group, &[]);
    pass.set_bind_group(3, &bind_group.0, &[]);
    pass.draw(0..3, 0..1);
    drop(pass);
    span.end(ctx.command_encoder());
    composited.0.insert(entity);
}
