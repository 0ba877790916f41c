//! The CPU oracle of the whole fin method (DESIGN §3).
//!
//! [`FinShadowModel`] prepares one scene under one light for one method:
//! silhouettes, fins, the layer plan and the casters in map space. It then
//! answers visibility in two ways that share every rule:
//! - [`FinShadowModel::analytic`]: each receiver's centre ray is intersected
//!   exactly with the casters and fins (no rasterization);
//! - [`RasterMaps`]: the per-layer light-space maps at a given resolution, sampled
//!   at texel centres, as a GPU renders them, looked up at the nearest texel.
//!
//! Both evaluate the same [`LayerTexel`] per layer and the same
//! [`combine_layers`], so the raster converges to the analytic answer as the map
//! resolution grows.

mod analytic;
mod combine;
mod extractor;
mod map_geometry;
mod model;
mod raster;
mod settings;

pub use analytic::AnalyticIndex;
pub use combine::{CombineParams, LayerTexel, Overlap, SideTexel, combine_layers};
pub use extractor::{FinExtractor, near_depth};
pub use map_geometry::{MapCutout, MapTriangle};
pub use model::FinShadowModel;
pub use raster::{MapRegion, RASTER_MAP_LIMIT, RasterMaps};
pub use settings::{FinSettings, Method};

pub use crate::receiver::Receiver;
