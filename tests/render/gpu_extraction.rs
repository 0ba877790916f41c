//! GPU fin extraction and layer assignment (`shaders/extract_*.wgsl`) against the
//! CPU extraction of the core crate, which the plugin can still run
//! (`FinExtraction::Cpu`): same counts, same visibility.
//!
//! Tolerances. Counts must be equal: both sides run the same rules on the same
//! f32 light-frame positions. Visibility: the two paths differ only in float
//! rounding (the light-frame transform is done on the GPU, fused multiply-adds,
//! a patch's mean depth summed in 64-bit fixed point instead of f32), which can
//! move a fin edge or a slab depth across a texel centre; so the mean absolute
//! difference is bounded by 0.002 (a few texels' worth of a 96×72 image) and
//! any single pixel may differ by at most what one texel of penumbra holds.

use bevy_shadow_fins::{FinExtraction, FinMethod, FinShadowSettings};
use shadow_fins::scenes::SceneId;

use super::common::*;

fn with(extraction: FinExtraction, method: FinMethod) -> FinShadowSettings {
    FinShadowSettings { extraction, method, ..settings() }
}

#[test]
fn gpu_extraction_matches_cpu_extraction() {
    let cases = [
        (SceneId::BoxOverPlane, FinMethod::MultiLayer),
        (SceneId::RingPlate, FinMethod::MultiLayer),
        (SceneId::SphereGrid, FinMethod::MultiLayer),
        (SceneId::StarPrism, FinMethod::MultiLayer),
        (SceneId::NearContact, FinMethod::OuterFins),
        (SceneId::RingPlate, FinMethod::SingleLayer),
        (SceneId::DenseBlob, FinMethod::MultiLayer),
    ];
    for (id, method) in cases {
        let gpu = render(&setup(id, with(FinExtraction::Gpu, method)));
        let cpu = render(&setup(id, with(FinExtraction::Cpu, method)));
        assert_not_trivial(&gpu);
        let (g, c) = (gpu.stats, cpu.stats);
        println!(
            "{} {method:?}: GPU {} silhouettes, {} fins, {} layers; CPU {}, {}, {}",
            id.name(),
            g.silhouettes,
            g.fins,
            g.layers,
            c.silhouettes,
            c.fins,
            c.layers
        );
        // On the GPU path these counts exist only as the GPU's read-back (the
        // main world never extracts), so equal non-zero counts are the GPU's.
        assert!(g.up_to_date && g.silhouettes > 0, "{}: the GPU's counts were read back", id.name());
        assert_eq!((g.silhouettes, g.fins, g.layers), (c.silhouettes, c.fins, c.layers), "{}", id.name());
        let (mad, far) = compare(&gpu.visibility, &cpu.visibility);
        let worst = gpu.visibility.iter().zip(&cpu.visibility).map(|(a, b)| (a - b).abs()).fold(0.0, f32::max);
        println!("  visibility: mean |gpu − cpu| = {mad:.5}, worst {worst:.3}, share > 0.1 = {:.2}%", far * 100.0);
        assert!(mad <= 0.002, "{} {method:?}: mean difference {mad}", id.name());
        assert!(far <= 0.005, "{} {method:?}: {far} of pixels differ by more than 0.1", id.name());
    }
}

#[test]
fn gpu_extraction_of_hard_shadows_builds_no_fin_and_one_layer() {
    let gpu = render(&setup(SceneId::RingPlate, with(FinExtraction::Gpu, FinMethod::Hard)));
    let cpu = render(&setup(SceneId::RingPlate, with(FinExtraction::Cpu, FinMethod::Hard)));
    assert_not_trivial(&gpu);
    assert_eq!((gpu.stats.fins, gpu.stats.layers), (0, 1));
    assert!(gpu.visibility.iter().all(|v| *v == 0.0 || *v == 1.0), "hard shadows are 0 or 1");
    assert_eq!(compare(&gpu.visibility, &cpu.visibility).1, 0.0);
}
