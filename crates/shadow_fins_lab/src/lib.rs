//! The lab's library: scenes and method settings from flags, evaluation of a
//! method or the ground truth over receivers, side-by-side comparisons, PNG
//! pictures and plots, and our own glTF test assets. The `shadow-fins-lab`
//! binary (CPU oracle) and the `shadow-fins-render-lab` binary (the plugin
//! rendered by Bevy) share it.

pub mod assets;
pub mod compare;
pub mod environment;
pub mod eval;
pub mod grid;
pub mod picture;
pub mod plot;
pub mod points;
pub mod results;
pub mod setup;

/// Everything that can go wrong, with what to do about it.
#[derive(Debug, thiserror::Error)]
pub enum LabError {
    #[error("{0}")]
    Usage(String),
    #[error(transparent)]
    Gltf(#[from] shadow_fins::GltfError),
    #[error(transparent)]
    Light(#[from] shadow_fins::LightError),
    #[error(transparent)]
    Settings(#[from] shadow_fins::SettingsError),
    #[error("{0}: {1}")]
    Io(String, std::io::Error),
    #[error("points file line {line}: {reason}")]
    Points { line: usize, reason: String },
    #[error("cannot write PNG: {0}")]
    Png(String),
}
