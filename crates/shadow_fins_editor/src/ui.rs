//! The panels: light, fins, method, views (left); stats, ground truth, files
//! (right); the chosen buffer over the viewport. Plain systems over resources:
//! the UI edits [`LightParams`] and the light's `FinShadowSettings`.

use std::collections::VecDeque;

use bevy::{
    diagnostic::{DiagnosticPath, DiagnosticsStore},
    prelude::*,
    render::view::screenshot::{Screenshot, save_to_disk},
};
use bevy_egui::{EguiContexts, EguiPrimaryContextPass, egui};
use bevy_shadow_fins::{FinFrames, FinLightStats, FinShadowSettings};
use shadow_fins::{oracle::Overlap, peers::PeerMethod, refine::Falloff};

use crate::{
    EditorState,
    peers::PeerJob,
    scene::LoadScene,
    settings_file::EditorSettings,
    state::{EditorLight, EditorMethod, LightKind, LightParams, LoadedScene, SceneSource, ViewKind},
    truth::{AnalysisJob, GroundTruthJob},
    views::{CurrentError, LatestVisibility, view_pixels},
};

/// The passes whose GPU time the stats show, as diagnostic names.
const PASSES: [&str; 4] = ["extraction", "penumbra_maps", "visibility", "composite"];

/// Files the UI reads and writes, editable in the UI.
#[derive(Resource)]
struct FilePaths {
    scene: String,
    settings: String,
}

/// Time and error as settings change, for the plot.
#[derive(Resource, Default)]
struct History {
    /// (fin passes' GPU ms, MAE against ground truth when known).
    points: VecDeque<(f32, Option<f32>)>,
}

#[derive(Default)]
struct ViewTexture {
    handle: Option<egui::TextureHandle>,
    key: (Option<ViewKind>, u64, usize, u64, u32),
    /// A hash of the pixels the handle holds: the same pixels are not set
    /// again (bevy_egui uploads a texture set anew a frame later, and the
    /// frame between draws no view: a screenshot could land on it).
    pixels: u64,
}

pub(crate) fn build(app: &mut App) {
    app.insert_resource(FilePaths { scene: "assets/demo.gltf".into(), settings: "out/editor-settings.ron".into() })
        .init_resource::<History>()
        .add_systems(Update, record_history)
        .add_systems(EguiPrimaryContextPass, panels);
}

/// GPU time of a fin pass (CPU time where the adapter has no timestamps), ms.
fn pass_ms(store: &DiagnosticsStore, pass: &str) -> Option<f64> {
    let get = |kind: &str| {
        store.get(&DiagnosticPath::new(format!("render/fin_shadows/{pass}/{kind}"))).and_then(|d| d.smoothed())
    };
    get("elapsed_gpu").or_else(|| get("elapsed_cpu"))
}

fn record_history(
    store: Res<DiagnosticsStore>,
    error: Res<CurrentError>,
    state: Res<EditorState>,
    mut history: ResMut<History>,
) {
    if !state.frames.is_multiple_of(10) {
        return;
    }
    let ms: f64 = PASSES.iter().filter_map(|p| pass_ms(&store, p)).sum();
    history.points.push_back((ms as f32, error.metrics.map(|m| m.mae)));
    while history.points.len() > 120 {
        history.points.pop_front();
    }
}

#[allow(clippy::too_many_arguments)]
fn panels(
    mut contexts: EguiContexts,
    mut commands: Commands,
    mut state: ResMut<EditorState>,
    mut params: ResMut<LightParams>,
    mut settings: Query<&mut FinShadowSettings, With<EditorLight>>,
    mut paths: ResMut<FilePaths>,
    mut load: MessageWriter<LoadScene>,
    main_light: Query<(Entity, &FinLightStats), With<EditorLight>>,
    (frame, store, truth, analysis, error, latest, history, scene): (
        Res<FinFrames>,
        Res<DiagnosticsStore>,
        Res<GroundTruthJob>,
        Res<AnalysisJob>,
        Res<CurrentError>,
        Res<LatestVisibility>,
        Res<History>,
        Option<Res<LoadedScene>>,
    ),
    mut peer: ResMut<PeerJob>,
    mut animation: ResMut<crate::animation::EditorAnimation>,
    mut texture: Local<ViewTexture>,
    mut added_ground: Option<ResMut<crate::ground::AddedGround>>,
) -> Result {
    let ctx = contexts.ctx_mut()?.clone();
    let Ok(mut fin_settings) = settings.single_mut() else { return Ok(()) };
    // The main light's own counts (other lights have theirs in "More lights").
    let (main_entity, fin_stats) = main_light.single().map_or((None, default()), |(e, s)| (Some(e), s.0));
    let main_is_fin_shadowed = frame.0.iter().any(|f| Some(f.light) == main_entity);
    let mut root = egui::Ui::new(
        ctx.clone(),
        "editor_root".into(),
        egui::UiBuilder::new().layer_id(egui::LayerId::background()).max_rect(ctx.viewport_rect()),
    );

    egui::Panel::left("controls").resizable(true).default_size(280.0).show(&mut root, |ui| {
        egui::ScrollArea::vertical().show(ui, |ui| {
            ui.heading("Light");
            let mut p = *params;
            // Slider ranges follow the scene's size (egui clamps a value to
            // its slider's range: a fixed range would cut a kilometre light).
            let extent = scene.as_ref().map_or(10.0, |s| s.extent);
            let (max_radius, max_lumens) = slider_ranges(extent);
            // Never below a value the user has (a kept or autosaved light).
            let (max_radius, max_lumens) = (max_radius.max(p.radius), max_lumens.max(p.intensity));
            // Wrapped: four kinds in one row would widen the panel over the view.
            ui.horizontal_wrapped(|ui| {
                for kind in LightKind::ALL {
                    ui.radio_value(&mut p.kind, kind, kind.label()).on_hover_text(match kind {
                        LightKind::FinLight => "The plugin's own disk light",
                        LightKind::Spot => {
                            "Bevy's own SpotLight with FinShadows: Bevy shades it (cone 1 rad), fins shadow it"
                        }
                        LightKind::Sun => {
                            "Bevy's DirectionalLight with FinShadows, as soft as its SunDisk's angular size \
                             (orthographic maps fitted to the scene; the position only places the marker)"
                        }
                        LightKind::Rect => {
                            "Bevy's RectLight with FinShadows: Bevy shades it (area-light LTC), fins shadow it; \
                             the rectangle has the disk's area (radius) and the aspect below"
                        }
                        LightKind::Point => {
                            "Bevy's PointLight with FinShadows: a sphere of this radius, shadowed all around \
                             (six cube-face frames); the layer view shows the face towards the scene's centre"
                        }
                    });
                }
            });
            vec3_row(ui, "position", &mut p.position, (extent * 0.005) as f64);
            vec3_row(ui, "direction", &mut p.direction, 0.01);
            ui.small("Shift+drag in the view moves the light; Shift+Ctrl+drag raises it.");
            if p.kind == LightKind::Sun {
                let mut degrees = p.sun_angle.to_degrees();
                ui.add(
                    egui::Slider::new(&mut degrees, 0.0..=20.0)
                        .text("angular size (°)")
                        .logarithmic(true)
                        .smallest_positive(0.01),
                )
                .on_hover_text("SunDisk::angular_size, the disk's diameter; the real sun is 0.53°");
                p.sun_angle = degrees.to_radians();
                ui.add(egui::Slider::new(&mut p.illuminance, 0.0..=1e5).text("illuminance (lx)").logarithmic(true));
            } else {
                ui.add(
                    egui::Slider::new(&mut p.radius, 0.0..=max_radius)
                        .text("radius")
                        .logarithmic(true)
                        .smallest_positive((max_radius as f64) * 1e-4),
                );
                if p.kind == LightKind::Rect {
                    ui.add(egui::Slider::new(&mut p.rect_aspect, 0.05..=20.0).text("width ÷ height").logarithmic(true));
                    let (w, h) = p.rect_size();
                    ui.small(format!("{w:.3} × {h:.3} (the area of the disk of this radius)"));
                }
                ui.add(egui::Slider::new(&mut p.intensity, 0.0..=max_lumens).text("intensity (lm)").logarithmic(true));
            }
            ui.horizontal(|ui| {
                ui.label("colour");
                ui.color_edit_button_rgb(&mut p.color);
            });

            ui.separator();
            ui.heading("Method");
            for m in EditorMethod::ALL {
                ui.radio_value(&mut p.method, m, m.label());
            }
            if p != *params {
                *params = p;
            }

            ui.separator();
            ui.heading("Fins");
            let mut s = *fin_settings;
            ui.add(egui::Slider::new(&mut s.layers, 1..=32).text("layers"));
            ui.add(egui::Slider::new(&mut s.sub_layers, 1..=4096).text("sub-layers").logarithmic(true));
            ui.add(egui::Slider::new(&mut s.coverage_samples, 1..=256).text("coverage samples").logarithmic(true));
            ui.add(egui::Slider::new(&mut s.convolution_order, 1..=16).text("convolution order"));
            egui::ComboBox::from_label("map resolution").selected_text(s.map_resolution.to_string()).show_ui(
                ui,
                |ui| {
                    for r in [256, 512, 1024, 2048] {
                        ui.selectable_value(&mut s.map_resolution, r, r.to_string());
                    }
                },
            );
            ui.checkbox(&mut s.refinement, "refinement (eq. 5)");
            egui::ComboBox::from_label("falloff").selected_text(s.falloff.name()).show_ui(ui, |ui| {
                for f in Falloff::ALL {
                    ui.selectable_value(&mut s.falloff, f, f.name());
                }
            });
            egui::ComboBox::from_label("overlap").selected_text(s.overlap.name()).show_ui(ui, |ui| {
                for o in Overlap::ALL {
                    ui.selectable_value(&mut s.overlap, o, o.name());
                }
            });
            if s != *fin_settings {
                *fin_settings = s;
            }

            if !animation.clips.is_empty() {
                ui.separator();
                animation_controls(ui, &mut animation);
            }

            ui.separator();
            ui.heading("View");
            for v in ViewKind::ALL {
                ui.radio_value(&mut state.view, v, v.label());
            }
            // Only for a file with no ground of its own (`ground.rs`).
            if let Some(ground) = added_ground.as_mut() {
                let mut shown = ground.shown;
                ui.checkbox(&mut shown, "ground under the subject (the file has none)");
                if shown != ground.shown {
                    ground.shown = shown;
                }
            }
            // The other papers' methods, on the CPU at the ground truth's pixels.
            let mut method = peer.method;
            egui::ComboBox::from_label("other paper").selected_text(method.name()).show_ui(ui, |ui| {
                for m in PeerMethod::ALL {
                    ui.selectable_value(&mut method, m, format!("{} ({})", m.name(), m.paper()));
                }
            });
            if method != peer.method {
                peer.method = method;
                if !state.view.is_peer() {
                    state.view = ViewKind::Peer;
                }
            }
            let layers = fin_stats.layers.max(1) as u32;
            ui.add(egui::Slider::new(&mut state.layer, 0..=layers - 1).text("map layer"));
        });
    });

    egui::Panel::right("stats").resizable(true).default_size(260.0).show(&mut root, |ui| {
        egui::ScrollArea::vertical().show(ui, |ui| {
            ui.heading("Stats");
            if let Some(scene) = &scene {
                ui.label(format!("scene: {} ({} objects)", scene.name, scene.scene.objects.len()));
            }
            for pass in PASSES {
                let t = pass_ms(&store, pass).map_or("–".into(), |ms| format!("{ms:.3} ms"));
                ui.label(format!("{pass}: {t}"));
            }
            if main_is_fin_shadowed {
                let s = fin_stats;
                ui.label(format!("casters {} · triangles {}", s.casters, s.triangles));
                ui.label(format!("silhouette edges {} · fins {}", s.silhouettes, s.fins));
                ui.label(format!(
                    "layers in use {} · maps {}² · CPU {:.2} ms",
                    s.layers, s.map_resolution, s.extract_ms
                ));
                ui.label(format!("GPU memory of the light's shadows {}", bevy_shadow_fins::ByteSize(s.gpu_bytes)));
                // What the last update redid: the casters extracted, the maps
                // in part or whole, and who posed.
                let redraw = if s.partial_redraw { "partial" } else { "whole" };
                let extracted = if s.incremental_extraction { "the moved casters" } else { "every caster" };
                ui.label(format!(
                    "last update extracted {extracted} · maps {redraw}: {} texels · {} posed on the GPU",
                    s.redrawn_texels, s.posed_on_gpu
                ));
                // What the GPU's limits or the budget cut, said where the user looks.
                for why in s.degraded.iter() {
                    ui.colored_label(egui::Color32::from_rgb(240, 190, 80), format!("degraded: {why}"));
                }
            }

            ui.separator();
            ui.heading("Ground truth");
            let st = truth.status;
            ui.add(
                egui::ProgressBar::new(st.rows_done as f32 / st.rows.max(1) as f32)
                    .text(format!("{}/{} rows · {} samples/pixel", st.rows_done, st.rows, st.samples)),
            );
            match error.metrics {
                Some(m) => {
                    ui.label(format!("MAE {:.4} · RMSE {:.4} · p99 {:.3}", m.mae, m.rmse, m.p99));
                    ui.label(format!(
                        "umbra over {:.2}% · leaks {:.2}% ({} px)",
                        m.umbra_over * 100.0,
                        m.leak * 100.0,
                        m.count
                    ));
                }
                None => {
                    ui.label("error: waiting for ground truth");
                }
            }
            if state.view.is_peer() {
                match (&peer.grid, peer.metrics) {
                    (Some(_), Some(m)) => {
                        ui.label(format!("{}: MAE {:.4} · p99 {:.3}", peer.method.name(), m.mae, m.p99));
                        ui.label(format!(
                            "umbra over {:.2}% · leaks {:.2}% · CPU {:.0} ms",
                            m.umbra_over * 100.0,
                            m.leak * 100.0,
                            peer.cpu_ms
                        ));
                    }
                    (Some(_), None) => {
                        ui.label(format!("{}: waiting for ground truth", peer.method.name()));
                    }
                    (None, _) => {
                        ui.label(format!("{}: computing on the CPU…", peer.method.name()));
                    }
                }
            }
            plot(ui, &history);

            ui.separator();
            ui.heading("Files");
            ui.horizontal(|ui| {
                ui.text_edit_singleline(&mut paths.scene);
                if ui.button("open glTF").clicked() {
                    load.write(LoadScene::new(SceneSource::Gltf(paths.scene.clone().into())));
                }
            });
            if ui.button("open the demo scene").clicked() {
                load.write(LoadScene::new(SceneSource::Demo));
            }
            ui.horizontal(|ui| {
                ui.text_edit_singleline(&mut paths.settings);
                if ui.button("save").clicked() {
                    let file = EditorSettings::capture(&params, &fin_settings);
                    match file.save(std::path::Path::new(&paths.settings)) {
                        Ok(()) => state.status = Some(format!("saved {}", paths.settings)),
                        Err(e) => state.error = Some(e.to_string()),
                    }
                }
                if ui.button("load").clicked() {
                    let (mut p, mut s) = (*params, *fin_settings);
                    match EditorSettings::load_into(std::path::Path::new(&paths.settings), &mut p, &mut s) {
                        Ok(()) => {
                            *params = p;
                            *fin_settings = s;
                            state.status = Some(format!("loaded {}", paths.settings));
                        }
                        // Nothing applied: the current settings stay.
                        Err(e) => state.error = Some(e.to_string()),
                    }
                }
            });
            if ui.button("screenshot").clicked() {
                let path = format!("out/editor-{}.png", state.frames);
                match std::fs::create_dir_all("out") {
                    Ok(()) => {
                        commands.spawn(Screenshot::primary_window()).observe(save_to_disk(path.clone()));
                        state.status = Some(format!("screenshot → {path}"));
                    }
                    Err(e) => state.error = Some(format!("could not create out/: {e}")),
                }
            }
            if let Some(s) = &state.status {
                ui.small(s.as_str());
            }
            if let Some(e) = state.error.clone() {
                ui.colored_label(egui::Color32::from_rgb(255, 110, 90), format!("error: {e}"));
                if ui.button("dismiss").clicked() {
                    state.error = None;
                }
            }
        });
    });

    // The chosen buffer, over what is left of the viewport.
    let analysis = analysis.latest.as_deref();
    let key = (
        Some(state.view),
        // Only the GPU's views follow its read-backs (a texture set anew
        // every few frames can miss a screenshot's frame).
        if matches!(state.view, ViewKind::Visibility | ViewKind::Error) { latest.serial / 3 } else { 0 },
        analysis.map_or(0, |a| a as *const _ as usize) ^ error.signed.as_ref().map_or(0, |g| g.values.len()),
        peer.serial,
        truth.status.rows_done,
    );
    if texture.key != key {
        texture.key = key;
        if let Some((w, h, px)) = view_pixels(state.view, &latest, analysis, &error, &peer) {
            let hash = {
                use std::hash::{Hash, Hasher};
                let mut hasher = std::collections::hash_map::DefaultHasher::new();
                (w, h, &px).hash(&mut hasher);
                hasher.finish()
            };
            let image = || egui::ColorImage::from_rgba_unmultiplied([w as usize, h as usize], px.as_flattened());
            let unchanged = texture.pixels == hash;
            match texture.handle.as_mut() {
                Some(_) if unchanged => {}
                Some(t) => t.set(image(), egui::TextureOptions::NEAREST),
                None => texture.handle = Some(ctx.load_texture("editor_view", image(), egui::TextureOptions::NEAREST)),
            }
            texture.pixels = hash;
        } else {
            texture.handle = None;
        }
    }
    if state.view != ViewKind::Final
        && let Some(t) = texture.handle.as_ref()
    {
        let rect = root.available_rect_before_wrap();
        let size = t.size_vec2();
        let scale = (rect.width() / size.x).min(rect.height() / size.y);
        let shown = egui::Rect::from_center_size(rect.center(), size * scale);
        root.painter().image(
            t.id(),
            shown,
            egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
            egui::Color32::WHITE,
        );
        let label = match (state.view, analysis) {
            (ViewKind::SlabDepth | ViewKind::InnerMap | ViewKind::OuterMap, Some(a)) => {
                format!("{} — layer {} of {}, {}²", state.view.label(), a.map_layer, a.layer_count, a.map_resolution)
            }
            (view, _) => view.label().to_string(),
        };
        root.painter().text(
            shown.left_top() + egui::vec2(6.0, 6.0),
            egui::Align2::LEFT_TOP,
            label,
            egui::FontId::proportional(16.0),
            egui::Color32::WHITE,
        );
    }
    Ok(())
}

/// The glTF's clips: which one, play or rest, and the time it rests at.
fn animation_controls(ui: &mut egui::Ui, animation: &mut crate::animation::EditorAnimation) {
    ui.heading("Animation");
    let mut selected = animation.selected;
    let name = |k: usize| animation.clips.get(k).map_or_else(String::new, |c| c.name.clone());
    egui::ComboBox::from_label("clip").selected_text(name(selected)).show_ui(ui, |ui| {
        for (k, clip) in animation.clips.iter().enumerate() {
            ui.selectable_value(&mut selected, k, format!("{} ({:.2} s)", clip.name, clip.duration));
        }
    });
    if selected != animation.selected {
        (animation.selected, animation.time) = (selected, 0.0);
    }
    ui.checkbox(&mut animation.playing, "play (loops)");
    let duration = animation.duration();
    // A clip of one key has one pose: nothing to scrub.
    ui.add_enabled(duration > 0.0, egui::Slider::new(&mut animation.time, 0.0..=duration.max(1e-3)).text("time, s"));
    // The ground truth traces a snapshot: taken when the animation rests.
    match animation.snapshot_pose {
        Some((clip, t)) if animation.playing || (clip, t) != (animation.selected, animation.time) => {
            ui.label(format!("ground truth at {t:.2} s of {} (pause to update)", name(clip)));
        }
        _ => {}
    }
}

fn vec3_row(ui: &mut egui::Ui, label: &str, v: &mut Vec3, speed: f64) {
    // Enough decimals to show one drag step (a millimetre scene's too).
    let decimals = ((-speed.log10()).ceil() as usize + 1).clamp(3, 12);
    ui.horizontal(|ui| {
        ui.label(label);
        for c in [&mut v.x, &mut v.y, &mut v.z] {
            ui.add(egui::DragValue::new(c).speed(speed).max_decimals(decimals));
        }
    });
}

/// The radius and power sliders' upper ends for a scene `extent` across:
/// half the scene, and a hundred times the light a surface a scene away
/// needs to read well ([`crate::readable_lumens`]), at least 10⁸ lm.
pub(crate) fn slider_ranges(extent: f32) -> (f32, f32) {
    let extent = if extent.is_finite() && extent > 0.0 { extent } else { 10.0 };
    ((extent * 0.5).max(1e-6), (crate::readable_lumens(extent) * 100.0).max(1e8))
}

/// GPU time (orange) and MAE (cyan) over the last frames, each scaled to its maximum.
fn plot(ui: &mut egui::Ui, history: &History) {
    let (rect, _) = ui.allocate_exact_size(egui::vec2(ui.available_width(), 80.0), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 2.0, egui::Color32::from_gray(20));
    let n = history.points.len();
    if n < 2 {
        return;
    }
    let max_ms = history.points.iter().map(|p| p.0).fold(1e-6, f32::max);
    let max_mae = history.points.iter().filter_map(|p| p.1).fold(1e-6, f32::max);
    let x = |i: usize| rect.left() + rect.width() * i as f32 / (n - 1) as f32;
    let y = |v: f32, max: f32| rect.bottom() - rect.height() * (v / max).clamp(0.0, 1.0) * 0.9;
    let ms: Vec<egui::Pos2> =
        history.points.iter().enumerate().map(|(i, p)| egui::pos2(x(i), y(p.0, max_ms))).collect();
    painter.add(egui::Shape::line(ms, egui::Stroke::new(1.5, egui::Color32::from_rgb(255, 160, 60))));
    let mae: Vec<egui::Pos2> =
        history.points.iter().enumerate().filter_map(|(i, p)| p.1.map(|m| egui::pos2(x(i), y(m, max_mae)))).collect();
    if mae.len() > 1 {
        painter.add(egui::Shape::line(mae, egui::Stroke::new(1.5, egui::Color32::from_rgb(80, 220, 255))));
    }
    painter.text(
        rect.left_top(),
        egui::Align2::LEFT_TOP,
        format!("GPU {max_ms:.2} ms · MAE {max_mae:.3} (max)"),
        egui::FontId::proportional(11.0),
        egui::Color32::GRAY,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slider_ranges_hold_the_default_view_of_any_scale() {
        // The default view's light is 5% of the subject across and needs
        // `readable_lumens` of its height: both must fit inside the sliders.
        for extent in [5e-4_f32, 1.0, 25.0, 4000.0] {
            let (radius, lumens) = slider_ranges(extent);
            assert!(radius >= extent * 0.05 && lumens >= crate::readable_lumens(extent), "{extent}");
        }
        let (radius, lumens) = slider_ranges(f32::NAN);
        assert!(radius.is_finite() && lumens.is_finite());
    }
}
