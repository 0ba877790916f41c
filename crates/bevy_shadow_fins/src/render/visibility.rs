//! The fin methods' visibility pass (`shaders/visibility.wgsl`), per
//! camera and light frame: each fin weight refined to the receiver (eq. 5),
//! the layers combined, written into the light's layer of the camera's
//! illuminance buffer.

use bevy::{
    core_pipeline::prepass::ViewPrepassTextures,
    prelude::*,
    render::{
        render_asset::RenderAssets,
        render_resource::*,
        renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery},
        texture::GpuImage,
        view::{ExtractedView, ViewUniformOffset, ViewUniforms},
    },
};

use crate::{frame::FinFrames, settings::FinShadowView};

use crate::render::{
    maps::{FinLightsGpu, FinPipelines},
    view::{
        FinViewTexture, NoGBuffer, ViewPass, ViewsWithVisibility, gbuffer_input, prepass_inputs, run_view_pass,
        view_transform,
    },
};

/// Per camera and frame slot: the fin visibility pass's bind group (`None`
/// for lights on the coverage, convolution or plateaus method, or that
/// cannot run this frame).
#[derive(Component)]
pub struct FinViewBindGroup(Vec<Option<BindGroup>>);

/// Per camera and frame slot: its view → light-frame transform (`FinView`
/// in `visibility.wgsl`).
#[derive(Component, Default)]
pub struct FinViewBuffer(pub(super) Vec<Buffer>);

#[allow(clippy::too_many_arguments)]
pub(crate) fn prepare_view_bind_groups(
    mut commands: Commands,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    lights: Res<FinLightsGpu>,
    frames: Res<FinFrames>,
    pipelines: Option<Res<FinPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    view_uniforms: Res<ViewUniforms>,
    no_gbuffer: Res<NoGBuffer>,
    mut views: Query<(Entity, &FinViewTexture, &ViewPrepassTextures, &ExtractedView, Option<&mut FinViewBuffer>)>,
) {
    let (Some(pipelines), Some(view_binding)) = (pipelines, view_uniforms.uniforms.binding()) else {
        for (entity, ..) in &views {
            commands.entity(entity).remove::<FinViewBindGroup>();
        }
        return;
    };
    for (entity, texture, prepass, view, view_buffers) in &mut views {
        // A light that cannot run the pass this frame has no bind group, so
        // the pass does not run on last frame's maps and nothing composites
        // stale shadows.
        let inputs = prepass_inputs(prepass);
        let gbuffer = gbuffer_input(prepass, &no_gbuffer);
        let mut buffers = view_buffers.map(|mut b| std::mem::take(&mut b.0)).unwrap_or_default();
        let groups = frames
            .0
            .iter()
            .enumerate()
            .map(|(slot, frame)| {
                if !frame.data.settings.method.shaded_by_fin_pass() {
                    return None;
                }
                let gpu = lights.0.get(&frame.key())?;
                let (Some(params), Some(maps), Some(_), Some((depth, normal)), Some(layer)) = (
                    gpu.params.as_ref(),
                    gpu.maps.as_ref(),
                    gpu.bind_group.as_ref(),
                    inputs,
                    texture.layers.get(frame.layer),
                ) else {
                    return None;
                };
                let buffer = view_transform(&device, &queue, &frame.data, &view.world_from_view, &mut buffers, slot);
                Some(device.create_bind_group(
                    "fin_visibility_bind_group",
                    &pipeline_cache.get_bind_group_layout(&pipelines.view_layout),
                    &BindGroupEntries::sequential((
                        params.as_entire_binding(),
                        maps.as_entire_binding(),
                        depth,
                        normal,
                        layer,
                        view_binding.clone(),
                        buffer.as_entire_binding(),
                        gbuffer,
                    )),
                ))
            })
            .collect();
        commands.entity(entity).insert((FinViewBindGroup(groups), FinViewBuffer(buffers)));
    }
}

pub(crate) fn fin_visibility(
    view: ViewQuery<(Entity, &FinShadowView, &FinViewTexture, &FinViewBindGroup, &ViewUniformOffset)>,
    frames: Res<FinFrames>,
    pipelines: Option<Res<FinPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    images: Res<RenderAssets<GpuImage>>,
    mut written: ResMut<ViewsWithVisibility>,
    mut ctx: RenderContext,
) {
    let (entity, settings, texture, bind_groups, offset) = view.into_inner();
    let Some(pipeline) = pipelines.and_then(|p| pipeline_cache.get_compute_pipeline(p.visibility)) else { return };
    for (slot, bind_group) in bind_groups.0.iter().enumerate() {
        let Some(bind_group) = bind_group else { continue };
        let view = ViewPass { entity, settings, texture, offset: offset.offset };
        run_view_pass(&mut ctx, &view, "fin_visibility", pipeline, bind_group, slot, &images, &frames, &mut written);
    }
}
