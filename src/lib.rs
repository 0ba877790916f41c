//! Hosts the examples and the rendering tests of the fin-shadow plugin, and the
//! headless harness they share: a built-in scene of the core crate rendered by
//! Bevy with the plugin, its visibility buffer read back to the CPU.

pub mod harness;
pub mod render_lab;
