//! Integration tests of the core crate: one test binary, one module per topic.

mod core {
    pub mod common;
    mod contact;
    mod convergence;
    mod coverage;
    mod cutout;
    mod default_view;
    mod gltf_files;
    mod ground_truth_closed_form;
    mod hostile_gltf;
    mod multi_layer;
    mod peers;
    mod rect_light;
    mod silhouette_properties;
    mod sphere_light;
    mod stability;
    mod straight_edge;
}
