//! The buffers the editor shows: the camera's visibility buffer read back from
//! the GPU every frame, and false-colour images of it, of the layer index, of
//! one layer's maps and of the error against ground truth.

use std::sync::Arc;

use bevy::{
    asset::RenderAssetUsages,
    prelude::*,
    render::{
        gpu_readback::{Readback, ReadbackComplete},
        render_resource::{Extent3d, TextureDimension, TextureFormat, TextureUsages},
    },
    window::PrimaryWindow,
};
use bevy_shadow_fins::FinShadowView;
use shadow_fins::metrics::ErrorMetrics;

use crate::state::ViewKind;
use crate::{
    state::{EditorCamera, EditorLight, window_size},
    truth::{Analysis, Grid, GroundTruthJob},
};

/// The latest visibility buffer read back from the GPU (camera pixels).
#[derive(Resource, Default, Clone)]
pub struct LatestVisibility {
    pub width: u32,
    pub height: u32,
    pub values: Arc<Vec<f32>>,
    /// Bumped on every read-back.
    pub serial: u64,
}

impl LatestVisibility {
    /// The value at the pixel under the centre of grid cell `(x, y)`.
    pub fn sample_for(&self, grid: &Grid, x: u32, y: u32) -> Option<f32> {
        if self.width == 0 || self.values.is_empty() {
            return None;
        }
        let px = (((x as f32 + 0.5) / grid.width as f32) * self.width as f32) as u32;
        let py = (((y as f32 + 0.5) / grid.height as f32) * self.height as f32) as u32;
        self.values.get((py.min(self.height - 1) * self.width + px.min(self.width - 1)) as usize).copied()
    }
}

/// Error of the GPU visibility against the ground truth at the grid pixels
/// done so far (DESIGN §4 metrics).
#[derive(Resource, Default, Clone)]
pub struct CurrentError {
    pub metrics: Option<ErrorMetrics>,
    /// Signed error per grid pixel (NaN where not measured).
    pub signed: Option<Grid>,
}

#[derive(Component)]
struct VisibilityReadback;

pub(crate) fn build(app: &mut App) {
    app.init_resource::<LatestVisibility>()
        .init_resource::<CurrentError>()
        .add_systems(Update, (keep_visibility_target_sized, update_error));
}

/// The camera's visibility buffer is copied into an image of the window's size
/// (recreated on resize) and read back every frame.
fn keep_visibility_target_sized(
    mut commands: Commands,
    mut images: ResMut<Assets<Image>>,
    window: Query<&Window, With<PrimaryWindow>>,
    mut views: Query<&mut FinShadowView, With<EditorCamera>>,
    main_light: Query<Entity, With<EditorLight>>,
    readbacks: Query<Entity, With<VisibilityReadback>>,
) {
    let (Some(size), Ok(mut view), Ok(light)) = (window_size(&window), views.single_mut(), main_light.single()) else {
        return;
    };
    // The main light's own layer (not "the first light": extra lights may
    // sort before it).
    let current = view.light_visibility_targets.first().and_then(|(_, h)| images.get(h)).map(|i| i.size());
    if current == Some(size) {
        return;
    }
    let mut image = Image::new_fill(
        Extent3d { width: size.x, height: size.y, depth_or_array_layers: 1 },
        TextureDimension::D2,
        &1f32.to_le_bytes(),
        TextureFormat::R32Float,
        RenderAssetUsages::RENDER_WORLD,
    );
    image.texture_descriptor.usage |= TextureUsages::COPY_DST | TextureUsages::COPY_SRC;
    let handle = images.add(image);
    view.light_visibility_targets = vec![(light, handle.clone())];
    for e in &readbacks {
        commands.entity(e).despawn();
    }
    commands.spawn((VisibilityReadback, Readback::texture(handle))).observe(
        move |done: On<ReadbackComplete>, mut latest: ResMut<LatestVisibility>| {
            let (width, height) = (size.x, size.y);
            let row = width as usize * 4;
            let padded = row.div_ceil(256) * 256;
            if done.data.len() < padded * (height as usize - 1) + row {
                return;
            }
            let values = (0..height as usize)
                .flat_map(|y| done.data[y * padded..y * padded + row].chunks_exact(4))
                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect();
            *latest = LatestVisibility { width, height, values: Arc::new(values), serial: latest.serial + 1 };
        },
    );
}

/// Recomputes the error a few times a second (it is a CPU pass over the grid).
fn update_error(
    latest: Res<LatestVisibility>,
    truth: Res<GroundTruthJob>,
    mut error: ResMut<CurrentError>,
    mut last: Local<(u64, u32)>,
) {
    let Some(grid) = truth.grid.as_ref() else {
        if error.metrics.is_some() {
            *error = CurrentError::default();
        }
        return;
    };
    if latest.serial == last.0 || !latest.serial.is_multiple_of(4) && last.1 == truth.status.rows_done {
        return;
    }
    *last = (latest.serial, truth.status.rows_done);
    // The GPU's visibility under each grid cell's centre, scored as the peers are.
    let sampled = Grid {
        width: grid.width,
        height: grid.height,
        values: (0..grid.height)
            .flat_map(|y| (0..grid.width).map(move |x| (x, y)))
            .map(|(x, y)| latest.sample_for(grid, x, y).unwrap_or(f32::NAN))
            .collect(),
    };
    let (metrics, signed) = crate::peers::score(&sampled, grid);
    (error.metrics, error.signed) = (metrics, Some(signed));
}

/// RGBA pixels of the view `kind` (width, height, pixels), or `None` when its
/// data is not there yet.
pub fn view_pixels(
    kind: ViewKind,
    latest: &LatestVisibility,
    analysis: Option<&Analysis>,
    error: &CurrentError,
    peer: &crate::peers::PeerJob,
) -> Option<(u32, u32, Vec<[u8; 4]>)> {
    let gray = |v: f32| {
        let g = (v.clamp(0.0, 1.0) * 255.0) as u8;
        [g, g, g, 255]
    };
    let none = [30, 30, 60, 255];
    match kind {
        ViewKind::Final => None,
        ViewKind::Visibility => {
            (latest.width > 0).then(|| (latest.width, latest.height, latest.values.iter().map(|v| gray(*v)).collect()))
        }
        ViewKind::LayerIndex => {
            let a = analysis?;
            let n = a.layer_count.max(1) as f32;
            let px = a.layers.values.iter().map(|v| if v.is_nan() { none } else { palette(*v / n) }).collect();
            Some((a.layers.width, a.layers.height, px))
        }
        ViewKind::SlabDepth | ViewKind::InnerMap | ViewKind::OuterMap => {
            let a = analysis?;
            let l0 = a.reference_depth.max(1e-6);
            let px = a
                .map
                .iter()
                .map(|t| match kind {
                    ViewKind::SlabDepth if t.slab_depth.is_finite() => gray(1.0 - t.slab_depth / l0),
                    ViewKind::InnerMap if t.inner.count > 0 => palette(t.inner.min_weight * 2.0),
                    ViewKind::OuterMap if t.outer.count > 0 => palette(t.outer.max_weight * 2.0),
                    _ => none,
                })
                .collect();
            Some((a.map_resolution, a.map_resolution, px))
        }
        ViewKind::Error | ViewKind::PeerError => {
            let g = if kind == ViewKind::Error { error.signed.as_ref()? } else { peer.signed.as_ref()? };
            let px = g.values.iter().map(|e| if e.is_nan() { none } else { diverging(*e) }).collect();
            Some((g.width, g.height, px))
        }
        ViewKind::Peer => {
            let g = peer.grid.as_ref()?;
            let px = g.values.iter().map(|v| if v.is_nan() { none } else { gray(*v) }).collect();
            Some((g.width, g.height, px))
        }
    }
}

/// A perceptual-ish ramp for `t ∈ [0, 1]` (dark blue → green → yellow).
fn palette(t: f32) -> [u8; 4] {
    let t = t.clamp(0.0, 1.0);
    let r = (255.0 * (1.5 * t - 0.5).clamp(0.0, 1.0)) as u8;
    let g = (255.0 * (1.2 * t).min(1.0) * (0.3 + 0.7 * t)) as u8;
    let b = (255.0 * (0.6 - 0.6 * t).clamp(0.0, 1.0) + 60.0 * (1.0 - t)) as u8;
    [r, g, b, 255]
}

/// Signed error: blue (too dark) → black (0) → red (too bright), full at ±0.5.
fn diverging(e: f32) -> [u8; 4] {
    let m = (e.abs() * 2.0).min(1.0);
    let v = (255.0 * m.sqrt()) as u8;
    if e > 0.0 { [v, v / 5, v / 8, 255] } else { [v / 8, v / 3, v, 255] }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_colours_distinguish_too_dark_from_too_bright() {
        let (dark, bright) = (diverging(-0.3), diverging(0.3));
        assert!(dark[2] > dark[0] && bright[0] > bright[2]);
        assert_eq!(diverging(0.0), [0, 0, 0, 255]);
    }

    #[test]
    fn sampling_maps_grid_cells_to_the_pixels_under_their_centres() {
        let latest =
            LatestVisibility { width: 4, height: 2, values: Arc::new((0..8).map(|i| i as f32).collect()), serial: 1 };
        let grid = Grid { width: 2, height: 1, values: vec![0.0; 2] };
        assert_eq!(latest.sample_for(&grid, 0, 0), Some(5.0));
        assert_eq!(latest.sample_for(&grid, 1, 0), Some(7.0));
    }
}
