//! Rendering tests of the plugin, headless (lavapipe on CPU machines): GPU
//! read-backs of the visibility buffer against the core's raster oracle at the
//! same map resolution. One test binary, a module per topic.

mod render {
    mod alpha_masked;
    mod bevy_renderer;
    pub mod common;
    mod compositing;
    mod convolution;
    mod coverage;
    mod editor;
    mod forward;
    mod gltf_scenes;
    mod gpu_extraction;
    mod lab;
    mod lights;
    mod oracle_agreement;
    mod plateaus;
    mod point_light;
    mod posed;
    mod rect_light;
    mod reliability;
    mod robustness;
    mod runtime_changes;
    mod sun;
}
