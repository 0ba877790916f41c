//! The lab's command line: real runs of the binary, good and bad input.

use std::process::Command;

fn lab(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_shadow-fins-lab")).args(args).output().expect("run shadow-fins-lab")
}

fn temp(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("shadow-fins-lab-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn visibility_writes_one_row_per_point_and_methods_agree_where_they_must() {
    let points = temp("points.csv");
    // Under the box's shadow centre (umbra), and far away (lit).
    std::fs::write(&points, "x,y,z,nx,ny,nz\n-0.24,0,-0.16,0,1,0\n4,0,4,0,1,0\n").unwrap();
    for method in [
        "ground-truth",
        "fins",
        "hard",
        "outer-fins",
        "single-layer",
        "coverage",
        "single-sample",
        "plateaus",
        "penumbra-wedges",
        "wedge-blending",
    ] {
        let out =
            lab(&["visibility", "--scene", "box-over-plane", "--points", points.to_str().unwrap(), "--method", method]);
        assert!(out.status.success(), "{method}: {}", String::from_utf8_lossy(&out.stderr));
        let text = String::from_utf8(out.stdout).unwrap();
        let values: Vec<f32> = text.lines().skip(1).map(|l| l.rsplit(',').next().unwrap().parse().unwrap()).collect();
        assert_eq!(values.len(), 2, "{method}");
        assert!(values[0] < 0.01 && values[1] > 0.999, "{method}: {values:?}");
    }
}

#[test]
fn the_raster_oracle_and_settings_flags_are_accepted() {
    let points = temp("points2.csv");
    std::fs::write(&points, "0.9,0,0.7\n").unwrap();
    let out = lab(&[
        "visibility",
        "--scene",
        "box-over-plane",
        "--points",
        points.to_str().unwrap(),
        "--method",
        "fins",
        "--map-resolution",
        "256",
        "--layers",
        "4",
        "--sub-layers",
        "64",
        "--no-refinement",
        "--falloff",
        "bernstein",
        "--overlap",
        "min-max",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: f32 =
        String::from_utf8(out.stdout).unwrap().lines().nth(1).unwrap().rsplit(',').next().unwrap().parse().unwrap();
    assert!((0.0..=1.0).contains(&v));
}

#[test]
fn bad_input_gets_a_clear_error_and_a_non_zero_exit() {
    let points = temp("points3.csv");
    std::fs::write(&points, "0,0,0\n").unwrap();
    let p = points.to_str().unwrap();
    let cases: [(&[&str], &str); 6] = [
        (&["visibility", "--points", p, "--radius", "-1"], "radius -1"),
        (&["visibility", "--points", p, "--layers", "0"], "layer count 0"),
        (&["visibility", "--points", p, "--method", "magic"], "unknown method"),
        (&["visibility", "--points", p, "--method", "coverage", "--coverage-samples", "0"], "--coverage-samples 0"),
        (&["visibility", "--points", p, "--scene", "nowhere"], "unknown scene"),
        (&["visibility", "--points", "/nonexistent.csv"], "/nonexistent.csv"),
    ];
    for (args, expected) in cases {
        let out = lab(args);
        assert!(!out.status.success(), "{args:?} should fail");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(expected), "{args:?}: stderr was {err}");
    }
    let broken = temp("broken.gltf");
    std::fs::write(&broken, "{ this is not json").unwrap();
    let out = lab(&["visibility", "--points", p, "--gltf", broken.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a valid glTF"));
    std::fs::write(&points, "0,nan,0\n").unwrap();
    let out = lab(&["visibility", "--points", p]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("line 1"));
}

#[test]
fn image_writes_a_png_strip_that_is_not_blank() {
    let png = temp("strip.png");
    let out = lab(&[
        "image",
        "--scene",
        "box-over-plane",
        "--width",
        "48",
        "--height",
        "36",
        "--samples",
        "64",
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(
        table.contains("| hard |")
            && table.contains("| fins 16L |")
            && table.contains("| fins 16L paper |")
            && table.contains("| single-sample |")
            && table.contains("| plateaus |")
            && table.contains("| penumbra-wedges |")
            && table.contains("| wedge-blending |")
            && table.contains("| convolution |"),
        "{table}"
    );
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[1..4], b"PNG");
    // Decode and check the picture has both dark and bright pixels (not a black image).
    let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    let data = &buf[..info.buffer_size()];
    let (dark, bright) = (data.iter().filter(|&&b| b < 20).count(), data.iter().filter(|&&b| b > 235).count());
    assert!(dark > 100 && bright > 100, "dark {dark}, bright {bright}");
}

/// The environment experiment: every shadow kind at each threshold, the
/// light count growing with `t`, convolution within the errors the fit
/// allows, and bad thresholds a usage error.
#[test]
fn environment_fits_more_lights_at_a_higher_threshold_and_scores_each_shadow_kind() {
    let png = temp("environment.png");
    let args = ["environment", "--scene", "box-over-plane", "--cube", "12", "--width", "40", "--height", "30"];
    let out = lab(&[&args[..], &["--thresholds", "0.03,0.12", "--out", png.to_str().unwrap()]].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let table = String::from_utf8(out.stdout).unwrap();
    let rows: Vec<Vec<&str>> = table
        .lines()
        .filter(|l| l.starts_with("| 0."))
        .map(|l| l.split('|').map(str::trim).filter(|c| !c.is_empty()).collect())
        .collect();
    assert_eq!(rows.len(), 2 * 4, "{table}");
    let lights = |t: &str| rows.iter().find(|r| r[0] == t).map(|r| r[1].parse::<usize>().unwrap()).unwrap();
    assert!(lights("0.12") > lights("0.03"), "{table}");
    for r in &rows {
        let mae: f32 = r[3].parse().unwrap();
        assert!(mae.is_finite() && (0.0..0.2).contains(&mae), "{r:?}");
    }
    assert!(std::fs::read(&png).unwrap().starts_with(b"\x89PNG"));
    let bad = lab(&[&args[..], &["--thresholds", "0", "--out", png.to_str().unwrap()]].concat());
    assert!(!bad.status.success() && String::from_utf8_lossy(&bad.stderr).contains("--thresholds"));
}
#[test]
fn exported_gltf_round_trips_through_the_cli() {
    let gltf = temp("scene.gltf");
    let out = lab(&["export-gltf", "--scene", "star-prism", "--out", gltf.to_str().unwrap()]);
    assert!(out.status.success());
    let points = temp("points4.csv");
    std::fs::write(&points, "0,0,0,0,1,0\n").unwrap();
    let out = lab(&[
        "visibility",
        "--gltf",
        gltf.to_str().unwrap(),
        "--light-center",
        "0,4,0",
        "--radius",
        "0.5",
        "--points",
        points.to_str().unwrap(),
        "--method",
        "fins",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // The star's centre is right above the origin: full umbra there.
    let v: f32 =
        String::from_utf8(out.stdout).unwrap().lines().nth(1).unwrap().rsplit(',').next().unwrap().parse().unwrap();
    assert!(v < 0.01, "{v}");
}

// ---------------------------------------------------------------------------
// `make-assets`: our own glTF test assets.

use shadow_fins::glam::{Mat4, Quat, Vec3, vec3};
use shadow_fins_lab::assets::{self, FILES};

/// The workspace's committed `assets/` folder.
fn committed_assets() -> std::path::PathBuf {
    // At run time: a binary built in another clone must not read that clone's folder.
    let manifest = std::env::var("CARGO_MANIFEST_DIR").unwrap_or_else(|_| env!("CARGO_MANIFEST_DIR").into());
    std::path::Path::new(&manifest).join("../../assets")
}

/// Standard or URL-safe base64, written here rather than taken from the generator.
fn unbase64(s: &str) -> Vec<u8> {
    let value = |c: u8| match c {
        b'A'..=b'Z' => c - b'A',
        b'a'..=b'z' => c - b'a' + 26,
        b'0'..=b'9' => c - b'0' + 52,
        b'+' | b'-' => 62,
        b'/' | b'_' => 63,
        _ => panic!("not base64: {:?}", c as char),
    };
    let (mut out, mut acc, mut bits) = (Vec::new(), 0u32, 0);
    for &c in s.as_bytes().iter().take_while(|&&c| c != b'=') {
        acc = (acc << 6) | value(c) as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
        }
    }
    out
}

fn data_uri(uri: &str) -> Vec<u8> {
    let (_, data) = uri.split_once(";base64,").expect("a base64 data: URI");
    unbase64(data)
}

/// A generated asset parsed by the `gltf` crate (which validates it), its
/// buffers decoded, and its JSON as a plain value.
struct Parsed {
    gltf: gltf::Gltf,
    buffers: Vec<Vec<u8>>,
    json: gltf::json::Value,
    text: String,
}

fn parsed(file: &str) -> Parsed {
    let text = assets::all().unwrap().into_iter().find(|a| a.file == file).expect(file).text;
    let gltf = gltf::Gltf::from_slice(text.as_bytes()).unwrap_or_else(|e| panic!("{file}: {e}"));
    let buffers = gltf
        .buffers()
        .map(|b| match b.source() {
            gltf::buffer::Source::Uri(uri) => data_uri(uri),
            gltf::buffer::Source::Bin => panic!("{file}: a .gltf has no BIN chunk"),
        })
        .collect();
    let json = gltf::json::deserialize::from_slice(text.as_bytes()).unwrap();
    Parsed { gltf, buffers, json, text }
}

impl Parsed {
    fn node(&self, name: &str) -> gltf::Node<'_> {
        self.gltf.nodes().find(|n| n.name() == Some(name)).unwrap_or_else(|| panic!("no node {name}"))
    }

    fn parent(&self, node: usize) -> Option<gltf::Node<'_>> {
        self.gltf.nodes().find(|n| n.children().any(|c| c.index() == node))
    }

    /// The node's world matrix, composed here from its ancestors' local transforms.
    fn world(&self, node: &gltf::Node) -> Mat4 {
        let local = Mat4::from_cols_array_2d(&node.transform().matrix());
        self.parent(node.index()).map_or(local, |p| self.world(&p) * local)
    }

    fn buffer<'s>(&'s self) -> impl Clone + Fn(gltf::Buffer<'_>) -> Option<&'s [u8]> + 's {
        move |b| self.buffers.get(b.index()).map(|d| d.as_slice())
    }
}

fn forward(node: &gltf::Node) -> (Vec3, Vec3) {
    let (t, r, _) = node.transform().decomposed();
    (Vec3::from(t), Quat::from_array(r) * Vec3::NEG_Z)
}

#[test]
fn make_assets_writes_the_committed_files_and_the_same_bytes_every_run() {
    let (a, b) = (temp("assets-a"), temp("assets-b"));
    for dir in [&a, &b] {
        let out = lab(&["make-assets", "--out", dir.to_str().unwrap()]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    for file in FILES {
        let first = std::fs::read(a.join(file)).unwrap();
        assert_eq!(first, std::fs::read(b.join(file)).unwrap(), "{file} differs between two runs");
        assert!(first.len() < 200_000, "{file} is {} bytes", first.len());
        let committed = std::fs::read(committed_assets().join(file))
            .unwrap_or_else(|e| panic!("assets/{file}: {e}; run `shadow-fins-lab make-assets --out assets`"));
        assert!(
            committed == first,
            "assets/{file} is not what the generator writes now: run `shadow-fins-lab make-assets --out assets`"
        );
    }
}

#[test]
fn every_asset_is_valid_gltf_with_normals_uvs_indices_and_true_bounds_and_imports_whole() {
    use gltf::{Semantic, accessor::DataType};
    for file in FILES {
        let p = parsed(file);
        assert_eq!(p.gltf.scenes().count(), 1, "{file}");
        let mut placed = 0;
        for node in p.gltf.nodes() {
            let Some(mesh) = node.mesh() else { continue };
            placed += mesh.primitives().count();
        }
        for mesh in p.gltf.meshes() {
            for prim in mesh.primitives() {
                let what = format!("{file}: mesh {:?}", mesh.name());
                assert_eq!(prim.mode(), gltf::mesh::Mode::Triangles, "{what}");
                for semantic in [Semantic::Positions, Semantic::Normals, Semantic::TexCoords(0)] {
                    assert!(prim.get(&semantic).is_some(), "{what} has no {semantic:?}");
                }
                let indices = prim.indices().unwrap_or_else(|| panic!("{what} has no indices"));
                assert!(matches!(indices.data_type(), DataType::U16 | DataType::U32), "{what}");
                let reader = prim.reader(p.buffer());
                let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
                let normals: Vec<[f32; 3]> = reader.read_normals().unwrap().collect();
                let uvs = reader.read_tex_coords(0).unwrap().into_f32().count();
                assert!(normals.len() == positions.len() && uvs == positions.len(), "{what}");
                assert!(normals.iter().all(|n| (Vec3::from(*n).length() - 1.0).abs() < 1e-5), "{what}");
                let max_index = reader.read_indices().unwrap().into_u32().max().unwrap();
                assert!((max_index as usize) < positions.len(), "{what}");
                let (lo, hi) = positions.iter().fold(([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]), |(lo, hi), p| {
                    (std::array::from_fn(|i| lo[i].min(p[i])), std::array::from_fn(|i| hi[i].max(p[i])))
                });
                let bounds = prim.bounding_box();
                assert_eq!((bounds.min, bounds.max), (lo, hi), "{what}: POSITION min/max");
            }
        }
        let import = shadow_fins::gltf_import::parse_gltf(p.text.as_bytes(), None).unwrap();
        assert!(import.skipped.is_empty(), "{file}: {:?}", import.skipped);
        assert_eq!(import.scene.objects.len(), placed, "{file}: every placed primitive imported");
    }
}

#[test]
fn every_asset_has_one_spot_light_with_a_radius_and_one_camera_aimed_into_it() {
    for file in FILES {
        let p = parsed(file);
        let j = &p.json;
        let used = j["extensionsUsed"].as_array().unwrap();
        assert!(used.iter().any(|e| e == "KHR_lights_punctual"), "{file}");
        let lights = j["extensions"]["KHR_lights_punctual"]["lights"].as_array().unwrap();
        assert_eq!(lights.len(), 1, "{file}");
        let light = &lights[0];
        let num = |v: &gltf::json::Value| v.as_f64().unwrap();
        assert_eq!(light["type"], "spot", "{file}");
        assert_eq!(num(&light["extras"]["radius"]), 0.4, "{file}: the radius extra");
        assert_eq!((num(&light["intensity"]), num(&light["range"])), (80000.0, 40.0), "{file}");
        let cone = (num(&light["spot"]["innerConeAngle"]), num(&light["spot"]["outerConeAngle"]));
        assert!((cone.0 - 0.3).abs() < 1e-6 && (cone.1 - 0.8).abs() < 1e-6, "{file}: {cone:?}");
        let nodes = j["nodes"].as_array().unwrap();
        let lit: Vec<usize> =
            (0..nodes.len()).filter(|&i| !nodes[i]["extensions"]["KHR_lights_punctual"].is_null()).collect();
        assert_eq!(lit.len(), 1, "{file}: one node holds the light");
        assert_eq!(p.gltf.cameras().count(), 1, "{file}");
        let camera = p.gltf.cameras().next().unwrap();
        let gltf::camera::Projection::Perspective(persp) = camera.projection() else { panic!("{file}: orthographic") };
        assert_eq!((persp.yfov(), persp.znear(), persp.zfar()), (0.8, 0.05, Some(200.0)), "{file}");
        let viewers: Vec<_> = p.gltf.nodes().filter(|n| n.camera().is_some()).collect();
        assert_eq!(viewers.len(), 1, "{file}");
        // Both look down their −Z at the scene's middle, a metre up; at the table in the courtyard.
        for node in [p.gltf.nodes().nth(lit[0]).unwrap(), viewers[0].clone()] {
            assert!(p.parent(node.index()).is_none(), "{file}: {:?} is a root", node.name());
            let (at, dir) = forward(&node);
            let middle = vec3(0.0, 1.0, 0.0);
            let miss = (middle - at).reject_from(dir).length();
            assert!(dir.dot(middle - at) > 0.0 && miss < 0.75, "{file}: {:?} misses by {miss} m", node.name());
            if file == "courtyard.gltf" {
                let to_table = (Vec3::from(assets::COURTYARD_TARGET) - at).normalize();
                assert!(dir.dot(to_table) > 0.9999, "{file}: {:?} looks along {dir}", node.name());
            }
        }
        let (spot_at, _) = forward(&p.gltf.nodes().nth(lit[0]).unwrap());
        if file == "courtyard.gltf" {
            assert_eq!(spot_at, vec3(3.0, 6.0, 2.0));
            assert_eq!(forward(&viewers[0]).0, vec3(6.0, 4.0, 8.0));
        }
    }
}

#[test]
fn courtyard_imports_as_its_node_hierarchy_composes() {
    let p = parsed("courtyard.gltf");
    // The hierarchy: table → leg.0 → vase, one leg by a matrix, the root scaled unevenly.
    let vase = p.node("vase");
    let chain: Vec<_> = std::iter::successors(Some(vase.clone()), |n| p.parent(n.index())).collect();
    let names: Vec<_> = chain.iter().map(|n| n.name().unwrap()).collect();
    assert_eq!(names, ["vase", "leg.0", "table"], "three levels deep");
    assert!(matches!(p.node("leg.3").transform(), gltf::scene::Transform::Matrix { .. }));
    let (_, rotation, scale) = p.node("table").transform().decomposed();
    assert!(rotation[0] == 0.0 && rotation[2] == 0.0 && rotation[1] != 0.0, "a Y rotation: {rotation:?}");
    assert!(scale[0] != scale[2], "non-uniform scale {scale:?}");

    // Materials: two textured, the rest plain colours, all rough dielectrics.
    let materials: Vec<_> = p.gltf.materials().collect();
    let textured = materials.iter().filter(|m| m.pbr_metallic_roughness().base_color_texture().is_some()).count();
    assert!(materials.len() >= 3 && textured == 2, "{} materials, {textured} textured", materials.len());
    for m in &materials {
        let pbr = m.pbr_metallic_roughness();
        assert!(pbr.metallic_factor() == 0.0 && (pbr.roughness_factor() - 0.8).abs() < 1e-6, "{:?}", m.name());
    }
    let ground = p.node("ground").mesh().unwrap().primitives().next().unwrap();
    let b = ground.bounding_box();
    assert_eq!((b.min, b.max), ([-6.0, 0.0, -6.0], [6.0, 0.0, 6.0]), "a 12 m ground at y = 0");
    let sampler = ground.material().pbr_metallic_roughness().base_color_texture().unwrap().texture().sampler();
    assert_eq!(sampler.wrap_s(), gltf::texture::WrappingMode::Repeat);

    // The importer's world triangles are the hierarchy's transforms, composed independently here.
    let import = shadow_fins::gltf_import::parse_gltf(p.text.as_bytes(), None).unwrap();
    let world_points = |name: &str| -> Vec<Vec<(Vec3, Vec3)>> {
        let objects = import.scene.objects.iter().filter(|o| o.name == name);
        objects.map(|o| o.mesh.positions().iter().map(|&q| (q, o.transform.transform_point3(q))).collect()).collect()
    };
    let table = Mat4::from_scale_rotation_translation(
        vec3(1.15, 1.0, 0.85),
        Quat::from_xyzw(0.0, 0.25, 0.0, 1.0).normalize(),
        vec3(0.4, 0.0, -0.3),
    );
    let leg0 = Mat4::from_translation(vec3(0.6, 0.4, 0.35));
    let vase_local =
        Mat4::from_rotation_translation(Quat::from_xyzw(0.0, 0.6, 0.0, 1.0).normalize(), vec3(-0.15, 0.48, -0.1));
    let vase_world = table * leg0 * vase_local;
    let vases = world_points("vase");
    assert_eq!(vases.len(), 1);
    let vase_top = vase_world.transform_point3(vec3(0.0, 0.34, 0.0));
    assert!(vases[0].iter().any(|(_, w)| w.distance(vase_top) < 1e-5), "no vertex at the vase's top {vase_top}");
    for (local, world) in &vases[0] {
        assert!(vase_world.transform_point3(*local).distance(*world) < 1e-5, "{local} → {world}");
    }
    let leg3 = table
        * Mat4::from_rotation_translation(Quat::from_rotation_y(std::f32::consts::FRAC_PI_4), vec3(0.6, 0.4, -0.35));
    let legs = world_points("leg");
    assert_eq!(legs.len(), 4, "one leg mesh, four instances");
    assert!(
        legs.iter().any(|leg| leg.iter().all(|(l, w)| leg3.transform_point3(*l).distance(*w) < 1e-5)),
        "no leg placed by leg.3's matrix"
    );
    let top = table * Mat4::from_translation(vec3(0.0, 0.84, 0.0));
    let tops = world_points("top");
    assert!(tops[0].iter().all(|(l, w)| top.transform_point3(*l).distance(*w) < 1e-5));
    let top_height = tops[0].iter().map(|(_, w)| w.y).fold(f32::MIN, f32::max);
    assert!((0.8..=1.0).contains(&top_height), "table top at {top_height} m");
    // The arch's parts overlap one another and stand on the ground.
    let aabb = |points: &[(Vec3, Vec3)]| {
        points.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), (_, w)| (lo.min(*w), hi.max(*w)))
    };
    let lintel = aabb(&world_points("lintel")[0]);
    let pillars = world_points("pillar");
    assert_eq!(pillars.len(), 2);
    for pillar in &pillars {
        let pillar = aabb(pillar);
        assert!(pillar.0.y.abs() < 1e-6, "pillar stands on the ground: {pillar:?}");
        assert!(pillar.0.cmple(lintel.1).all() && lintel.0.cmple(pillar.1).all(), "{pillar:?} misses {lintel:?}");
    }
}

#[test]
fn leaf_cards_are_masked_double_sided_and_their_leaf_has_holes() {
    let p = parsed("leaf-cards.gltf");
    let leaf = p.gltf.materials().find(|m| m.name() == Some("leaf")).unwrap();
    assert_eq!(leaf.alpha_mode(), gltf::material::AlphaMode::Mask);
    assert_eq!(leaf.alpha_cutoff(), Some(0.5));
    assert!(leaf.double_sided());
    let cards = p.gltf.nodes().filter(|n| n.mesh().is_some_and(|m| m.name() == Some("leaf"))).count();
    assert!((3..=6).contains(&cards), "{cards} cards");
    let import = shadow_fins::gltf_import::parse_gltf(p.text.as_bytes(), None).unwrap();
    for o in import.scene.objects.iter().filter(|o| o.name == "leaf") {
        let low = o.mesh.positions().iter().map(|&q| o.transform.transform_point3(q).y).fold(f32::MAX, f32::min);
        assert!(low > 0.05, "a card dips to y = {low}");
    }

    let texture = leaf.pbr_metallic_roughness().base_color_texture().unwrap().texture();
    let gltf::image::Source::Uri { uri, .. } = texture.source().source() else { panic!("not a URI") };
    let decoder = png::Decoder::new(std::io::Cursor::new(data_uri(uri)));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgba);
    let (w, h) = (info.width as usize, info.height as usize);
    let alpha: Vec<u8> = buf[..info.buffer_size()].chunks(4).map(|t| t[3]).collect();
    assert!(alpha.iter().all(|&a| a == 0 || a == 255), "alpha is 0 or 1");
    let clear = alpha.iter().filter(|&&a| a == 0).count();
    assert!(clear > 0 && clear < w * h, "{clear} of {} texels clear", w * h);
    // Flood the clear texels reachable from the border: what stays unreached is a hole in the leaf.
    let mut outside = vec![false; w * h];
    let mut stack: Vec<usize> = (0..w * h)
        .filter(|&i| (i % w == 0 || i % w == w - 1 || i / w == 0 || i / w == h - 1) && alpha[i] == 0)
        .collect();
    while let Some(i) = stack.pop() {
        if std::mem::replace(&mut outside[i], true) {
            continue;
        }
        let (x, y) = (i % w, i / w);
        let neighbours =
            [(x > 0, i.wrapping_sub(1)), (x + 1 < w, i + 1), (y > 0, i.wrapping_sub(w)), (y + 1 < h, i + w)];
        stack.extend(neighbours.into_iter().filter(|&(ok, j)| ok && alpha[j] == 0 && !outside[j]).map(|(_, j)| j));
    }
    let mut holes = 0;
    let mut seen = outside.clone();
    for start in 0..w * h {
        if alpha[start] != 0 || seen[start] {
            continue;
        }
        holes += 1;
        let mut stack = vec![start];
        while let Some(i) = stack.pop() {
            if std::mem::replace(&mut seen[i], true) {
                continue;
            }
            let (x, y) = (i % w, i / w);
            // A hole never reaches the border, so its neighbours are all inside the image.
            assert!(x > 0 && x + 1 < w && y > 0 && y + 1 < h);
            stack.extend([i - 1, i + 1, i - w, i + w].into_iter().filter(|&j| alpha[j] == 0 && !seen[j]));
        }
    }
    assert!(holes >= 2, "{holes} holes in the leaf");
}

#[test]
fn skinned_arm_weights_sum_to_one_and_the_animation_bends_it() {
    let p = parsed("skinned-arm.gltf");
    let skinned: Vec<_> = p.gltf.nodes().filter(|n| n.skin().is_some()).collect();
    assert_eq!(skinned.len(), 1);
    let arm = &skinned[0];
    assert!(p.parent(arm.index()).is_none(), "the skinned mesh's node is a root");
    assert_eq!(Mat4::from_cols_array_2d(&arm.transform().matrix()), Mat4::IDENTITY);
    let skin = arm.skin().unwrap();
    let joints: Vec<_> = skin.joints().collect();
    assert!((2..=3).contains(&joints.len()), "{} joints", joints.len());
    for pair in joints.windows(2) {
        assert_eq!(p.parent(pair[1].index()).map(|n| n.index()), Some(pair[0].index()), "a joint chain");
    }
    let inverse_binds: Vec<_> = skin.reader(p.buffer()).read_inverse_bind_matrices().unwrap().collect();
    assert_eq!(inverse_binds.len(), joints.len());
    for (joint, inverse) in joints.iter().zip(&inverse_binds) {
        let product = Mat4::from_cols_array_2d(inverse) * p.world(joint);
        assert!(product.abs_diff_eq(Mat4::IDENTITY, 1e-6), "{:?}: {product}", joint.name());
    }

    let prim = arm.mesh().unwrap().primitives().next().unwrap();
    let reader = prim.reader(p.buffer());
    let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
    let mut heights: Vec<f32> = positions.iter().map(|q| q[1]).collect();
    heights.sort_by(f32::total_cmp);
    heights.dedup();
    assert!(heights.len() >= 4, "at least three segments: {heights:?}");
    let skin_joints: Vec<[u16; 4]> = reader.read_joints(0).unwrap().into_u16().collect();
    let weights: Vec<[f32; 4]> = reader.read_weights(0).unwrap().into_f32().collect();
    assert_eq!((skin_joints.len(), weights.len()), (positions.len(), positions.len()));
    for (j, w) in skin_joints.iter().zip(&weights) {
        assert!((w.iter().sum::<f32>() - 1.0).abs() < 1e-6, "weights {w:?}");
        assert!(w.iter().all(|&x| x >= 0.0) && j.iter().all(|&k| (k as usize) < joints.len()), "{j:?} {w:?}");
    }

    let animation = p.gltf.animations().next().unwrap();
    let mut rotations: std::collections::HashMap<usize, (Quat, Quat)> = Default::default();
    for channel in animation.channels() {
        assert_eq!(channel.target().property(), gltf::animation::Property::Rotation);
        assert_eq!(channel.sampler().interpolation(), gltf::animation::Interpolation::Linear);
        let reader = channel.reader(p.buffer());
        let times: Vec<f32> = reader.read_inputs().unwrap().collect();
        assert_eq!(times.last(), Some(&2.0), "a 2 s animation");
        let Some(gltf::animation::util::ReadOutputs::Rotations(r)) = reader.read_outputs() else { panic!() };
        let keys: Vec<Quat> = r.into_f32().map(Quat::from_array).collect();
        let at = |t: f32| keys[times.iter().position(|&k| k == t).expect("a key at 0 s and at 1 s")];
        let (start, bent) = (at(0.0), at(1.0));
        assert!(start.dot(bent).abs() < 0.99, "{:?} barely turns", channel.target().node().name());
        rotations.insert(channel.target().node().index(), (start, bent));
    }
    // The chain's tip at 0 s and 1 s, each joint's rest translation with its animated rotation.
    let tip = |pick: fn(&(Quat, Quat)) -> Quat| {
        let mut world = Mat4::IDENTITY;
        for joint in &joints {
            let (t, r, s) = joint.transform().decomposed();
            let r = rotations.get(&joint.index()).map_or(Quat::from_array(r), pick);
            world *= Mat4::from_scale_rotation_translation(s.into(), r, t.into());
        }
        world.transform_point3(Vec3::ZERO)
    };
    let (straight, bent) = (tip(|r| r.0), tip(|r| r.1));
    assert!(straight.distance(bent) > 0.3, "the wrist moves from {straight} to {bent}");
}

#[test]
fn morph_blob_grows_a_spike_from_its_top() {
    let p = parsed("morph-blob.gltf");
    let node = p.node("blob");
    let mesh = node.mesh().unwrap();
    let prim = mesh.primitives().next().unwrap();
    let targets: Vec<_> = prim.reader(p.buffer()).read_morph_targets().collect();
    assert!((1..=2).contains(&targets.len()));
    assert_eq!(mesh.weights().map(<[f32]>::len), Some(targets.len()), "default weights");
    let rise = targets
        .into_iter()
        .flat_map(|(positions, _, _)| positions.expect("POSITION displacements"))
        .map(|d| d[1])
        .fold(f32::MIN, f32::max);
    assert!(rise > 1.0, "the tallest displacement is {rise} m");
    let animation = p.gltf.animations().next().unwrap();
    let channel = animation.channels().next().unwrap();
    assert_eq!(channel.target().node().index(), node.index());
    assert_eq!(channel.target().property(), gltf::animation::Property::MorphTargetWeights);
    let reader = channel.reader(p.buffer());
    let times: Vec<f32> = reader.read_inputs().unwrap().collect();
    assert_eq!(times.last(), Some(&2.0));
    let Some(gltf::animation::util::ReadOutputs::MorphTargetWeights(w)) = reader.read_outputs() else { panic!() };
    let weights: Vec<f32> = w.into_f32().collect();
    assert_eq!(weights.len(), times.len() * mesh.weights().unwrap().len());
    assert!(weights.contains(&0.0) && weights.contains(&1.0), "from none to full: {weights:?}");
}
