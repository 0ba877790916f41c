//! Throughput of the per-frame CPU stage: silhouettes + patches + fins + layer
//! assignment, single-threaded, on the bumpy blob from 1k to 1M triangles —
//! all three together, then each stage alone (groups `stage/silhouettes`,
//! `stage/fins`, `stage/layers`), so that how each grows with `n` shows.
//!
//! `cargo bench -p shadow_fins --bench pipeline`
//!
//! The floor is ≥ 50 M triangles/s on one core at 100k triangles. The
//! paper's CPU stage costs t = 22.69 ms + n / 238.72 ms (n triangles);
//! `scripts/benchmarks.sh` fits the same line to these numbers.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use shadow_fins::{
    glam::{Affine3A, Vec3},
    light::{DiskLight, Light},
    oracle::FinExtractor,
    scene::{LightSpaceScene, Scene, SceneObject},
    shapes,
};

fn blob_scene(triangles: u32) -> (Scene, Light) {
    let blob =
        SceneObject::new("blob", shapes::bumpy_blob(triangles), Affine3A::from_translation(Vec3::Y * 1.5)).unwrap();
    let light = Light::Disk(DiskLight::new(Vec3::new(0.4, 5.0, 0.0), Vec3::NEG_Y, 0.5).unwrap());
    (Scene::new(vec![blob]), light)
}

fn extraction(c: &mut Criterion) {
    let mut group = c.benchmark_group("silhouette+fins+layers");
    group.sample_size(20);
    for triangles in [1_000u32, 10_000, 100_000, 1_000_000] {
        let (scene, light) = blob_scene(triangles);
        let ls = LightSpaceScene::new(&scene, light);
        let count = scene.triangle_count() as u64;
        let mut ex = FinExtractor::default();
        group.throughput(Throughput::Elements(count));
        group.bench_with_input(BenchmarkId::from_parameter(count), &count, |b, _| {
            b.iter(|| {
                ex.extract(&scene, &ls, 16, 1024);
                std::hint::black_box(ex.fins.len())
            })
        });
    }
    group.finish();
}

/// Each stage alone; the stages before it run once outside the timing.
fn stages(c: &mut Criterion) {
    for stage in ["silhouettes", "fins", "layers"] {
        let mut group = c.benchmark_group(format!("stage/{stage}"));
        group.sample_size(10);
        for triangles in [1_000u32, 10_000, 100_000, 1_000_000] {
            let (scene, light) = blob_scene(triangles);
            let ls = LightSpaceScene::new(&scene, light);
            let count = scene.triangle_count() as u64;
            let mut ex = FinExtractor::default();
            ex.extract(&scene, &ls, 16, 1024);
            group.throughput(Throughput::Elements(count));
            group.bench_with_input(BenchmarkId::from_parameter(count), &count, |b, _| {
                b.iter(|| {
                    match stage {
                        "silhouettes" => ex.extract_silhouettes(&scene, &ls),
                        "fins" => ex.build_fins(&ls),
                        _ => ex.assign_layers(16, 1024),
                    }
                    std::hint::black_box((ex.silhouettes.len(), ex.fins.len(), ex.plan.len()))
                })
            });
        }
        group.finish();
    }
}

criterion_group!(benches, extraction, stages);
criterion_main!(benches);
