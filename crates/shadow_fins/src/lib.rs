//! # shadow_fins
//!
//! Soft shadows from lights with a size by the *multi-layered shadow fins*
//! method (Cai, Jia, Wang, Hu, Martin, *Rendering Soft Shadows using
//! Multi-layered Shadow Fins*, CGF 25(1), 2006), on the CPU, with no Bevy:
//!
//! - [`mesh`]: validated triangle meshes, welding, edge → face adjacency;
//! - [`light`]: disk, rectangle, sun and sphere (point: six cube-face frames) lights, and the light frame everything runs in;
//! - [`silhouette`], [`fins`], [`layers`], [`refine`]: the method's stages;
//! - [`cutout`]: alpha-masked casters' holes (glTF `MASK` materials);
//! - [`coverage`]: exact coverage with occluder fusion (beyond the paper):
//!   per light sample, the depth complexity counted from potential
//!   silhouette edges;
//! - [`oracle`]: the method evaluated exactly ([`oracle::AnalyticIndex`]) and as
//!   light-space maps at a resolution ([`oracle::RasterMaps`]), the GPU's reference;
//! - [`peers`]: the other four papers' methods, measured beside ours (Parker
//!   et al.'s single-sample soft shadows, Haines' plateaus, penumbra wedges
//!   with and without Forest et al.'s blending, Annen et al.'s convolution
//!   soft shadows);
//! - [`ground_truth`]: many-sample disk visibility through a [`bvh::Bvh`];
//! - [`metrics`]: error against ground truth over the shadowed region;
//! - [`scenes`]: procedural scenes mirroring the paper's figures;
//! - [`default_view`]: a light and a camera that make any scene readable —
//!   the subject without the ground that dwarfs it, rooms seen from inside,
//!   the same view at any scale;
//! - `gltf` (feature `gltf`): glTF files into the core's meshes.
//!
//! The exact semantics are in the repository's `DESIGN.md` §3.
//!
//! ```
//! use shadow_fins::{scenes::SceneId, scene::LightSpaceScene, oracle::*};
//! let s = SceneId::BoxOverPlane.build();
//! let ls = LightSpaceScene::new(&s.scene, s.light);
//! let model = FinShadowModel::new(&s.scene, &ls, Method::MultiLayer, FinSettings::default());
//! let index = model.analytic();
//! // The middle of the box's shadow on the ground is umbra.
//! let p = ls.frame.to_frame(glam::Vec3::new(-0.24, 0.0, -0.16));
//! let n = ls.frame.dir_to_frame(glam::Vec3::Y);
//! assert!(index.visibility(Receiver { position: p, normal: n }) < 0.01);
//! ```

pub mod bvh;
pub mod camera;
pub mod cell_grid;
pub mod coverage;
pub mod cutout;
pub mod default_view;
pub mod error;
pub mod fins;
#[cfg(feature = "gltf")]
pub mod gltf_import;
pub mod ground_truth;
pub mod layers;
pub mod light;
pub mod mesh;
pub mod metrics;
pub mod oracle;
pub mod peers;
pub mod receiver;
pub mod refine;
pub mod scene;
pub mod scenes;
pub mod shapes;
pub mod silhouette;

pub use error::{GltfError, LightError, MeshError, SettingsError};
pub use glam;
