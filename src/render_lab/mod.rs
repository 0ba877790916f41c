//! The lab's rendered half: the speed/accuracy trade measured on what Bevy
//! draws with the plugin (`measure`), the numerical extremes (`stability`),
//! several lights at once (`lights`), the sun (`sun`), the object count
//! (`scaling`) and alpha-masked leaf cards at scale (`foliage`). The
//! `shadow-fins-render-lab` binary drives both; the
//! Bevy-free parts (the grid, rows, CSV/JSON, plots) live in `shadow_fins_lab`.

pub mod foliage;
pub mod lights;
pub mod measure;
pub mod scaling;
pub mod stability;
pub mod sun;
