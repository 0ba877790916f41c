//! The other papers the project was specified from, as measured peers of
//! the fin method: the same scenes, light frame, receivers, ground truth
//! and metrics, so that the lab can say what each costs and gets wrong.
//!
//! - [`single_sample`]: Parker, Shirley, Smits, *Single Sample Soft Shadows*
//!   (1998): one ray per receiver against softened occluders;
//! - [`plateaus`]: Haines, *Soft Planar Shadows Using Plateaus* (2001): a
//!   receiver plane's texture of drop shadow, cones and sheets.
//!
//! Each model answers [`PeerModel::visibility`] for a receiver in the light
//! frame, like the fin oracle's indices and the ground truth.

pub mod plateaus;
pub mod single_sample;

use crate::{
    oracle::Receiver,
    scene::{LightSpaceScene, Scene},
};

pub use plateaus::{PlateauModel, ReceiverPlane};
pub use single_sample::SingleSampleModel;

/// A peer method, by the name the lab's `--method` takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PeerMethod {
    /// Parker et al. 1998.
    SingleSample,
    /// Haines 2001 (one receiver plane).
    Plateaus,
}

impl PeerMethod {
    pub const ALL: [PeerMethod; 2] = [PeerMethod::SingleSample, PeerMethod::Plateaus];

    pub fn name(self) -> &'static str {
        match self {
            PeerMethod::SingleSample => "single-sample",
            PeerMethod::Plateaus => "plateaus",
        }
    }

    /// The paper, for tables: authors and year.
    pub fn paper(self) -> &'static str {
        match self {
            PeerMethod::SingleSample => "Parker, Shirley, Smits 1998",
            PeerMethod::Plateaus => "Haines 2001",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.name() == s)
    }
}

/// A peer method prepared for one scene under one light.
pub enum PeerModel {
    SingleSample(SingleSampleModel),
    Plateaus(PlateauModel),
}

impl PeerModel {
    pub fn new(method: PeerMethod, scene: &Scene, light_space: &LightSpaceScene) -> Self {
        match method {
            PeerMethod::SingleSample => PeerModel::SingleSample(SingleSampleModel::new(light_space)),
            PeerMethod::Plateaus => PeerModel::Plateaus(PlateauModel::new(scene, light_space)),
        }
    }

    /// Visibility of the light from a receiver (light frame), in `[0, 1]`.
    pub fn visibility(&self, receiver: Receiver) -> f32 {
        let v = match self {
            PeerModel::SingleSample(m) => m.visibility(receiver),
            PeerModel::Plateaus(m) => m.visibility(receiver),
        };
        // NaN in, 0 out: never a NaN on screen.
        if v > 0.0 { v.min(1.0) } else { 0.0 }
    }
}
