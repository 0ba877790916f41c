//! glTF scenes as a Bevy app loads them (`WorldAssetRoot`, Bevy's own glTF
//! loader: materials, textures, hierarchy, `KHR_lights_punctual`), shadowed by
//! the plugin and judged on the triangles the plugin saw
//! (`bevy_shadow_fins::scene_snapshot`).

use bevy::prelude::*;
use shadow_fins::{
    bvh::Bvh,
    camera::pixel_receiver,
    ground_truth::GroundTruth,
    light::Light,
    oracle::Method,
    scene::{LightSpaceScene, Scene},
};
use shadow_fins_app::harness::{Session, Setup};

use super::common::{HEIGHT, WIDTH, assert_not_trivial, asset, compare, linear, oracle, save, settings};

/// The core importer's reading of `name` and a setup that loads it through
/// Bevy's loader instead, seen by the core's default view.
fn gltf_setup(name: &str) -> (Scene, Setup) {
    let import = shadow_fins::gltf_import::load_gltf(asset(name)).expect("the core importer reads it");
    assert!(import.skipped.is_empty(), "{name}: {:?}", import.skipped);
    let (light, camera) = shadow_fins::scenes::default_view(&import.scene).expect("a view");
    let mut setup = Setup::new(import.scene.clone(), light, camera, settings(), (WIDTH, HEIGHT));
    setup.gltf = Some(asset(name));
    (import.scene, setup)
}

/// Every world-space triangle.
fn world_triangles(scene: &Scene) -> Vec<[Vec3; 3]> {
    scene.objects.iter().flat_map(|o| o.mesh.triangles().map(|t| t.map(|p| o.transform.transform_point3(p)))).collect()
}

/// The largest distance from a triangle of `a` to its nearest triangle of
/// `b` (vertex by vertex, in either's winding start), relative to the
/// scene's size; `None` if the counts differ. Nearest, not sorted: the two
/// readers compose transforms in different orders, so a vertex may differ
/// in its last bit, which would reorder a sort.
fn largest_vertex_gap(a: &Scene, b: &Scene) -> Option<f32> {
    let (ta, tb) = (world_triangles(a), world_triangles(b));
    if ta.len() != tb.len() {
        return None;
    }
    let (lo, hi) = a.bounds()?;
    let size = (hi - lo).length();
    let distance = |x: &[Vec3; 3], y: &[Vec3; 3]| {
        (0..3).map(|r| (0..3).map(|i| x[i].distance(y[(i + r) % 3])).fold(0.0, f32::max)).fold(f32::INFINITY, f32::min)
    };
    // Both ways: duplicates on one side cannot hide a triangle missing from it.
    let one_way = |p: &[[Vec3; 3]], q: &[[Vec3; 3]]| {
        p.iter().map(|x| q.iter().map(|y| distance(x, y)).fold(f32::INFINITY, f32::min)).fold(0.0, f32::max)
    };
    Some(one_way(&ta, &tb).max(one_way(&tb, &ta)) / size)
}

#[test]
fn bevys_gltf_loader_and_the_core_importer_place_the_same_triangles() {
    // The courtyard's table is a hierarchy three nodes deep with rotations,
    // non-uniform scales and a `matrix` node: the ground truth may read glTF
    // through the core importer only if it places every triangle where Bevy does.
    for name in ["courtyard.gltf", "kitbash.gltf"] {
        let (core, setup) = gltf_setup(name);
        let mut session = Session::new(&setup);
        session.wait_for_gltf().expect("Bevy loads it");
        let snapshot = session.scene_snapshot();
        assert!(snapshot.skipped.is_empty(), "{name}: {:?}", snapshot.skipped);
        assert_eq!(snapshot.scene.triangle_count(), core.triangle_count(), "{name}");
        let gap = largest_vertex_gap(&core, &snapshot.scene).expect("same triangle count");
        println!("{name}: {} triangles, largest vertex gap {gap:.1e} of the scene's size", core.triangle_count());
        assert!(gap < 1e-5, "{name}: Bevy and the core importer disagree by {gap} of the scene's size");
    }
}

/// Linear luminance of an sRGB pixel.
fn luminance(p: [u8; 4]) -> f32 {
    0.2126 * linear(p[0]) + 0.7152 * linear(p[1]) + 0.0722 * linear(p[2])
}

#[test]
fn a_bevy_loaded_textured_gltf_with_its_own_spot_light_is_fin_shadowed_as_the_oracle_says() {
    let (_, mut setup) = gltf_setup("courtyard.gltf");
    // Its own light and its own camera; twice the usual size, as the table
    // is a fifth of the file's view.
    (setup.gltf_lights, setup.gltf_camera, setup.gltf_light_radius) = (true, true, 0.1);
    (setup.width, setup.height) = (2 * WIDTH, 2 * HEIGHT);
    let mut session = Session::new(&setup);
    let shot = session.settle(16).expect("headless render");
    save(&shot, "gltf_courtyard");
    // Its materials are the glTF's, textures included.
    let world = session.app.world_mut();
    let textured = world
        .query::<&MeshMaterial3d<StandardMaterial>>()
        .iter(world)
        .filter(|m| {
            world.resource::<Assets<StandardMaterial>>().get(&m.0).is_some_and(|m| m.base_color_texture.is_some())
        })
        .count();
    assert!(textured > 0, "no mesh has the glTF's base-colour texture");
    // Its one spot light, with the radius its extras give (not Bevy's range).
    let lights = session.fin_lights();
    assert_eq!(lights.len(), 1, "the glTF's spot light is the one fin-shadowed light");
    let Light::Disk(disk) = lights[0].1 else { panic!("a spot light is a disk: {:?}", lights[0].1) };
    assert!((disk.radius - 0.4).abs() < 1e-6, "radius {} is not the extras' 0.4", disk.radius);
    // Judged on what the plugin saw.
    let snapshot = session.scene_snapshot();
    let mut judged = setup.clone();
    judged.scene = snapshot.scene;
    judged.light = lights[0].1;
    judged.camera = session.main_camera().expect("the view");
    println!("the file's camera: {:?}", judged.camera);
    assert_not_trivial(&shot);
    let expected = oracle(&judged, Method::MultiLayer);
    let (mad, far) = compare(&shot.visibility, &expected);
    let shadowed = |v: &[f32]| v.iter().filter(|v| **v < 0.5).count();
    let worst = shot.visibility.iter().zip(&expected).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
    println!(
        "courtyard as Bevy loads it: mean |GPU − oracle| {mad:.2e}, worst {worst:.3}, {:.2}% of pixels off by > 0.1; \
         {} pixels in shadow (GPU), {} (oracle)",
        far * 100.0,
        shadowed(&shot.visibility),
        shadowed(&expected)
    );
    assert!(shadowed(&expected) > 100, "the oracle sees too little shadow for the test to mean anything");
    assert!(mad <= 0.01, "mean |GPU − oracle| {mad}");
    // Not only on average: the shadowed pixels themselves (a missing shadow
    // would cost the mean little over a mostly lit view).
    assert!(far < 0.002, "{:.3}% of pixels off by > 0.1", far * 100.0);
    let shaded: Vec<(f32, f32)> =
        shot.visibility.iter().zip(&expected).filter(|(a, b)| a.min(**b) < 0.999).map(|(a, b)| (*a, *b)).collect();
    let shaded_mad = shaded.iter().map(|(a, b)| (a - b).abs()).sum::<f32>() / shaded.len().max(1) as f32;
    assert!(shaded_mad <= 0.01, "mean |GPU − oracle| over the {} shaded pixels {shaded_mad}", shaded.len());

    // The same scene with the light's shadows off: the shadowed image is darker
    // exactly where the ground truth says shadow.
    let world = session.app.world_mut();
    let light = lights[0].0;
    world.entity_mut(light).remove::<bevy_shadow_fins::FinShadows>();
    world.get_mut::<SpotLight>(light).unwrap().shadow_maps_enabled = false;
    let unshadowed = session.settle(16).expect("headless render");
    save(&unshadowed, "gltf_courtyard_unshadowed");
    let ls = LightSpaceScene::new(&judged.scene, judged.light);
    let truth = GroundTruth::new(&ls, 256);
    let bvh = Bvh::new(&ls.casters);
    let (mut umbra, mut lit) = (vec![], vec![]);
    let (w, h) = (setup.width, setup.height);
    for y in (0..h).step_by(2) {
        for x in (0..w).step_by(2) {
            let Some(r) = pixel_receiver(&judged.camera, (x, y, w, h), &ls, &bvh) else { continue };
            if !r.faces_light(&ls.frame) {
                continue;
            }
            let i = (y * w + x) as usize;
            let kept = luminance(shot.color[i]) / luminance(unshadowed.color[i]).max(1e-4);
            match truth.visibility(r) {
                v if v < 0.05 => umbra.push(kept),
                v if v > 0.99 => lit.push(kept),
                _ => {}
            }
        }
    }
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len().max(1) as f32;
    println!(
        "luminance kept: {:.3} over {} umbra pixels, {:.3} over {} lit pixels (ground truth, 256 samples)",
        mean(&umbra),
        umbra.len(),
        mean(&lit),
        lit.len()
    );
    assert!(
        umbra.len() > 10 && lit.len() > 10,
        "the view shows too little umbra ({}) or light ({})",
        umbra.len(),
        lit.len()
    );
    assert!(mean(&umbra) < 0.6, "the umbra is not darker in the shadowed image: kept {}", mean(&umbra));
    assert!(mean(&lit) > 0.97, "lit pixels got darker: kept {}", mean(&lit));
}

/// `text` with every `data:image/png` URI replaced by `uri(k)` (k counts them).
fn replace_png_uris(text: &str, uri: impl Fn(usize) -> String) -> (String, usize) {
    const PNG: &str = "data:image/png;base64,";
    let (mut out, mut rest, mut k) = (String::new(), text, 0);
    while let Some(at) = rest.find(PNG) {
        let end = at + rest[at..].find('"').expect("a closed string");
        out.push_str(&rest[..at]);
        out.push_str(&uri(k));
        rest = &rest[end..];
        k += 1;
    }
    out.push_str(rest);
    (out, k)
}

#[test]
fn a_gltf_with_jpeg_textures_opens_textured_and_fin_shadowed() {
    // Bevy's own sample scenes ship JPEG textures: the courtyard with its
    // PNG textures swapped for JPEG files beside it.
    let dir = std::env::temp_dir().join(format!("fins-jpeg-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (w, h) = (48, 24);
    let checker = image::RgbImage::from_fn(w, h, |x, y| {
        if (x / 8 + y / 8) % 2 == 0 { image::Rgb([210, 200, 180]) } else { image::Rgb([90, 100, 120]) }
    });
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 90).encode_image(&checker).unwrap();
    assert_eq!(&jpeg[..2], &[0xff, 0xd8], "a JPEG file");
    let text = std::fs::read_to_string(asset("courtyard.gltf")).unwrap();
    let (text, swapped) = replace_png_uris(&text, |k| format!("texture-{k}.jpg"));
    assert!(swapped >= 2, "the courtyard has PNG textures to swap");
    for k in 0..swapped {
        std::fs::write(dir.join(format!("texture-{k}.jpg")), &jpeg).unwrap();
    }
    let path = dir.join("courtyard-jpeg.gltf");
    std::fs::write(&path, text).unwrap();
    let (_, mut setup) = gltf_setup("courtyard.gltf");
    setup.gltf = Some(path);
    // Its own light and camera, as the PNG-textured file's test.
    (setup.gltf_lights, setup.gltf_camera, setup.gltf_light_radius) = (true, true, 0.1);
    (setup.width, setup.height) = (2 * WIDTH, 2 * HEIGHT);
    let mut session = Session::new(&setup);
    let shot = session.settle(16);
    std::fs::remove_dir_all(&dir).ok();
    let shot = shot.expect("Bevy opens a JPEG-textured glTF");
    save(&shot, "gltf_courtyard_jpeg");
    // The materials carry the decoded JPEG (its size), not a placeholder.
    let world = session.app.world_mut();
    let textures: Vec<Handle<Image>> = world
        .query::<&MeshMaterial3d<StandardMaterial>>()
        .iter(world)
        .filter_map(|m| world.resource::<Assets<StandardMaterial>>().get(&m.0)?.base_color_texture.clone())
        .collect();
    assert!(!textures.is_empty(), "no mesh has the glTF's base-colour texture");
    let images = world.resource::<Assets<Image>>();
    for t in &textures {
        let size = images.get(t).expect("the texture decoded").size();
        assert_eq!((size.x, size.y), (w, h), "the JPEG's size");
    }
    // And the fins shadow it as usual.
    assert_not_trivial(&shot);
}

#[test]
fn a_gltf_bevy_cannot_read_is_an_error_not_a_hang() {
    let broken = std::env::temp_dir().join(format!("fins-broken-{}.gltf", std::process::id()));
    std::fs::write(&broken, br#"{"asset":{"version":"2.0"},"buffers":[{"byteLength":4294967296}]}"#).unwrap();
    let (_, mut setup) = gltf_setup("kitbash.gltf");
    setup.gltf = Some(broken.clone());
    let result = Session::new(&setup).settle(3);
    std::fs::remove_file(&broken).ok();
    let error = result.err().expect("a broken glTF is an error");
    assert!(error.contains("could not load"), "{error}");
    // One readable line, as the editor's panel shows it: no backtrace.
    assert!(!error.contains('\n') && !error.to_lowercase().contains("backtrace"), "{error}");
}

#[test]
fn a_scene_the_file_does_not_have_is_an_error_that_says_so() {
    // `spawn_gltf_scene` loads the file once, as a `Gltf`, and spawns its
    // `scenes[i]`: an index past them is a load that never spawns, and says why.
    let (_, setup) = gltf_setup("leaf-cards.gltf");
    let mut session = Session::new(&setup);
    session.wait_for_gltf().expect("Bevy loads it");
    let assets = session.app.world().resource::<AssetServer>().clone();
    let path = asset("leaf-cards.gltf");
    let root = bevy_shadow_fins::spawn_gltf_scene(&mut session.app.world_mut().commands(), &assets, &path, 7);
    session.app.world_mut().flush();
    let loading = session.app.world().get::<bevy_shadow_fins::GltfSceneLoading>(root).expect("spawned").clone();
    for _ in 0..100 {
        if loading.failed(&assets).is_some() {
            break;
        }
        session.update();
    }
    let error = loading.failed(&assets).expect("a scene the file lacks fails");
    println!("scene 7 of leaf-cards.gltf: {error}");
    assert!(error.contains("1 scene(s)") && error.contains("scene 7"), "{error}");
    assert!(!loading.is_ready() && session.app.world().get::<WorldAssetRoot>(root).is_none());
}

/// What a load did: `Gltf`s loaded with their dependencies, and materials
/// replaced (a second load of a file lands as `Modified` on the first's).
#[derive(Resource, Default, Debug)]
struct LoadEvents {
    gltfs_loaded: usize,
    materials_modified: usize,
}

fn count_load_events(
    mut gltfs: MessageReader<AssetEvent<bevy::gltf::Gltf>>,
    mut materials: MessageReader<AssetEvent<StandardMaterial>>,
    mut events: ResMut<LoadEvents>,
) {
    events.gltfs_loaded += gltfs.read().filter(|e| matches!(e, AssetEvent::LoadedWithDependencies { .. })).count();
    events.materials_modified += materials.read().filter(|e| matches!(e, AssetEvent::Modified { .. })).count();
}

#[test]
fn a_gltf_is_loaded_once_and_its_materials_stay_the_ones_bevy_spawned() {
    // `spawn_gltf_scene` asks Bevy for the file once, as a `Gltf`. Asked for
    // the scene's label and then for the file's root, Bevy loaded it twice,
    // and the second load's materials replaced the first's after the scene
    // spawned (a change made to them in between was lost).
    let (_, setup) = gltf_setup("leaf-cards.gltf");
    let mut session = Session::new(&setup);
    session.app.init_resource::<LoadEvents>().add_systems(Update, count_load_events);
    session.wait_for_gltf().expect("Bevy loads it");
    session.settle(8).expect("render");
    let events = session.app.world().resource::<LoadEvents>();
    println!("{events:?}");
    assert_eq!((events.gltfs_loaded, events.materials_modified), (1, 0), "{events:?}");
}
