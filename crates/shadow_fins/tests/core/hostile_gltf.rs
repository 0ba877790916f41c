//! Hostile glTF files: a typed error or a valid scene, never a panic, a hang
//! or an allocation the file does not pay for. Runs the fuzz target's committed
//! corpus (`fuzz/corpus/gltf_import`) and generated mutations of its seeds on
//! the stable toolchain; `cargo fuzz run gltf_import` explores further.

use std::{path::Path, time::Instant};

use proptest::prelude::*;
use shadow_fins::{GltfError, gltf_import::parse_gltf};

fn corpus_dir() -> std::path::PathBuf {
    Path::new(&std::env::var("CARGO_MANIFEST_DIR").unwrap()).join("../../fuzz/corpus/gltf_import")
}

fn seed(name: &str) -> Vec<u8> {
    std::fs::read(corpus_dir().join(name)).unwrap()
}

/// What the fuzz target asserts: no panic, bounded time, finite meshes.
fn check(bytes: &[u8]) -> Result<usize, GltfError> {
    let start = Instant::now();
    let result = parse_gltf(bytes, None);
    assert!(start.elapsed().as_secs_f32() < 2.0, "an input took {:?}", start.elapsed());
    result.map(|import| {
        for o in &import.scene.objects {
            assert!(o.mesh.positions().iter().all(|p| p.is_finite()) && o.transform.is_finite());
        }
        import.scene.objects.len()
    })
}

#[test]
fn every_corpus_file_is_a_typed_error_or_a_valid_scene() {
    let mut files = 0;
    for entry in std::fs::read_dir(corpus_dir()).unwrap() {
        let path = entry.unwrap().path();
        let _ = check(&std::fs::read(&path).unwrap());
        files += 1;
    }
    assert!(files >= 15, "the seed corpus is committed ({files} files)");
}

#[test]
fn the_seed_files_say_what_is_wrong() {
    assert_eq!(check(&seed("triangle.gltf")).unwrap(), 1);
    assert_eq!(check(&seed("triangle.glb")).unwrap(), 1);
    assert_eq!(check(&seed("triangle-strip.gltf")).unwrap(), 1);
    // A 4 GiB buffer is refused before anything is allocated for it.
    for name in ["buffer-claims-4gib.gltf", "glb-buffer-claims-4gib.glb"] {
        match check(&seed(name)) {
            Err(GltfError::TooLarge { amount, .. }) => assert!(amount >= 4294967295, "{name}"),
            other => panic!("{name}: {other:?}"),
        }
    }
    // Cycles in the node graph end: each node is visited once.
    assert_eq!(check(&seed("node-cycle.gltf")).unwrap(), 1);
    assert_eq!(check(&seed("node-own-child.gltf")).unwrap(), 1);
    // Accessors the gltf crate's readers would index or assert on.
    for name in [
        "stride-too-short.gltf",
        "count-zero.gltf",
        "positions-wrong-type.gltf",
        "view-offset-overflow.gltf",
        "indices-overrun.gltf",
    ] {
        assert!(matches!(check(&seed(name)), Err(GltfError::Accessor { .. })), "{name}: {:?}", check(&seed(name)));
    }
    // 3000 nodes instancing one primitive: read once, placed 3000 times.
    assert_eq!(check(&seed("many-instances.gltf")).unwrap(), 3000);
    // 1e8 sparse zeros take no bytes: bounded by the file's size, not allocated.
    for name in ["count-huge.gltf", "sparse-no-view-huge.gltf", "sparse-zeros-100m.gltf"] {
        assert!(matches!(check(&seed(name)), Err(GltfError::TooLarge { .. })), "{name}: {:?}", check(&seed(name)));
    }
    // Found by fuzzing: the gltf crate's validation indexed this accessor unchecked.
    for name in [
        "empty",
        "not-json.gltf",
        "glb-truncated.glb",
        "glb-length-lies.glb",
        "position-accessor-out-of-range.gltf",
        "glb-length-below-header.glb",
    ] {
        assert!(matches!(check(&seed(name)), Err(GltfError::Parse(_))), "{name}: {:?}", check(&seed(name)));
    }
}

#[test]
fn a_buffer_that_is_a_device_not_a_file_is_refused() {
    // `/dev/zero` reports 0 bytes and reads forever.
    let text = String::from_utf8(seed("buffer-is-dev-zero.gltf")).unwrap();
    let result = parse_gltf(text.as_bytes(), Some(Path::new("/")));
    assert!(
        matches!(result, Err(GltfError::Buffer { ref reason, .. }) if reason.contains("not a regular file")),
        "{result:?}"
    );
}

/// Replaces the value of every `"key":number` in a glTF's JSON with `value`.
fn with_field(json: &str, key: &str, value: i64) -> String {
    let pattern = format!("\"{key}\":");
    let mut out = String::new();
    let mut rest = json;
    while let Some(at) = rest.find(&pattern) {
        let (head, tail) = rest.split_at(at + pattern.len());
        out += head;
        let end = tail.find(|c: char| !(c.is_ascii_digit() || c == '-' || c == '.')).unwrap_or(tail.len());
        out += &value.to_string();
        rest = &tail[end..];
    }
    out + rest
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    #[test]
    fn mutated_bytes_never_panic(glb in any::<bool>(), flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..8), cut in any::<usize>()) {
        let mut bytes = seed(if glb { "triangle.glb" } else { "triangle.gltf" });
        for (at, byte) in flips {
            let n = bytes.len();
            bytes[at % n] = byte;
        }
        let n = bytes.len();
        bytes.truncate(cut % (n + 1));
        let _ = check(&bytes);
    }

    #[test]
    fn hostile_numbers_in_any_field_never_panic(
        key in prop::sample::select(vec!["count", "byteOffset", "byteLength", "byteStride", "componentType", "mode", "bufferView", "buffer", "mesh", "indices", "POSITION", "nodes"]),
        value in prop_oneof![Just(0i64), Just(-1), Just(1), Just(3), Just(4294967295), Just(4294967296), Just(i64::MAX), 0i64..100_000],
    ) {
        let text = String::from_utf8(seed("triangle.gltf")).unwrap();
        let _ = check(with_field(&text, key, value).as_bytes());
    }
}
