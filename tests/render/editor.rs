//! The editor, run as the user runs it (the `editor` example's `main`) under
//! `xvfb-run`: it starts, draws its panels and the scene, writes a
//! screenshot, and its settings change what the plugin renders.

use std::{path::PathBuf, process::Command};

use bevy::{
    asset::RenderAssetUsages,
    image::{CompressedImageFormats, Image, ImageSampler, ImageType},
};
use shadow_fins_editor::EditorSettings;

/// The editor binary (the same `main` as `examples/editor.rs`), which cargo
/// builds before it runs this test.
fn editor_binary() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_shadow-fins-editor"))
}

fn out_dir() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("editor");
    std::fs::create_dir_all(&dir).expect("test output directory");
    dir
}

/// Runs the editor for `frames` frames with `args`, returns the screenshot.
fn screenshot(name: &str, args: &[&str], frames: u32) -> Image {
    let path = out_dir().join(format!("{name}.png"));
    let _ = std::fs::remove_file(&path);
    let output = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1280x800x24"])
        .arg(editor_binary())
        .args(args)
        .args(["--screenshot", path.to_str().unwrap(), "--frames", &frames.to_string()])
        .output()
        .expect("xvfb-run (scripts/setup.sh installs xvfb)");
    assert!(
        output.status.success() && path.exists(),
        "the editor failed ({}):\n{}",
        output.status,
        String::from_utf8_lossy(&output.stderr)
            .lines()
            .filter(|l| !l.contains("CommandQueue"))
            .collect::<Vec<_>>()
            .join("\n")
    );
    let bytes = std::fs::read(&path).unwrap();
    Image::from_buffer(
        &bytes,
        ImageType::Extension("png"),
        CompressedImageFormats::NONE,
        true,
        ImageSampler::Default,
        RenderAssetUsages::MAIN_WORLD,
    )
    .expect("a PNG")
}

/// Distinct colours in a rectangle (x0..x1, y0..y1), quantised to 4 bits.
fn distinct_colours(image: &Image, (x0, x1, y0, y1): (u32, u32, u32, u32)) -> usize {
    let mut seen = std::collections::HashSet::new();
    for y in y0..y1 {
        for x in x0..x1 {
            if let Ok(c) = image.get_color_at(x, y) {
                let c = c.to_srgba();
                seen.insert(((c.red * 15.0) as u8, (c.green * 15.0) as u8, (c.blue * 15.0) as u8));
            }
        }
    }
    seen.len()
}

/// Sampled pixels (every other one, in the middle half of the view) whose
/// sRGB colours differ by more than 0.06 summed over the channels.
fn changed_pixels(a: &Image, b: &Image) -> usize {
    let (w, h) = (a.width().min(b.width()), a.height().min(b.height()));
    let mut changed = 0;
    for y in (h / 4..h * 3 / 4).step_by(2) {
        for x in (w / 4..w * 3 / 4).step_by(2) {
            changed += pixel_changed(a, b, x, y) as usize;
        }
    }
    changed
}

/// Whether the pixel (x, y) differs by more than 0.06 of sRGB, summed over the channels.
fn pixel_changed(a: &Image, b: &Image, x: u32, y: u32) -> bool {
    let (p, q) = (a.get_color_at(x, y).unwrap().to_srgba(), b.get_color_at(x, y).unwrap().to_srgba());
    (p.red - q.red).abs() + (p.green - q.green).abs() + (p.blue - q.blue).abs() > 0.06
}

/// [`changed_pixels`] over a rectangle (x0..x1, y0..y1), every pixel, with
/// the count compared.
fn changed_pixels_in(a: &Image, b: &Image, (x0, x1, y0, y1): (u32, u32, u32, u32)) -> (usize, usize) {
    let (w, h) = (a.width().min(b.width()), a.height().min(b.height()));
    let (mut changed, mut n) = (0, 0);
    for y in y0..y1.min(h) {
        for x in x0..x1.min(w) {
            changed += pixel_changed(a, b, x, y) as usize;
            n += 1;
        }
    }
    (changed, n)
}

#[test]
fn the_editor_starts_draws_panels_and_scene_and_writes_a_screenshot() {
    let image = screenshot("editor", &[], 20);
    let (w, h) = (image.width(), image.height());
    assert!(w >= 800 && h >= 600, "screenshot is {w}×{h}");
    // The panels: text on a flat background; the scene in the middle: shading.
    let left = distinct_colours(&image, (0, 200, 0, h));
    let middle = distinct_colours(&image, (w / 2 - 150, w / 2 + 150, h / 2 - 150, h / 2 + 150));
    assert!(left >= 4, "the left panel looks empty ({left} colours)");
    assert!(middle >= 8, "the viewport looks empty ({middle} colours)");
}

#[test]
fn the_editor_shows_another_papers_method_over_the_viewport() {
    // `--view peer`: the chosen peer evaluated on the CPU at the ground
    // truth's grid, drawn over the viewport in grey. Wedge blending and the
    // outer-only plateaus shade the demo differently (BENCHMARKS.md: 0.03
    // against 0.3 MAE), and neither view is the final image.
    let blending = screenshot("peer-wedge-blending", &["--view", "peer", "--peer", "wedge-blending"], 12);
    let plateaus = screenshot("peer-plateaus", &["--view", "peer", "--peer", "plateaus"], 12);
    let final_image = screenshot("peer-final", &[], 12);
    let (w, h) = (blending.width(), blending.height());
    let middle = (w / 2 - 150, w / 2 + 150, h / 2 - 150, h / 2 + 150);
    let shades = distinct_colours(&blending, middle);
    assert!(shades >= 6, "the peer view looks flat ({shades} colours)");
    let (between, from_final) = (changed_pixels(&blending, &plateaus), changed_pixels(&blending, &final_image));
    println!("peer views: {between} sampled pixels differ between two peers, {from_final} from the final image");
    assert!(between > 5000, "wedge blending and plateaus look alike ({between} pixels differ)");
    assert!(from_final > 20000, "the peer view is not drawn over the final image ({from_final} pixels differ)");
}

#[test]
fn the_editors_settings_change_what_the_plugin_renders() {
    let dir = out_dir();
    let write = |name: &str, radius: f32, method: &str| {
        let mut s = EditorSettings::load(&PathBuf::from("tests/data/editor-settings.ron")).expect("settings fixture");
        s.radius = radius;
        s.method = method.into();
        let path = dir.join(format!("{name}.ron"));
        s.save(&path).unwrap();
        path
    };
    let hard = write("hard", 0.0, "hard");
    let soft = write("soft", 1.0, "multi-layer");
    let a = screenshot("hard", &["--settings", hard.to_str().unwrap()], 12);
    let b = screenshot("soft", &["--settings", soft.to_str().unwrap()], 12);
    let changed = changed_pixels(&a, &b);
    println!("{changed} sampled viewport pixels differ between hard and soft");
    assert!(changed > 500, "a 1-unit light and a hard shadow map rendered nearly the same ({changed} pixels differ)");
}

/// The method switch reaches the plugin's convolution and plateaus methods:
/// each renders the 1-unit light's shadow differently from the hard shadow
/// map it starts from (a settings file, as the radio buttons set it).
#[test]
fn the_editors_convolution_and_plateaus_methods_soften_the_hard_shadow() {
    let dir = out_dir();
    let write = |method: &str| {
        let mut s = EditorSettings::load(&PathBuf::from("tests/data/editor-settings.ron")).expect("settings fixture");
        (s.radius, s.method) = (1.0, method.into());
        let path = dir.join(format!("method-{method}.ron"));
        s.save(&path).unwrap();
        path
    };
    let hard = screenshot("method-hard", &["--settings", write("hard").to_str().unwrap()], 12);
    // Mean sRGB of the view's middle half: the same light, so about the same
    // exposure whichever shadow (not black, not blown out).
    let mean = |image: &Image| {
        let (w, h) = (image.width(), image.height());
        let pixels: Vec<f32> = (h / 4..h * 3 / 4)
            .step_by(4)
            .flat_map(|y| (w / 4..w * 3 / 4).step_by(4).map(move |x| (x, y)))
            .map(|(x, y)| image.get_color_at(x, y).unwrap().to_srgba())
            .map(|c| (c.red + c.green + c.blue) / 3.0)
            .collect();
        pixels.iter().sum::<f32>() / pixels.len() as f32
    };
    for method in ["convolution", "plateaus"] {
        let shot = screenshot(&format!("method-{method}"), &["--settings", write(method).to_str().unwrap()], 12);
        let changed = changed_pixels(&hard, &shot);
        let (w, h) = (shot.width(), shot.height());
        let (a, b) = (mean(&hard), mean(&shot));
        println!("{changed} sampled viewport pixels differ between hard and {method}; mean {a:.3} → {b:.3}");
        assert!(changed > 300, "{method} rendered nearly the hard shadow ({changed} pixels differ)");
        assert!((a - b).abs() < 0.1 && b > 0.2, "{method}: mean brightness {b} against the hard shadow's {a}");
        assert!(distinct_colours(&shot, (w / 4, w * 3 / 4, h / 4, h * 3 / 4)) > 20, "{method}: a flat view");
    }
}

#[test]
fn the_editors_rect_and_point_lights_cast_soft_shadows_that_their_size_changes() {
    // Bevy's RectLight and PointLight chosen in the editor (`kind: "rect"`,
    // `"point"`): of size 0 their fin shadow is the hard one, of radius 1
    // (the rectangle: that disk's area) a soft one.
    let dir = out_dir();
    for kind in ["rect", "point"] {
        let write = |name: &str, radius: f32| {
            let mut s =
                EditorSettings::load(&PathBuf::from("tests/data/editor-settings.ron")).expect("settings fixture");
            (s.radius, s.method, s.kind, s.rect_aspect) = (radius, "multi-layer".into(), Some(kind.into()), 3.0);
            let path = dir.join(format!("{name}.ron"));
            s.save(&path).unwrap();
            path
        };
        let (point, wide) = (write(&format!("{kind}-0"), 0.0), write(&format!("{kind}-1"), 1.0));
        let a = screenshot(&format!("{kind}-0"), &["--settings", point.to_str().unwrap()], 16);
        let b = screenshot(&format!("{kind}-1"), &["--settings", wide.to_str().unwrap()], 16);
        let (w, h) = (a.width().min(b.width()), a.height().min(b.height()));
        assert!(distinct_colours(&b, (w / 4, w * 3 / 4, h / 4, h * 3 / 4)) > 20, "the {kind}-lit view is flat");
        let changed = changed_pixels(&a, &b);
        println!("{changed} sampled viewport pixels differ between a size-0 and a sized {kind} light");
        assert!(changed > 300, "the {kind} light's size changed almost nothing ({changed} pixels differ)");
    }
}

/// Runs the editor on `scene` for a screenshot; returns it with what the
/// editor printed (its status and error lines).
fn screenshot_of_scene(name: &str, scene: &std::path::Path) -> (Image, String) {
    screenshot_of_scene_with(name, scene, &[])
}

/// [`screenshot_of_scene`] with more options.
fn screenshot_of_scene_with(name: &str, scene: &std::path::Path, options: &[&str]) -> (Image, String) {
    let path = out_dir().join(format!("{name}.png"));
    let _ = std::fs::remove_file(&path);
    let output = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1280x800x24"])
        .arg(editor_binary())
        .arg(scene)
        .args(["--no-autosave", "--screenshot", path.to_str().unwrap(), "--frames", "12"])
        .args(options)
        .output()
        .expect("xvfb-run (scripts/setup.sh installs xvfb)");
    let stdout = String::from_utf8_lossy(&output.stdout).into_owned();
    assert!(output.status.success() && path.exists(), "the editor failed ({}):\n{stdout}", output.status);
    let bytes = std::fs::read(&path).unwrap();
    let image = Image::from_buffer(
        &bytes,
        ImageType::Extension("png"),
        CompressedImageFormats::NONE,
        true,
        ImageSampler::Default,
        RenderAssetUsages::MAIN_WORLD,
    )
    .expect("a PNG");
    (image, stdout)
}

/// Over the viewport's middle (clear of the panels): the mean sRGB luma and
/// the shares of near-black and near-white pixels.
fn exposure(image: &Image) -> (f32, f32, f32) {
    let (w, h) = (image.width(), image.height());
    let (mut sum, mut black, mut white, mut n) = (0.0, 0, 0, 0);
    for y in (h / 4..h * 3 / 4).step_by(2) {
        for x in (w * 3 / 8..w * 5 / 8).step_by(2) {
            let c = image.get_color_at(x, y).unwrap().to_srgba();
            let luma = 0.2126 * c.red + 0.7152 * c.green + 0.0722 * c.blue;
            sum += luma;
            black += (luma < 0.03) as u32;
            white += (luma > 0.97) as u32;
            n += 1;
        }
    }
    (sum / n as f32, black as f32 / n as f32, white as f32 / n as f32)
}

/// A readable first view: neither mostly black nor blown out, with shading.
fn assert_readable(name: &str, image: &Image) {
    let (mean, black, white) = exposure(image);
    let (w, h) = (image.width(), image.height());
    let colours = distinct_colours(image, (w * 3 / 8, w * 5 / 8, h / 4, h * 3 / 4));
    println!(
        "{name}: mean luma {mean:.3}, {:.1}% black, {:.1}% white, {colours} colours",
        black * 100.0,
        white * 100.0
    );
    assert!((0.12..0.85).contains(&mean), "{name}: the view is too dark or too bright (mean luma {mean})");
    assert!(black < 0.35 && white < 0.2, "{name}: {black} of the view is black, {white} white");
    assert!(colours >= 12, "{name}: the view is flat ({colours} colours)");
}

#[test]
fn the_editor_opens_a_gltf_as_bevy_loads_it_with_its_own_light_and_camera() {
    let scene = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/courtyard.gltf");
    let (image, stdout) = screenshot_of_scene("gltf-courtyard", &scene);
    assert!(!stdout.contains("editor error"), "{stdout}");
    assert!(stdout.contains("loaded courtyard.gltf"), "{stdout}");
    assert!(stdout.contains("lights from the file") && stdout.contains("the file's camera"), "{stdout}");
    assert_readable("courtyard", &image);
}

#[test]
fn the_editor_plays_a_gltfs_animation_through_bevy_and_shows_the_pose_it_rests_at() {
    // The skinned arm's `bend` clip, held at 0 s (straight) and 1 s (bent
    // over): Bevy's animation player poses it, the fin shadows follow.
    let scene = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/skinned-arm.gltf");
    let mut tops = vec![];
    let shots = ["0", "1"].map(|t| {
        let (image, stdout) = screenshot_of_scene_with(&format!("gltf-arm-{t}s"), &scene, &["--animation-time", t]);
        assert!(!stdout.contains("editor error"), "{stdout}");
        assert!(stdout.contains(&format!("animations: 1 (held at {t}.00 s of \"bend\")")), "{stdout}");
        // The ground truth traces the pose shown (a snapshot taken once Bevy applied it).
        let traced = format!("editor animation: \"bend\" at {t}.00 s; ground truth traces the pose at {t}.00 s");
        let line = stdout.lines().find(|l| l.starts_with(&traced)).unwrap_or_else(|| panic!("{traced}:\n{stdout}"));
        tops.push(line.rsplit("y = ").next().and_then(|y| y.trim().parse::<f32>().ok()).expect("the scene's top"));
        image
    });
    // Straight, the arm's top is 2 m up (0.2 m pedestal, 1.8 m arm); bent over, far lower.
    println!("the traced scene's top: {:.3} m at 0 s, {:.3} m at 1 s", tops[0], tops[1]);
    assert!((tops[0] - 2.0).abs() < 0.01 && tops[1] < 1.8, "the ground truth traces another pose: {tops:?}");
    // In the viewport between the panels (their text changes with the timings).
    let (w, h) = (shots[0].width(), shots[0].height());
    let viewport = (w * 3 / 10, w * 7 / 10, h / 10, h * 9 / 10);
    let (changed, sampled) = changed_pixels_in(&shots[0], &shots[1], viewport);
    println!("arm at 0 s vs 1 s of bend: {changed} of {sampled} viewport pixels changed");
    assert!(changed * 100 > sampled, "the pose (and its shadow) did not change: {changed} of {sampled}");
    // Not the whole view either: the ground, the pedestal and the sky stay.
    assert!(changed * 4 < sampled, "more than the arm and its shadow changed: {changed} of {sampled}");
}

/// A scene of slabs (half sizes, centres) scaled by `scale`, written as a glTF.
fn slab_scene(name: &str, slabs: &[([f32; 3], [f32; 3])], scale: f32) -> PathBuf {
    use shadow_fins::{
        scene::{Scene, SceneObject},
        shapes,
    };
    let objects = slabs
        .iter()
        .enumerate()
        .map(|(i, (half, at))| {
            let transform = bevy::math::Affine3A::from_scale_rotation_translation(
                bevy::math::Vec3::splat(scale),
                bevy::math::Quat::IDENTITY,
                bevy::math::Vec3::from_array(*at) * scale,
            );
            SceneObject::new(format!("slab{i}"), shapes::cuboid(bevy::math::Vec3::from_array(*half)), transform)
                .unwrap()
        })
        .collect();
    let path = out_dir().join(format!("{name}.gltf"));
    std::fs::write(&path, shadow_fins::gltf_import::write_gltf(&Scene::new(objects))).unwrap();
    path
}

#[test]
fn a_millimetre_cornell_box_opens_from_inside_lit_and_readable() {
    // A Cornell box open at +z (floor, ceiling, back, two sides, two
    // blocks) 0.555 mm across: the light must go under its ceiling and the
    // camera inside, at a millimetre scale.
    let t = 5.0;
    let box_ = [
        ([277.5, t, 277.5], [0.0, -t, 0.0]),
        ([277.5, t, 277.5], [0.0, 555.0 + t, 0.0]),
        ([277.5, 277.5, t], [0.0, 277.5, -277.5 - t]),
        ([t, 277.5, 277.5], [-277.5 - t, 277.5, 0.0]),
        ([t, 277.5, 277.5], [277.5 + t, 277.5, 0.0]),
        ([82.5, 82.5, 82.5], [90.0, 82.5, 60.0]),
        ([82.5, 165.0, 82.5], [-90.0, 165.0, -80.0]),
    ];
    let scene = slab_scene("cornell-mm", &box_, 1e-3 * 1e-3);
    let (image, stdout) = screenshot_of_scene("gltf-cornell-mm", &scene);
    assert!(!stdout.contains("editor error"), "{stdout}");
    assert!(stdout.contains("loaded cornell-mm.gltf"), "{stdout}");
    assert!(stdout.contains("seen from inside") && stdout.contains("default light"), "{stdout}");
    assert_readable("cornell box (mm)", &image);
}

#[test]
fn a_kilometre_scene_opens_lit_and_readable() {
    // Two towers on a 4 km plain.
    let slabs = [
        ([2000.0, 1.0, 2000.0], [0.0, -1.0, 0.0]),
        ([60.0, 150.0, 60.0], [0.0, 150.0, 0.0]),
        ([40.0, 80.0, 90.0], [200.0, 80.0, 100.0]),
    ];
    let scene = slab_scene("towers-km", &slabs, 1.0);
    let (image, stdout) = screenshot_of_scene("gltf-towers-km", &scene);
    assert!(!stdout.contains("editor error"), "{stdout}");
    assert!(stdout.contains("loaded towers-km.gltf") && stdout.contains("default light"), "{stdout}");
    assert_readable("towers (km)", &image);
}

#[test]
fn a_gltf_without_a_ground_opens_on_a_ground_that_catches_its_shadow() {
    // A figure exported on its own (a body and a head, nothing under its
    // feet), as Bevy's helmet and fox ship.
    let slabs = [([0.25, 0.8, 0.15], [0.0, 0.8, 0.0]), ([0.2, 0.2, 0.2], [0.0, 1.85, 0.0])];
    let scene = slab_scene("figure-alone", &slabs, 1.0);
    let (with_ground, stdout) = screenshot_of_scene("gltf-figure-alone", &scene);
    assert!(!stdout.contains("editor error"), "{stdout}");
    assert!(stdout.contains("a ground added under it"), "{stdout}");
    // With a settings file too: its light is kept, the view is still fitted to the file.
    let (without, stdout) = screenshot_of_scene_with(
        "gltf-figure-alone-no-ground",
        &scene,
        &["--no-ground", "--settings", "tests/data/editor-settings.ron"],
    );
    assert!(!stdout.contains("a ground added under it"), "{stdout}");
    assert!(stdout.contains("the kept light") && stdout.contains("the default view"), "{stdout}");
    // Where the ground is (the lower half of the viewport): lit grey with it,
    // the sky without it.
    let (w, h) = (with_ground.width(), with_ground.height());
    let lower = (w * 3 / 10, w * 7 / 10, h / 2, h * 9 / 10);
    let (changed, sampled) = changed_pixels_in(&with_ground, &without, lower);
    println!("figure alone, ground vs none: {changed} of {sampled} lower-viewport pixels changed");
    assert!(changed * 2 > sampled, "no ground appeared: {changed} of {sampled}");
    // And the figure's soft shadow lies on it: the ground under the figure is
    // darker than the ground around it.
    let luma = |x: u32, y: u32| {
        let c = with_ground.get_color_at(x, y).unwrap().to_srgba();
        0.2126 * c.red + 0.7152 * c.green + 0.0722 * c.blue
    };
    let row: Vec<f32> = (w * 3 / 10..w * 7 / 10).map(|x| luma(x, h * 3 / 4)).collect();
    let (darkest, brightest) = row.iter().fold((1f32, 0f32), |(lo, hi), &l| (lo.min(l), hi.max(l)));
    println!("ground row at 3/4 height: luma {darkest:.3} to {brightest:.3}");
    assert!(brightest > 0.2 && darkest < 0.6 * brightest, "no shadow on the ground: {darkest} to {brightest}");
}
