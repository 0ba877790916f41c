//! Integration tests of the core crate: one test binary, one module per topic.

mod core {
    pub mod common;
    mod straight_edge;
}
