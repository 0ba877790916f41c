//! Render world of the plateaus method (`FinMethod::Plateaus`, Haines 2001):
//! per light frame, the plane, sheets and their grid uploaded when the
//! frame changed (`frame/plateaus.rs` builds them), and per camera the pass
//! (`plateaus.wgsl`) that reads them beside the light's hard shadow map
//! (drawn by the penumbra-map passes) into the same visibility buffer the
//! fins write, so compositing is unchanged.

use bevy::{
    asset::{embedded_asset, load_embedded_asset},
    core_pipeline::{
        prepass::ViewPrepassTextures,
        schedule::{Core3d, Core3dSystems},
    },
    prelude::*,
    render::{
        Render, RenderApp, RenderSystems,
        render_resource::{
            binding_types::{
                storage_buffer_read_only_sized, texture_2d, texture_depth_2d, texture_storage_2d, uniform_buffer,
                uniform_buffer_sized,
            },
            *,
        },
        renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery},
        view::{ExtractedView, ViewUniform, ViewUniformOffset, ViewUniforms},
    },
};

use crate::render::{
    extraction::ensure,
    maps::FinLightsGpu,
    view::{FinViewTexture, ViewsWithVisibility, view_transform},
};
use crate::{
    frame::{FinFrameData, FinFrames, FrameKey},
    settings::{FinMethod, FinShadowView},
};

pub(super) fn build(app: &mut App) {
    embedded_asset!(app, "shaders/plateaus.wgsl");
}

pub(super) fn finish(app: &mut App) {
    let Some(render_app) = app.get_sub_app_mut(RenderApp) else { return };
    render_app
        .init_resource::<PlateauLightsGpu>()
        .add_systems(bevy::render::RenderStartup, init_pipelines)
        .add_systems(
            Render,
            (
                prepare_plateaus.in_set(RenderSystems::PrepareResources),
                prepare_view_bind_groups.in_set(RenderSystems::PrepareBindGroups),
            ),
        )
        .add_systems(Core3d, plateaus_visibility.after(Core3dSystems::Prepass).before(Core3dSystems::MainPass));
}

#[derive(Resource)]
struct PlateauPipelines {
    view_layout: BindGroupLayoutDescriptor,
    visibility: CachedComputePipelineId,
}

fn init_pipelines(mut commands: Commands, pipeline_cache: Res<PipelineCache>, asset_server: Res<AssetServer>) {
    let view_layout = BindGroupLayoutDescriptor::new(
        "fin_plateaus_view_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                uniform_buffer_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                uniform_buffer_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                texture_depth_2d(),
                texture_2d(TextureSampleType::Float { filterable: false }),
                texture_storage_2d(TextureFormat::R32Float, StorageTextureAccess::WriteOnly),
                uniform_buffer::<ViewUniform>(true),
                uniform_buffer_sized(false, None),
            ),
        ),
    );
    let shader = load_embedded_asset!(asset_server.as_ref(), "shaders/plateaus.wgsl");
    commands.insert_resource(PlateauPipelines {
        visibility: crate::render::view::queue_compute(
            &pipeline_cache,
            "fin_plateaus",
            &view_layout,
            &shader,
            "plateaus_pass",
        ),
        view_layout,
    });
}

/// Every plateaus-method frame's plane, sheets and grid, by light and cube face.
#[derive(Resource, Default)]
struct PlateauLightsGpu(std::collections::HashMap<FrameKey, PlateauGpu>);

#[derive(Default)]
struct PlateauGpu {
    generation: u64,
    uniform: Option<Buffer>,
    sheets: Option<Buffer>,
    starts: Option<Buffer>,
    items: Option<Buffer>,
}

impl PlateauGpu {
    fn ready(&self) -> bool {
        self.generation != 0 && self.items.is_some()
    }
}

fn on_plateaus(frames: &FinFrames) -> impl Iterator<Item = &crate::frame::FinLightFrame> {
    frames.on_coverage(false).filter(|f| f.data.settings.method == FinMethod::Plateaus)
}

fn prepare_plateaus(
    frames: Res<FinFrames>,
    mut lights: ResMut<PlateauLightsGpu>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
) {
    lights.0.retain(|key, _| on_plateaus(&frames).any(|f| f.key() == *key));
    for frame in on_plateaus(&frames) {
        let gpu = lights.0.entry(frame.key()).or_default();
        upload(&frame.data, gpu, &device, &queue);
    }
}

/// One frame's plane, sheets and grid, uploaded when its frame changed.
fn upload(f: &FinFrameData, gpu: &mut PlateauGpu, device: &RenderDevice, queue: &RenderQueue) {
    let Some(p) = f.plateaus.as_ref() else {
        *gpu = PlateauGpu::default();
        return;
    };
    if f.generation == gpu.generation && gpu.ready() {
        return;
    }
    let storage = BufferUsages::STORAGE | BufferUsages::COPY_DST;
    let cap = f.limit_bytes;
    let uniform_bytes = bytemuck::bytes_of(&p.uniform);
    ensure(
        &mut gpu.uniform,
        device,
        "fin_plateaus_params",
        uniform_bytes.len() as u64,
        BufferUsages::UNIFORM | BufferUsages::COPY_DST,
        cap,
    );
    queue.write_buffer(gpu.uniform.as_ref().unwrap(), 0, uniform_bytes);
    let inputs: [(&str, &[u8]); 3] = [
        ("sheets", bytemuck::cast_slice(&p.sheets)),
        ("cell starts", bytemuck::cast_slice(&p.cell_starts)),
        ("cell items", bytemuck::cast_slice(&p.cell_items)),
    ];
    let limit = device.limits().max_storage_buffer_binding_size.min(cap);
    if let Some((name, bytes)) = inputs.iter().find(|(_, b)| b.len() as u64 > limit) {
        warn_once!(
            "fin shadows: the plateaus' {name} ({} bytes) exceed the buffer limit; no plateau shadows",
            bytes.len()
        );
        *gpu = PlateauGpu::default();
        return;
    }
    let buffers = [&mut gpu.sheets, &mut gpu.starts, &mut gpu.items];
    for (buffer, (name, bytes)) in buffers.into_iter().zip(inputs) {
        ensure(buffer, device, &format!("fin_plateaus_{name}"), (bytes.len() as u64).max(64), storage, cap);
        if !bytes.is_empty() {
            queue.write_buffer(buffer.as_ref().unwrap(), 0, bytes);
        }
    }
    gpu.generation = f.generation;
}

/// Per camera and frame slot: the plateau pass's bind group (`None` for
/// lights on other methods, or that cannot run this frame).
#[derive(Component)]
pub struct PlateauViewBindGroup(Vec<Option<BindGroup>>);

/// Per camera and frame slot: its view → light-frame transform.
#[derive(Component, Default)]
pub struct PlateauViewBuffer(Vec<Buffer>);

#[allow(clippy::too_many_arguments)]
fn prepare_view_bind_groups(
    mut commands: Commands,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    maps: Res<FinLightsGpu>,
    lights: Res<PlateauLightsGpu>,
    frames: Res<FinFrames>,
    pipelines: Option<Res<PlateauPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    view_uniforms: Res<ViewUniforms>,
    mut views: Query<(Entity, &FinViewTexture, &ViewPrepassTextures, &ExtractedView, Option<&mut PlateauViewBuffer>)>,
) {
    let binding = view_uniforms.uniforms.binding();
    for (entity, texture, prepass, view, buffers) in &mut views {
        let (Some(pipelines), Some(view_binding), false, Some((depth, normal))) =
            (pipelines.as_ref(), binding.clone(), lights.0.is_empty(), crate::render::view::prepass_inputs(prepass))
        else {
            commands.entity(entity).remove::<PlateauViewBindGroup>();
            continue;
        };
        let mut buffers = buffers.map(|mut b| std::mem::take(&mut b.0)).unwrap_or_default();
        let groups = frames
            .0
            .iter()
            .enumerate()
            .map(|(slot, frame)| {
                let gpu = lights.0.get(&frame.key()).filter(|g| g.ready())?;
                let m = maps.0.get(&frame.key())?;
                let (Some(params), Some(map_buffer), Some(_), Some(layer)) =
                    (m.params.as_ref(), m.maps.as_ref(), m.bind_group.as_ref(), texture.layers.get(frame.layer))
                else {
                    return None;
                };
                let buffer = view_transform(&device, &queue, &frame.data, &view.world_from_view, &mut buffers, slot);
                Some(device.create_bind_group(
                    "fin_plateaus_view_bind_group",
                    &pipeline_cache.get_bind_group_layout(&pipelines.view_layout),
                    &BindGroupEntries::sequential((
                        params.as_entire_binding(),
                        map_buffer.as_entire_binding(),
                        gpu.uniform.as_ref()?.as_entire_binding(),
                        gpu.sheets.as_ref()?.as_entire_binding(),
                        gpu.starts.as_ref()?.as_entire_binding(),
                        gpu.items.as_ref()?.as_entire_binding(),
                        depth,
                        normal,
                        layer,
                        view_binding.clone(),
                        buffer.as_entire_binding(),
                    )),
                ))
            })
            .collect();
        commands.entity(entity).insert((PlateauViewBindGroup(groups), PlateauViewBuffer(buffers)));
    }
}

#[allow(clippy::too_many_arguments)]
fn plateaus_visibility(
    view: ViewQuery<(Entity, &FinShadowView, &FinViewTexture, &PlateauViewBindGroup, &ViewUniformOffset)>,
    frames: Res<FinFrames>,
    maps: Res<FinLightsGpu>,
    pipelines: Option<Res<PlateauPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    images: Res<bevy::render::render_asset::RenderAssets<bevy::render::texture::GpuImage>>,
    mut written: ResMut<ViewsWithVisibility>,
    mut ctx: RenderContext,
) {
    let (entity, settings, texture, bind_groups, offset) = view.into_inner();
    let Some(pipeline) = pipelines.and_then(|p| pipeline_cache.get_compute_pipeline(p.visibility)) else { return };
    for (slot, bind_group) in bind_groups.0.iter().enumerate() {
        let Some(bind_group) = bind_group else { continue };
        // Only over a hard shadow map the passes have drawn for this frame.
        if maps.0.get(&frames.0[slot].key()).is_none_or(|m| m.dirty || m.renders == 0) {
            continue;
        }
        let view = crate::render::view::ViewPass { entity, settings, texture, offset: offset.offset };
        crate::render::view::run_view_pass(
            &mut ctx,
            &view,
            "fin_plateaus_visibility",
            pipeline,
            bind_group,
            slot,
            &images,
            &frames,
            &mut written,
        );
    }
}
