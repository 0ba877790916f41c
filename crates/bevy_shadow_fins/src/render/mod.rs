//! Render world: the plugin's passes, wired here (each pass and what they
//! share is its own file; see `docs/ARCHITECTURE.md`), and the extraction of
//! `FinFrames` and `FinShadowView` to the render world.

use bevy::{
    asset::embedded_asset,
    core_pipeline::schedule::{Core3d, Core3dSystems, camera_driver},
    prelude::*,
    render::{
        Render, RenderApp, RenderSystems,
        extract_component::{ExtractComponent, ExtractComponentPlugin},
        extract_resource::ExtractResourcePlugin,
        render_resource::*,
        renderer::{RenderDevice, RenderGraph, RenderGraphSystems},
    },
    shader::load_shader_library,
};

use crate::{frame::FinFrames, settings::FinShadowView};

use crate::{
    render::{
        maps::{FinLightsGpu, init_pipelines, prepare_maps, render_maps},
        view::{
            FinLightPasses, FinViewTexture, ViewsWithVisibility, clear_views_with_visibility, init_no_gbuffer,
            prepare_view_textures,
        },
        visibility::{FinViewBindGroup, FinViewBuffer, fin_visibility, prepare_view_bind_groups},
    },
    settings::{FinIncrementalExtraction, FinPartialRedraw},
};

mod bevy_lights;
mod composite;
mod convolution;
mod coverage;
mod extraction;
mod forward;
mod maps;
mod params;
mod plateaus;
mod view;
mod visibility;
#[cfg(test)]
mod wgsl_twins;

pub(crate) fn build(app: &mut App) {
    load_shader_library!(app, "shaders/fin_types.wgsl");
    load_shader_library!(app, "shaders/cutout.wgsl");
    load_shader_library!(app, "shaders/fin_view.wgsl");
    load_shader_library!(app, "shaders/receiver_normal.wgsl");
    embedded_asset!(app, "shaders/maps.wgsl");
    embedded_asset!(app, "shaders/visibility.wgsl");
    app.init_resource::<FinPartialRedraw>().init_resource::<FinIncrementalExtraction>().add_plugins((
        ExtractResourcePlugin::<FinFrames>::default(),
        ExtractResourcePlugin::<FinPartialRedraw>::default(),
        ExtractResourcePlugin::<FinIncrementalExtraction>::default(),
        ExtractResourcePlugin::<crate::BevyShadowMapsKept>::default(),
        ExtractComponentPlugin::<FinShadowView>::default(),
    ));
    composite::build(app);
    forward::build(app);
    coverage::build(app);
    convolution::build(app);
    plateaus::build(app);
    extraction::build(app);
}

pub(crate) fn finish(app: &mut App) {
    let Some(render_app) = app.get_sub_app_mut(RenderApp) else { return };
    // Like Bevy's SSAO: check what the device can do before adding any pass.
    let world = render_app.world();
    let (Some(device), Some(adapter)) =
        (world.get_resource::<RenderDevice>(), world.get_resource::<bevy::render::renderer::RenderAdapter>())
    else {
        return;
    };
    let compute = adapter.get_downlevel_capabilities().flags.contains(DownlevelFlags::COMPUTE_SHADERS);
    match crate::budget::check_device(&device.limits(), compute) {
        Ok(limits) => {
            app.insert_resource(limits);
        }
        Err(why) => {
            error!("fin shadows: {why}. The plugin adds no pass; fin lights cast no light.");
            app.insert_resource(crate::budget::FinShadowsUnsupported(why));
            return;
        }
    }
    let Some(render_app) = app.get_sub_app_mut(RenderApp) else { return };
    render_app
        .init_resource::<FinLightsGpu>()
        .init_resource::<ViewsWithVisibility>()
        .add_systems(bevy::render::RenderStartup, (init_pipelines, init_no_gbuffer))
        .add_systems(
            Render,
            (
                prepare_maps.in_set(RenderSystems::PrepareResources),
                clear_views_with_visibility.in_set(RenderSystems::PrepareResources),
                prepare_view_textures.in_set(RenderSystems::PrepareResources),
                prepare_view_bind_groups.in_set(RenderSystems::PrepareBindGroups),
            ),
        )
        // In `Render`, after `Begin`: the diagnostics recorder clears the spans recorded before it.
        .configure_sets(RenderGraph, FinLightPasses.in_set(RenderGraphSystems::Render).before(camera_driver))
        .add_systems(RenderGraph, render_maps.in_set(FinLightPasses))
        .add_systems(Core3d, fin_visibility.after(Core3dSystems::Prepass).before(Core3dSystems::MainPass));
    coverage::finish(app);
    convolution::finish(app);
    plateaus::finish(app);
    composite::finish(app);
    forward::finish(app);
    bevy_lights::finish(app);
}

impl ExtractComponent for FinShadowView {
    type QueryData = &'static FinShadowView;
    type QueryFilter = With<Camera3d>;
    type Out = FinShadowView;
    fn extract_component(item: &FinShadowView) -> Option<FinShadowView> {
        Some(item.clone())
    }
}

impl bevy::render::sync_component::SyncComponent for FinShadowView {
    type Target = (
        FinShadowView,
        FinViewTexture,
        FinViewBindGroup,
        FinViewBuffer,
        coverage::CoverageViewBindGroup,
        coverage::CoverageViewBuffers,
        convolution::ConvolutionViewBindGroup,
        convolution::ConvolutionViewBuffer,
        plateaus::PlateauViewBindGroup,
        plateaus::PlateauViewBuffer,
        composite::FinCompositePipeline,
        composite::FinCompositeBindGroup,
        bevy::pbr::deferred::SkipDeferredLighting,
    );
}

#[cfg(test)]
mod shader_layout_tests {
    /// Every pass's WGSL lives in the workspace's top-level `shaders/`; the
    /// crate sees it through the `src/render/shaders` link, which `cargo
    /// package` follows, so the published crate carries the same files.
    #[test]
    fn the_shaders_the_plugin_embeds_are_the_top_level_shaders_folder() {
        let manifest = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let linked = manifest.join("src/render/shaders").canonicalize().expect("src/render/shaders resolves");
        let top = manifest.join("../../shaders").canonicalize().expect("the top-level shaders/ folder");
        assert_eq!(linked, top);
        let sources: String = [
            "mod.rs",
            "composite.rs",
            "convolution.rs",
            "coverage.rs",
            "extraction.rs",
            "forward.rs",
            "maps.rs",
            "plateaus.rs",
            "visibility.rs",
        ]
        .iter()
        .map(|f| std::fs::read_to_string(manifest.join("src/render").join(f)).expect("render source"))
        .collect();
        for entry in std::fs::read_dir(&top).expect("shaders/") {
            let name = entry.expect("entry").file_name().into_string().expect("utf-8 name");
            assert!(sources.contains(&format!("\"shaders/{name}\"")), "shaders/{name} is not embedded by the plugin");
        }
    }
}
