//! Layered compositing: each fin-shadowed light's direct light times its
//! visibility layer, on top of everything else Bevy lights.
//!
//! On a fin-shadowed camera this pass takes the place of Bevy's deferred
//! lighting pass: it runs Bevy's own `apply_pbr_lighting` on the G-buffer (so
//! every Bevy light, probe, SSAO and fog is unchanged), then per fin light:
//! - a Bevy light (`SpotLight`, `DirectionalLight` or `RectLight` +
//!   `FinShadows`): Bevy has just shaded it times its own shadow `S` — 1 with
//!   its shadow map off, as it is unless [`crate::BevyShadowMapsKept`] (a
//!   `RectLight` has none) —; the pass adds `(V − S)` of it, so `V` replaces `S`,
//!   evaluated by Bevy's own per-light function (`lighting::spot_light` with
//!   the light's index in Bevy's clustered list, `lighting::directional_light`
//!   and `lighting::rect_light` with its index in the view's directional or
//!   rectangle lights), so the light's colour, range, cone and BRDF are Bevy's by
//!   construction, after any Bevy upgrade;
//! - a [`FinLight`]: the pass adds it, shaded by Bevy's point-light BRDF
//!   functions, times `V`.
//!
//! Doing it in one pass keeps the sum exact before tonemapping, with HDR on
//! or off. The pipeline is Bevy's deferred lighting pipeline, specialised for
//! the same view key, with our shader and one more bind group.

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
        ExtractedDirectionalLight, ExtractedRectLight, GlobalClusterableObjectMeta, MeshPipelineKey, MeshViewBindGroup,
        ViewKeyCache,
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
        render_resource::{
            binding_types::{texture_2d_array, uniform_buffer_sized},
            *,
        },
        renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery},
        view::{ExtractedView, ViewTarget},
    },
    shader::Shader,
};

use bytemuck::Zeroable;

use crate::render::view::FinViewTexture;
use crate::{
    frame::{FinFrames, LightShading, MAX_FIN_LIGHTS},
    settings::{FinLight, FinShadowView},
};

/// The fin light as the compositing shader reads it (`FinLightUniform` in
/// `composite.wgsl`); the same numbers Bevy's `GpuClusteredLight` holds.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct FinLightUniform {
    pub(crate) position_radius: [f32; 4],
    pub(crate) forward_inverse_square_range: [f32; 4],
    pub(crate) color: [f32; 4],
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

    /// A Bevy directional light as `prepare_lights` uploads it
    /// (`GpuDirectionalLight::dir_to_light` and `color`): the composite finds
    /// the light in the view's list by these (`position_radius` unused).
    fn directional(sun: &ExtractedDirectionalLight) -> Self {
        let dir_to_light: Vec3 = sun.transform.back().into();
        let color = Vec4::from_slice(&sun.color.to_f32_array()) * sun.illuminance;
        Self {
            position_radius: [0.0; 4],
            forward_inverse_square_range: dir_to_light.extend(0.0).to_array(),
            color: color.to_array(),
        }
    }

    /// A Bevy rectangle light as `prepare_lights` uploads it (`GpuRectLight`:
    /// position, width, height): the composite finds the light in the view's
    /// rectangle lights by these (`color` unused).
    fn rect(rect: &ExtractedRectLight) -> Self {
        let position = rect.transform.translation();
        Self {
            position_radius: position.extend(rect.width).to_array(),
            forward_inverse_square_range: [0.0, 0.0, 0.0, rect.height],
            color: [0.0; 4],
        }
    }
}

/// What the compositing pass does with light slot `i` (`CompositeLight.info.x`).
pub(super) const KIND_OWN: u32 = 0;
pub(super) const KIND_BEVY: u32 = 1;
const KIND_NONE: u32 = 2;
pub(super) const KIND_BEVY_DIRECTIONAL: u32 = 3;
pub(super) const KIND_BEVY_RECT: u32 = 4;

/// One light slot as the compositing shader reads it (`CompositeLight` in
/// `composite.wgsl`): the shading of a [`FinLight`], or the index of a Bevy
/// light in Bevy's clustered light list.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct CompositeLight {
    pub(crate) own: FinLightUniform,
    /// x: kind, y: Bevy's light index, z: 1 when this view's layer was written.
    pub(crate) info: [u32; 4],
}

/// Bytes of [`CompositeLights`] (the forward hook's fallback of no light).
pub(super) const COMPOSITE_LIGHTS_BYTES: usize = size_of::<CompositeLights>();

/// Every light slot of one view (`CompositeLights` in `composite_types.wgsl`).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub(super) struct CompositeLights {
    /// x: the light slots in use; y: 1 while Bevy's own shadow maps of
    /// fin-shadowed lights are kept ([`crate::BevyShadowMapsKept`]: the shader
    /// replaces their shadow by V).
    pub(crate) count: [u32; 4],
    pub(crate) lights: [CompositeLight; MAX_FIN_LIGHTS],
}

pub(crate) fn build(app: &mut App) {
    embedded_asset!(app, "shaders/composite.wgsl");
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

/// Compositing pipelines per view key.
#[derive(Resource)]
struct FinCompositePipelines {
    shader: Handle<Shader>,
    light_layout: BindGroupLayoutDescriptor,
    specialized: HashMap<MeshPipelineKey, (CachedRenderPipelineId, BindGroupLayoutDescriptor)>,
}

/// Loads the shader at startup, so the pipeline is ready as soon as a fin light appears.
fn init_composite(mut commands: Commands, asset_server: Res<AssetServer>) {
    commands.insert_resource(FinCompositePipelines {
        shader: load_embedded_asset!(asset_server.as_ref(), "shaders/composite.wgsl"),
        light_layout: light_layout(),
        specialized: HashMap::new(),
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

/// Per view: the compositing bind group, its light-slot uniform and what
/// goes into it (the written flags are set when the pass runs).
#[derive(Component)]
pub struct FinCompositeBindGroup {
    /// Also the forward hook's group 4 (`forward.rs`).
    pub(super) bind_group: BindGroup,
    uniform: Buffer,
    lights: Box<CompositeLights>,
}

/// The compositing pass's group 3, the forward hook's group 4: the view's
/// visibility layers and its [`CompositeLights`].
pub(super) fn light_layout() -> BindGroupLayoutDescriptor {
    BindGroupLayoutDescriptor::new(
        "fin_composite_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::FRAGMENT,
            (texture_2d_array(TextureSampleType::Float { filterable: false }), uniform_buffer_sized(false, None)),
        ),
    )
}

#[allow(clippy::too_many_arguments)]
fn prepare_composite_pipelines(
    mut commands: Commands,
    pipeline_cache: Res<PipelineCache>,
    view_key_cache: Res<ViewKeyCache>,
    deferred_layout: Option<Res<DeferredLightingLayout>>,
    frames: Res<FinFrames>,
    pipelines: Option<ResMut<FinCompositePipelines>>,
    mut composited: ResMut<CompositedViews>,
    views: Query<(Entity, &ExtractedView, Has<DeferredPrepass>), With<FinShadowView>>,
) {
    let Some(mut pipelines) = pipelines else { return };
    let pipelines = &mut *pipelines;
    let ran_last_frame = std::mem::take(&mut composited.0);
    for (entity, view, deferred) in &views {
        let key = view_key_cache.get(&view.retained_view_entity).copied();
        let (Some(layout), Some(key), true, true) = (deferred_layout.as_deref(), key, deferred, !frames.0.is_empty())
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

/// The light slots (the written flags are set per view when the pass runs).
/// A Bevy light missing from Bevy's clustered list is left out; per pixel the
/// shader takes a light away only where Bevy's own cluster list for that
/// pixel holds it (`bevy_lit_pixel_with` in `composite.wgsl`): never from
/// light Bevy did not add — out of range, on render layers the view does not
/// see, or in its first frames before Bevy clusters it.
///
/// A directional light is not clustered, and its index in a view's list
/// depends on Bevy's sort and the view's render layers: the slot holds the
/// light as Bevy uploads it (direction towards the light, colour ×
/// illuminance) and the shader finds it in the view's list by those (and,
/// unless Bevy's maps are kept, its shadow maps being off), or leaves it alone when the view has no such
/// light. A rectangle light is not clustered either (Bevy uploads at most
/// eight per view, in query order): the slot holds its position, width and
/// height, by which the shader finds it.
fn composite_lights(
    frames: &FinFrames,
    clustered: Option<&GlobalClusterableObjectMeta>,
    directional: &Query<&ExtractedDirectionalLight>,
    rects: &Query<&ExtractedRectLight>,
    bevy_maps_kept: bool,
) -> CompositeLights {
    let mut out = CompositeLights::zeroed();
    out.count[0] = frames.light_count().min(MAX_FIN_LIGHTS) as u32;
    out.count[1] = bevy_maps_kept as u32;
    // One slot per light (its visibility layer), shaded as its first frame says.
    let first_frames = (0..frames.light_count()).filter_map(|layer| frames.of_layer(layer).next().map(|(_, f)| f));
    for (slot, frame) in first_frames.take(MAX_FIN_LIGHTS).enumerate() {
        let none = (KIND_NONE, FinLightUniform::zeroed(), 0);
        let (kind, own, id) = match frame.shading {
            LightShading::Own { light, transform } => {
                FinLightUniform::new(&light, &transform).map_or(none, |own| (KIND_OWN, own, 0))
            }
            LightShading::Bevy { render_entity } => match (directional.get(render_entity), rects.get(render_entity)) {
                (Ok(sun), _) => (KIND_BEVY_DIRECTIONAL, FinLightUniform::directional(sun), 0),
                (_, Ok(rect)) => (KIND_BEVY_RECT, FinLightUniform::rect(rect), 0),
                _ => clustered
                    .and_then(|c| c.entity_to_index.get(&render_entity))
                    .map_or(none, |&id| (KIND_BEVY, FinLightUniform::zeroed(), id as u32)),
            },
        };
        out.lights[slot] = CompositeLight { own, info: [kind, id, 0, 0] };
    }
    out
}

fn prepare_composite_bind_groups(
    mut commands: Commands,
    device: Res<RenderDevice>,
    pipeline_cache: Res<PipelineCache>,
    pipelines: Option<Res<FinCompositePipelines>>,
    frames: Res<FinFrames>,
    clustered: Option<Res<GlobalClusterableObjectMeta>>,
    directional: Query<&ExtractedDirectionalLight>,
    rects: Query<&ExtractedRectLight>,
    kept: Option<Res<crate::BevyShadowMapsKept>>,
    views: Query<(Entity, &FinViewTexture, Option<&FinCompositeBindGroup>), With<FinCompositePipeline>>,
) {
    let Some(pipelines) = pipelines else { return };
    let kept = kept.is_some_and(|k| k.kept());
    let lights = composite_lights(&frames, clustered.as_deref(), &directional, &rects, kept);
    for (entity, texture, previous) in &views {
        let uniform = match previous {
            Some(p) => p.uniform.clone(),
            None => device.create_buffer(&BufferDescriptor {
                label: Some("fin_composite_lights"),
                size: size_of::<CompositeLights>() as u64,
                usage: BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
        };
        let bind_group = device.create_bind_group(
            "fin_composite_bind_group",
            &pipeline_cache.get_bind_group_layout(&pipelines.light_layout),
            &BindGroupEntries::sequential((&texture.array, uniform.as_entire_binding())),
        );
        commands.entity(entity).insert(FinCompositeBindGroup { bind_group, uniform, lights: Box::new(lights) });
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
    written: Res<crate::render::view::ViewsWithVisibility>,
    frames: Res<FinFrames>,
    pipeline_cache: Res<PipelineCache>,
    pass_ids: Res<ComponentUniforms<PbrDeferredLightingDepthId>>,
    queue: Res<RenderQueue>,
    mut composited: ResMut<CompositedViews>,
    mut ctx: RenderContext,
) {
    let (entity, mesh_view_bind_group, target, pass_id_depth, pipeline, bind_group) = view.into_inner();
    // A layer not written this frame holds stale values: that light is left
    // as Bevy lit it (a FinLight: not at all). With none written, Bevy's own
    // lighting pass shows.
    let mut lights = *bind_group.lights;
    for layer in 0..lights.count[0] as usize {
        // A point light's layer is whole once all six faces wrote theirs.
        let complete = frames.of_layer(layer).all(|(slot, _)| written.0.contains(&(entity, slot)));
        lights.lights[layer].info[2] = (complete && frames.of_layer(layer).next().is_some()) as u32;
    }
    // Staged now, applied before this frame's command buffers run; the
    // forward hook reads the same flags in the main pass (`forward.rs`).
    queue.write_buffer(&bind_group.uniform, 0, bytemuck::bytes_of(&lights));
    if !lights.lights.iter().any(|l| l.info[2] == 1) {
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
    pass.set_bind_group(3, &bind_group.bind_group, &[]);
    pass.draw(0..3, 0..1);
    drop(pass);
    span.end(ctx.command_encoder());
    composited.0.insert(entity);
}
