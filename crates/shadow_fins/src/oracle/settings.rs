//! Which method the oracle evaluates ([`Method`]) and with what settings
//! ([`FinSettings`]: layers, sub-layers, refinement, overlap, falloff).

use super::combine::Overlap;
use crate::{error::SettingsError, refine::Falloff};

/// Which soft-shadow method to evaluate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Method {
    /// Shadow map from the light centre: visibility 0 or 1.
    Hard,
    /// Hard shadow plus outer fins only: the smoothies / penumbra-map family.
    OuterFins,
    /// Inner and outer fins in one layer (the paper's §3).
    SingleLayer,
    /// Inner and outer fins in up to `layers` layers (the paper's §4).
    MultiLayer,
}

impl Method {
    pub const ALL: [Method; 4] = [Method::Hard, Method::OuterFins, Method::SingleLayer, Method::MultiLayer];

    pub fn name(self) -> &'static str {
        match self {
            Method::Hard => "hard",
            Method::OuterFins => "outer-fins",
            Method::SingleLayer => "single-layer",
            Method::MultiLayer => "fins",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == s)
    }
}

/// Settings of the fin method. Defaults are the paper's: 16 layers from 1024
/// sub-layers, refinement on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FinSettings {
    /// Layer count `N` (1..=64).
    pub layers: u32,
    /// Sub-layer count `S` (1..=65536).
    pub sub_layers: u32,
    /// Refine fin weights to the real receiver depth (eq. 5).
    pub refinement: bool,
    pub falloff: Falloff,
    /// How overlapping fins and layers combine.
    pub overlap: Overlap,
}

impl Default for FinSettings {
    fn default() -> Self {
        Self {
            layers: 16,
            sub_layers: 1024,
            refinement: true,
            falloff: Falloff::default(),
            overlap: Overlap::default(),
        }
    }
}

impl FinSettings {
    /// Checks every field's range.
    pub fn validate(self) -> Result<Self, SettingsError> {
        if !(1..=64).contains(&self.layers) {
            return Err(SettingsError::Layers(self.layers));
        }
        if !(1..=65536).contains(&self.sub_layers) {
            return Err(SettingsError::SubLayers(self.sub_layers));
        }
        Ok(self)
    }
}
