//! glTF in and out: our exporter's files load back the same, and broken files
//! give typed errors rather than panics.

use shadow_fins::{
    GltfError, MeshError,
    gltf_import::{parse_gltf, write_gltf},
    scenes::SceneId,
};

#[test]
fn exported_scenes_load_back_with_the_same_geometry() {
    for id in [SceneId::BoxOverPlane, SceneId::SphereGrid] {
        let s = id.build();
        let text = write_gltf(&s.scene);
        let import = parse_gltf(text.as_bytes(), None).unwrap();
        assert!(import.skipped.is_empty());
        assert_eq!(import.scene.objects.len(), s.scene.objects.len());
        assert_eq!(import.scene.triangle_count(), s.scene.triangle_count());
        let (a, b) = (s.scene.bounds().unwrap(), import.scene.bounds().unwrap());
        assert!((a.0 - b.0).length() < 1e-5 && (a.1 - b.1).length() < 1e-5);
    }
}

/// The committed assets are the built-in scenes as the exporter writes them
/// (regenerate with `shadow-fins-lab export-gltf --scene NAME --out assets/NAME.gltf`).
#[test]
fn the_committed_assets_are_the_built_in_scenes() {
    // The package directory at run time: a test binary reused from a build
    // cache of another checkout must still find this checkout's assets.
    let dir = std::env::var("CARGO_MANIFEST_DIR").unwrap_or_else(|_| env!("CARGO_MANIFEST_DIR").into());
    for id in [SceneId::Demo, SceneId::Kitbash, SceneId::Figure, SceneId::GreebleTower] {
        let path = format!("{dir}/../../assets/{}.gltf", id.name());
        let import = shadow_fins::gltf_import::load_gltf(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
        let built = id.build().scene;
        assert!(import.skipped.is_empty(), "{path}: {:?}", import.skipped);
        assert_eq!(import.scene.triangle_count(), built.triangle_count(), "{path}");
        let (a, b) = (built.bounds().unwrap(), import.scene.bounds().unwrap());
        assert!((a.0 - b.0).length() < 1e-4 && (a.1 - b.1).length() < 1e-4, "{path}: {a:?} vs {b:?}");
    }
}

#[test]
fn broken_files_give_typed_errors() {
    assert!(matches!(parse_gltf(b"not a gltf at all", None), Err(GltfError::Parse(_))));
    let good = write_gltf(&SceneId::BoxOverPlane.build().scene);
    let truncated = &good.as_bytes()[..good.len() / 2];
    assert!(matches!(parse_gltf(truncated, None), Err(GltfError::Parse(_))));
    let missing = good.replace("data:application/octet-stream;base64,", "missing.bin#");
    assert!(matches!(parse_gltf(missing.as_bytes(), None), Err(GltfError::Buffer { .. })));
    assert!(matches!(shadow_fins::gltf_import::load_gltf("/nonexistent/file.gltf"), Err(GltfError::Io { .. })));
}

#[test]
fn a_mesh_with_nan_positions_is_skipped_with_its_reason() {
    // Two objects; poison the first position of the first one with NaN bits.
    let s = SceneId::BoxOverPlane.build();
    let text = write_gltf(&s.scene);
    let start = text.find("base64,").unwrap() + 7;
    // The first 4 bytes of the buffer are the first float: replace them with NaN.
    let nan = [0x00u8, 0x00, 0xc0, 0x7f];
    let b64 = |bytes: &[u8]| {
        const T: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
        let n = (bytes[0] as u32) << 16 | (bytes[1] as u32) << 8 | bytes[2] as u32;
        (0..4).map(|i| T[(n >> (18 - 6 * i) & 63) as usize] as char).collect::<String>()
    };
    // Re-encode the first 6 bytes (two base64 quads) with the NaN float in front.
    let decoded_rest = &text[start + 4..start + 8];
    let _ = decoded_rest;
    let mut bytes = nan.to_vec();
    bytes.extend([0u8, 0]);
    let poisoned = format!("{}{}{}{}", &text[..start], b64(&bytes[0..3]), b64(&bytes[3..6]), &text[start + 8..]);
    let import = parse_gltf(poisoned.as_bytes(), None).unwrap();
    assert_eq!(import.scene.objects.len(), s.scene.objects.len() - 1);
    assert!(matches!(
        import.skipped.as_slice(),
        [GltfError::Mesh { source: MeshError::NonFinitePosition { vertex: 0, .. }, .. }]
    ));
}
