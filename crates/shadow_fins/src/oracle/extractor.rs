//! Per-frame fin extraction on the CPU (the stage the paper runs on the CPU):
//! silhouettes (§3.1), fins and fans (eq. 3), and the layer plan (§4.1).

use crate::{
    fins::{Fin, FinBuilder},
    layers::LayerPlan,
    scene::{LightSpaceScene, Scene},
    silhouette::{SilhouetteEdge, SilhouetteScratch, extract_object_silhouettes},
};

/// Per-frame fin extraction: silhouettes, patches, fins and the layer plan.
/// Buffers are reused between calls; this is the stage the paper runs on the CPU.
#[derive(Debug, Default)]
pub struct FinExtractor {
    scratch: SilhouetteScratch,
    builder: FinBuilder,
    depths: Vec<f32>,
    patch_depth: Vec<(f32, u32)>,
    /// Face patches found by the last [`FinExtractor::extract_silhouettes`].
    patch_count: u32,
    pub silhouettes: Vec<SilhouetteEdge>,
    /// Per caster triangle (the order of [`LightSpaceScene::casters`]): its patch,
    /// or [`NO_PATCH`](crate::silhouette::NO_PATCH) when it is not drawn into the maps.
    pub face_patches: Vec<u32>,
    /// Layer of each patch.
    pub patch_layers: Vec<u32>,
    pub fins: Vec<Fin>,
    /// Layer of each fin (same order as `fins`).
    pub fin_layers: Vec<u32>,
    pub plan: LayerPlan,
}

impl FinExtractor {
    /// Extracts silhouettes, patches and fins of every casting object and
    /// assigns layers. `layers == 1` gives the single-layered plan.
    ///
    /// Layers (§4.1): the sub-layer histogram of silhouette-edge midpoints is cut
    /// at its quantiles into depth planes; each patch goes, whole, to the layer of
    /// the mean depth of its silhouette edges, and its fins with it. (The paper
    /// clips casters into depth slabs instead; measured against ground truth,
    /// that turns the inner penumbra of any occluder deeper than its own
    /// silhouette — a box's sides, a wall standing on the floor — into umbra.)
    pub fn extract(&mut self, scene: &Scene, light_space: &LightSpaceScene, layers: u32, sub_layers: u32) {
        self.extract_silhouettes(scene, light_space);
        self.build_fins(light_space);
        self.assign_layers(layers, sub_layers);
    }

    /// Stage 1: silhouette edges (and face patches) of every casting object.
    pub fn extract_silhouettes(&mut self, scene: &Scene, light_space: &LightSpaceScene) {
        self.silhouettes.clear();
        self.face_patches.clear();
        let frame = &light_space.frame;
        let (mut vertex_base, mut patches) = (0u32, 0u32);
        for (object, to_frame) in scene.objects.iter().zip(&light_space.object_frames) {
            let outline = object.fitting_cutout().map(|c| &*c.outline);
            if object.casts_shadows {
                let light = to_frame.light_in_object(frame);
                patches += extract_object_silhouettes(
                    &object.topology,
                    to_frame,
                    light,
                    vertex_base,
                    patches,
                    &mut self.scratch,
                    &mut self.face_patches,
                    &mut self.silhouettes,
                    outline,
                );
            }
            vertex_base += object.topology.positions.len() as u32 + outline.map_or(0, |o| o.positions.len() as u32);
        }
        self.patch_count = patches;
        // A sphere light's face keeps the silhouettes that can shade it.
        self.silhouettes.retain(|e| !frame.outside_face_window(&[e.a, e.b]));
    }

    /// Stage 2: fins and fans of the silhouettes of stage 1 (eq. 3 widths).
    pub fn build_fins(&mut self, light_space: &LightSpaceScene) {
        let near = near_depth(light_space);
        self.builder.build(&self.silhouettes, &light_space.frame, light_space.reference_depth, near, &mut self.fins);
    }

    /// Stage 3: the sub-layer histogram cut into `layers` planes, and every
    /// patch and fin of stages 1–2 given its layer.
    pub fn assign_layers(&mut self, layers: u32, sub_layers: u32) {
        let patches = self.patch_count;
        self.depths.clear();
        self.depths.extend(self.silhouettes.iter().map(SilhouetteEdge::mid_depth));
        self.plan = LayerPlan::from_edge_depths(&self.depths, sub_layers, layers);

        // Patch layer: mean silhouette-edge depth; patches with no silhouette
        // (a closed mesh seen from inside) go to the last layer.
        self.patch_depth.clear();
        self.patch_depth.resize(patches as usize, (0.0, 0));
        for e in &self.silhouettes {
            let (sum, n) = &mut self.patch_depth[e.patch as usize];
            *sum += e.mid_depth();
            *n += 1;
        }
        let last = self.plan.len() as u32 - 1;
        self.patch_layers.clear();
        self.patch_layers.extend(
            self.patch_depth.iter().map(
                |&(sum, n)| {
                    if n == 0 { last } else { self.plan.layer_of(sum / n as f32) as u32 }
                },
            ),
        );
        self.fin_layers.clear();
        self.fin_layers.extend(self.fins.iter().map(|f| self.patch_layers[f.patch as usize]));
    }
}

/// Depth below which geometry is treated as at or behind the light plane.
pub fn near_depth(light_space: &LightSpaceScene) -> f32 {
    if light_space.frame.is_perspective() { light_space.reference_depth * 1e-5 } else { f32::NEG_INFINITY }
}
