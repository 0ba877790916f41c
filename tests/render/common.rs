//! Shared helpers: scenes, the oracle's visibility per pixel, comparisons.

use bevy_shadow_fins::FinShadowSettings;
use shadow_fins::{
    bvh::Bvh,
    camera::pixel_receiver,
    oracle::{FinShadowModel, Method},
    scene::LightSpaceScene,
    scenes::SceneId,
};
use shadow_fins_app::harness::{Setup, Shot};

/// sRGB byte → linear.
pub fn linear(byte: u8) -> f32 {
    let c = byte as f32 / 255.0;
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

pub const WIDTH: u32 = 96;
pub const HEIGHT: u32 = 72;
pub const MAP: u32 = 256;

pub fn setup(id: SceneId, settings: FinShadowSettings) -> Setup {
    let s = id.build();
    Setup::new(s.scene, s.light, s.camera, settings, (WIDTH, HEIGHT))
}

pub fn settings() -> FinShadowSettings {
    FinShadowSettings { map_resolution: MAP, ..Default::default() }
}

/// The raster oracle's visibility at every pixel's receiver (1 for background).
pub fn oracle(setup: &Setup, method: Method) -> Vec<f32> {
    oracle_for(setup, &setup.camera, method)
}

/// [`oracle`] seen from another camera.
pub fn oracle_for(setup: &Setup, camera: &shadow_fins::camera::Camera, method: Method) -> Vec<f32> {
    let faces = LightSpaceScene::faces(&setup.scene, setup.light);
    let models: Vec<FinShadowModel> =
        faces.iter().map(|ls| FinShadowModel::new(&setup.scene, ls, method, setup.settings.core())).collect();
    let maps: Vec<_> = models.iter().map(|m| m.raster(setup.settings.clamped().map_resolution)).collect();
    per_pixel_in_faces(setup, camera, &faces, |face, r| maps[face].visibility(r))
}

/// [`per_pixel`] for a light of one frame or several (a point light's cube
/// faces, `LightSpaceScene::faces`): each pixel's receiver evaluated by
/// `visibility(face, receiver in that face's frame)` in the face that shades it.
pub fn per_pixel_in_faces(
    setup: &Setup,
    camera: &shadow_fins::camera::Camera,
    faces: &[LightSpaceScene],
    visibility: impl Fn(usize, shadow_fins::oracle::Receiver) -> f32,
) -> Vec<f32> {
    let first = &faces[0].frame;
    per_pixel(setup, camera, &faces[0], |r| {
        let (k, r) = LightSpaceScene::receiver_in_face(faces, first.to_world(r.position), first.dir_to_world(r.normal));
        visibility(k, r)
    })
}

/// `visibility` at every pixel's receiver seen from `camera` (1 for background).
pub fn per_pixel(
    setup: &Setup,
    camera: &shadow_fins::camera::Camera,
    ls: &LightSpaceScene,
    visibility: impl Fn(shadow_fins::oracle::Receiver) -> f32,
) -> Vec<f32> {
    let bvh = Bvh::new(&ls.casters);
    (0..setup.width * setup.height)
        .map(|i| {
            let pixel = (i % setup.width, i / setup.width, setup.width, setup.height);
            pixel_receiver(camera, pixel, ls, &bvh).map_or(1.0, &visibility)
        })
        .collect()
}

/// Mean absolute difference and the share of pixels off by more than 0.1.
pub fn compare(visibility: &[f32], oracle: &[f32]) -> (f32, f32) {
    let n = oracle.len() as f32;
    let mad = visibility.iter().zip(oracle).map(|(a, b)| (a - b).abs()).sum::<f32>() / n;
    let far = visibility.iter().zip(oracle).filter(|(a, b)| (*a - *b).abs() > 0.1).count() as f32 / n;
    (mad, far)
}

/// The largest per-pixel difference of two visibility buffers.
pub fn max_difference(visibility: &[f32], other: &[f32]) -> f32 {
    visibility.iter().zip(other).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max)
}

/// `setup` with its object `name` moved by `offset`.
pub fn with_moved(setup: &Setup, name: &str, offset: bevy::math::Vec3) -> Setup {
    let mut moved = setup.clone();
    for o in moved.scene.objects.iter_mut().filter(|o| o.name == name) {
        o.transform.translation += bevy::math::Vec3A::from(offset);
    }
    moved
}

/// What moving one object of a running app showed ([`moved_in_place`]).
pub struct MovedInPlace {
    /// The visibility before the move, settled.
    pub before: Vec<f32>,
    /// The settled shot after it, and the fin stats then.
    pub shot: Shot,
    pub stats: bevy_shadow_fins::FinFrameStats,
    /// What a fresh app renders with the object already moved.
    pub fresh: Vec<f32>,
}

/// `setup` settled, then its object `name` moved by `offset` in the running
/// app (its entity found by its translation) and settled again, saved as
/// `image`; beside a fresh app of [`with_moved`]: what an update in place
/// must match.
pub fn moved_in_place(setup: &Setup, name: &str, offset: bevy::math::Vec3, image: &str) -> MovedInPlace {
    use bevy::prelude::{Entity, Mesh3d, Transform};
    let object = setup.scene.objects.iter().find(|o| o.name == name).expect("the object to move");
    let at = bevy::math::Vec3::from(object.transform.translation);
    let mut session = shadow_fins_app::harness::Session::new(setup);
    let before = session.settle(6).expect("render").visibility;
    assert_visibility_not_trivial(&before);
    let world = session.app.world_mut();
    let mut meshes = world.query::<(Entity, &Mesh3d, &Transform)>();
    let entity = meshes.iter(world).find(|(_, _, t)| t.translation.distance(at) < 1e-4).expect("its entity").0;
    world.get_mut::<Transform>(entity).expect("a transform").translation += offset;
    let shot = session.settle(6).expect("render");
    save(&shot, image);
    let stats = fin_stats(&session);
    let fresh = render(&with_moved(setup, name, offset)).visibility;
    MovedInPlace { before, shot, stats, fresh }
}

/// The first fin-shadowed light's stats ([`bevy_shadow_fins::FinShadowStats`]) now.
pub fn fin_stats(session: &shadow_fins_app::harness::Session) -> bevy_shadow_fins::FinFrameStats {
    session.app.world().resource::<bevy_shadow_fins::FinShadowStats>().0
}

/// Mean and 99th percentile of per-pixel errors (at least one).
pub fn mean_and_p99(mut errors: Vec<f32>) -> (f32, f32) {
    assert!(!errors.is_empty(), "no pixel to compare");
    errors.sort_by(f32::total_cmp);
    let mean = errors.iter().sum::<f32>() / errors.len() as f32;
    (mean, errors[errors.len() * 99 / 100])
}

/// Linear RGB of every pixel of a shot's sRGB colour.
pub fn linear_rgb(shot: &Shot) -> Vec<[f32; 3]> {
    shot.color.iter().map(|p| [linear(p[0]), linear(p[1]), linear(p[2])]).collect()
}

/// Writes a test's image to `<target>/tmp/test-images/` when `SHADOW_FINS_TEST_IMAGES` is set.
pub fn save(shot: &Shot, name: &str) {
    if std::env::var_os("SHADOW_FINS_TEST_IMAGES").is_some() {
        let dir = format!("{}/test-images", env!("CARGO_TARGET_TMPDIR"));
        shot.save_color(&format!("{dir}/{name}.png")).expect("write test image");
        shot.save_visibility(&format!("{dir}/{name}_visibility.png")).expect("write test image");
    }
}

pub fn render(setup: &Setup) -> Shot {
    shadow_fins_app::harness::render(setup, 6).expect("headless render")
}

/// [`render`] for tests of Bevy's own lights: at least 16 frames, since
/// Bevy's clustering adds lights a few frames late (later the more lights
/// and the busier the machine; seen as frames without a light on lavapipe),
/// and a stable image before that is not the settled one.
pub fn render_bevy_lights(setup: &Setup) -> Shot {
    shadow_fins_app::harness::render(setup, 16).expect("headless render")
}

/// A shot must show both shadow and light: a test that passes on a black (or
/// white) image is a bug.
pub fn assert_not_trivial(shot: &Shot) {
    assert_visibility_not_trivial(&shot.visibility);
}

/// [`assert_not_trivial`] for one visibility buffer.
pub fn assert_visibility_not_trivial(visibility: &[f32]) {
    let dark = visibility.iter().filter(|v| **v < 0.05).count();
    let lit = visibility.iter().filter(|v| **v > 0.95).count();
    assert!(dark > 50 && lit > 50, "visibility buffer is trivial: {dark} dark, {lit} lit pixels");
}

/// Per pixel (linear green): |image − (dark + Σ_k V_k·(lit_k − dark))|, the
/// composite of several fin-shadowed lights against each light's own shadowed
/// contribution, with `lights` = (V_k, the image of light k alone over casters
/// that do not cast). Over the pixels where nothing clips at white and some
/// light's V passes `counted`.
pub fn composite_sum_errors(
    image: &Shot,
    lights: &[(&[f32], &Shot)],
    dark: &Shot,
    counted: impl Fn(f32) -> bool,
) -> Vec<f32> {
    let (ic, dc) = (linear_rgb(image), linear_rgb(dark));
    let lit: Vec<Vec<[f32; 3]>> = lights.iter().map(|(_, shot)| linear_rgb(shot)).collect();
    (0..ic.len())
        .filter(|&i| lit.iter().map(|l| l[i][1] - dc[i][1]).sum::<f32>() + dc[i][1] < 0.95 && ic[i][1] < 0.95)
        .filter(|&i| lights.iter().any(|(v, _)| counted(v[i])))
        .map(|i| {
            let expected =
                dc[i][1] + lights.iter().zip(&lit).map(|((v, _), l)| v[i] * (l[i][1] - dc[i][1])).sum::<f32>();
            (ic[i][1] - expected).abs()
        })
        .collect()
}

/// One fin-shadowed light's composite against Bevy's own shading of it
/// (tonemapping off): the light shadowed, `lit` (the same light with nothing
/// casting, V = 1), `dark` (another setup: the light at zero), and per pixel
/// the light's gain `lit − dark` (linear green).
pub struct SingleLightComposite {
    pub shadowed: Shot,
    pub lit: Shot,
    pub gain: Vec<f32>,
    /// |shadowed − (dark + V·(lit − dark))| over the pixels the light lights
    /// (gain > 0.05) where `lit` clips nowhere at white.
    pub errors: Vec<f32>,
}

impl SingleLightComposite {
    /// Renders the three shots, saving the first two as `{name}_shadowed`
    /// and `{name}_lit`.
    pub fn render(shadowed: &Setup, dark: &Setup, name: &str) -> Self {
        let mut lit = shadowed.clone();
        for o in &mut lit.scene.objects {
            o.casts_shadows = false;
        }
        let (s, l, d) = (render_bevy_lights(shadowed), render_bevy_lights(&lit), render_bevy_lights(dark));
        save(&s, &format!("{name}_shadowed"));
        save(&l, &format!("{name}_lit"));
        let (sc, lc, dc) = (linear_rgb(&s), linear_rgb(&l), linear_rgb(&d));
        let gain: Vec<f32> = (0..lc.len()).map(|i| lc[i][1] - dc[i][1]).collect();
        let errors = (0..sc.len())
            .filter(|&i| gain[i] > 0.05 && lc[i].iter().all(|c| *c < 0.95))
            .map(|i| (sc[i][1] - (dc[i][1] + s.visibility[i] * gain[i])).abs())
            .collect();
        Self { shadowed: s, lit: l, gain, errors }
    }

    /// Pixels the light lights but its shadow's umbra covers (V < 0.02).
    pub fn lit_umbra(&self) -> usize {
        (0..self.gain.len()).filter(|&i| self.shadowed.visibility[i] < 0.02 && self.gain[i] > 0.05).count()
    }

    /// Asserts Bevy shaded the light times V: a non-trivial shadow, V = 1
    /// where nothing casts, over 1000 unclipped lit pixels with more than 50
    /// in the umbra, and |shadowed − (dark + V·(lit − dark))| of mean ≤ 0.005
    /// and p99 ≤ 0.02 (`label` names the light in messages).
    pub fn assert_is_the_light_times_visibility(self, label: &str) {
        assert_not_trivial(&self.shadowed);
        assert!(self.lit.visibility.iter().all(|v| *v == 1.0), "{label}: nothing casts, yet V < 1 somewhere");
        let n = self.errors.len();
        assert!(n > 1000, "{label}: only {n} unclipped lit pixels");
        assert!(self.lit_umbra() > 50, "{label}: no lit-but-shadowed umbra to check: is its shadow composited?");
        let (mean, p99) = mean_and_p99(self.errors);
        println!("{label}: |shadowed − (dark + V·(lit − dark))| mean {mean:.4}, p99 {p99:.4} over {n} pixels");
        assert!(mean <= 0.005 && p99 <= 0.02, "{label}: mean {mean}, p99 {p99}");
    }
}

/// Every built-in scene of `ids` rendered as `make(id)` sets it up, against
/// the raster oracle at the same map resolution: mean |GPU − oracle| ≤ 0.01,
/// at most 3% of pixels off by more than 0.1, and a penumbra (> 100 pixels).
pub fn assert_matches_the_oracle(label: &str, ids: &[SceneId], make: impl Fn(SceneId) -> Setup) {
    for &id in ids {
        let setup = make(id);
        let shot = render_bevy_lights(&setup);
        let tag = format!("{label}_{}_{:?}", id.name(), setup.settings.extraction);
        save(&shot, &tag);
        assert_not_trivial(&shot);
        let (mad, far) = compare(&shot.visibility, &oracle(&setup, Method::MultiLayer));
        println!("{tag}: mean |gpu − oracle| = {mad:.5}, share > 0.1 = {:.2}%", far * 100.0);
        assert!(mad <= 0.01 && far <= 0.03, "{tag}: {mad} / {far}");
        let penumbra = shot.visibility.iter().filter(|v| (0.05..0.95).contains(*v)).count();
        assert!(penumbra > 100, "{tag}: only {penumbra} penumbra pixels: is the light soft at all?");
    }
}

/// A file of the project's `assets/` folder.
pub fn asset(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets").join(name)
}
