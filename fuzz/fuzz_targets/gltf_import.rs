//! glTF/GLB bytes into the core's scene: a typed error or valid meshes, never a
//! panic, a hang or an allocation the input does not pay for.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(import) = shadow_fins::gltf_import::parse_gltf(data, None) {
        for object in &import.scene.objects {
            assert!(object.mesh.positions().iter().all(|p| p.is_finite()));
            assert!(object.transform.is_finite());
        }
    }
});
