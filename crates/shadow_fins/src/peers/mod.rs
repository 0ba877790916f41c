//! The other papers the project was specified from, as measured peers of
//! the fin method: the same scenes, light frame, receivers, ground truth
//! and metrics, so that the lab can say what each costs and gets wrong.
//!
//! - [`single_sample`]: Parker, Shirley, Smits, *Single Sample Soft Shadows*
//!   (1998): one ray per receiver against softened occluders;
//! - [`plateaus`]: Haines, *Soft Planar Shadows Using Plateaus* (2001): a
//!   receiver plane's texture of drop shadow, cones and sheets;
//! - [`convolution`]: Annen et al., *Real-Time, All-Frequency Shadows in
//!   Dynamic Scenes* (2008): convolution shadow maps with CSM-Z average
//!   blocker depth, summed-area tables or mipmaps;
//! - [`wedges`]: penumbra wedges (Assarsson, Akenine-Möller 2002), plain and
//!   with Forest, Barthe, Paulin's blending of overlapping penumbrae (2006).
//!
//! Each model answers [`PeerModel::visibility`] for a receiver in the light
//! frame, like the fin oracle's indices and the ground truth. The papers
//! model planar lights and the sun: a sphere light's face frame reaches them
//! as the disk of the sphere's radius in the face's plane
//! ([`crate::light::LightFrame::face_plane_disk`]).

pub mod convolution;
pub mod environment;
mod geometry;
pub mod plateaus;
pub mod single_sample;
pub mod wedges;

use crate::{
    receiver::Receiver,
    scene::{LightSpaceScene, Scene},
};

pub use convolution::{ConvolutionModel, ConvolutionSettings, Prefilter};
pub use plateaus::{PlateauModel, PlateauTexture, ReceiverPlane, SheetRecord};
pub use single_sample::SingleSampleModel;
pub use wedges::{WedgeBlending, WedgeModel};

/// A peer method, by the name the lab's `--method` takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PeerMethod {
    /// Parker et al. 1998.
    SingleSample,
    /// Haines 2001 (one receiver plane).
    Plateaus,
    /// Penumbra wedges, occluded areas added (Assarsson, Akenine-Möller 2002).
    PenumbraWedges,
    /// Penumbra wedges with Forest et al.'s blending (2006).
    WedgeBlending,
    /// Convolution soft shadows, summed-area tables (Annen et al. 2008).
    Convolution,
    /// Convolution soft shadows, mipmaps.
    ConvolutionMipmap,
}

impl PeerMethod {
    pub const ALL: [PeerMethod; 6] = [
        PeerMethod::SingleSample,
        PeerMethod::Plateaus,
        PeerMethod::PenumbraWedges,
        PeerMethod::WedgeBlending,
        PeerMethod::Convolution,
        PeerMethod::ConvolutionMipmap,
    ];

    pub fn name(self) -> &'static str {
        match self {
            PeerMethod::SingleSample => "single-sample",
            PeerMethod::Plateaus => "plateaus",
            PeerMethod::PenumbraWedges => "penumbra-wedges",
            PeerMethod::WedgeBlending => "wedge-blending",
            PeerMethod::Convolution => "convolution",
            PeerMethod::ConvolutionMipmap => "convolution-mipmap",
        }
    }

    /// The paper, for tables: authors and year.
    pub fn paper(self) -> &'static str {
        match self {
            PeerMethod::SingleSample => "Parker, Shirley, Smits 1998",
            PeerMethod::Plateaus => "Haines 2001",
            PeerMethod::PenumbraWedges => "Assarsson, Akenine-Möller 2002",
            PeerMethod::WedgeBlending => "Forest, Barthe, Paulin 2006",
            PeerMethod::Convolution | PeerMethod::ConvolutionMipmap => "Annen et al. 2008",
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
    Wedges(WedgeModel),
    Convolution(Box<ConvolutionModel>),
}

impl PeerModel {
    /// Prepared for any receiver (convolution shadow maps cover every caster).
    pub fn new(method: PeerMethod, scene: &Scene, light_space: &LightSpaceScene) -> Self {
        Self::prepare(method, scene, light_space, None)
    }

    /// Prepared for these receivers: convolution shadow maps fitted to them,
    /// as a renderer fits its maps to the view; the others as [`Self::new`].
    pub fn for_receivers(
        method: PeerMethod,
        scene: &Scene,
        light_space: &LightSpaceScene,
        receivers: &[Receiver],
    ) -> Self {
        Self::prepare(method, scene, light_space, Some(receivers))
    }

    fn prepare(
        method: PeerMethod,
        scene: &Scene,
        light_space: &LightSpaceScene,
        receivers: Option<&[Receiver]>,
    ) -> Self {
        let planar;
        let light_space = match light_space.frame.face_plane_disk() {
            Some(frame) => {
                planar = LightSpaceScene { frame, ..light_space.clone() };
                &planar
            }
            None => light_space,
        };
        match method {
            PeerMethod::SingleSample => PeerModel::SingleSample(SingleSampleModel::new(light_space)),
            PeerMethod::Plateaus => PeerModel::Plateaus(PlateauModel::new(scene, light_space)),
            PeerMethod::PenumbraWedges => PeerModel::Wedges(WedgeModel::new(scene, light_space, WedgeBlending::Add)),
            PeerMethod::WedgeBlending => PeerModel::Wedges(WedgeModel::new(scene, light_space, WedgeBlending::Forest)),
            PeerMethod::Convolution | PeerMethod::ConvolutionMipmap => {
                let prefilter =
                    if method == PeerMethod::Convolution { Prefilter::SummedArea } else { Prefilter::Mipmap };
                let settings = ConvolutionSettings { prefilter, ..Default::default() };
                PeerModel::Convolution(Box::new(match receivers {
                    Some(r) => ConvolutionModel::fitted(light_space, settings, r),
                    None => ConvolutionModel::new(light_space, settings),
                }))
            }
        }
    }

    /// Visibility of the light from a receiver (light frame), in `[0, 1]`.
    pub fn visibility(&self, receiver: Receiver) -> f32 {
        let v = self.unclamped_visibility(receiver);
        // NaN in, 0 out: never a NaN on screen.
        if v > 0.0 { v.min(1.0) } else { 0.0 }
    }

    /// The model's own answer, before [`Self::visibility`]'s guard: each
    /// model keeps it finite and in `[0, 1]` itself (what the tests pin).
    pub fn unclamped_visibility(&self, receiver: Receiver) -> f32 {
        match self {
            PeerModel::SingleSample(m) => m.visibility(receiver),
            PeerModel::Plateaus(m) => m.visibility(receiver),
            PeerModel::Wedges(m) => m.visibility(receiver),
            PeerModel::Convolution(m) => m.visibility(receiver),
        }
    }
}
