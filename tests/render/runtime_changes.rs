//! Settings changed at runtime take effect the next frames, with no restart.

use bevy::prelude::*;
use bevy_shadow_fins::{FinFrame, FinLight, FinShadowSettings};
use shadow_fins::{oracle::Method, scenes::SceneId};
use shadow_fins_app::harness;

use super::common::*;

fn run(app: &mut App, slot: &std::sync::Arc<std::sync::Mutex<Option<Vec<u8>>>>, frames: u32) -> Vec<f32> {
    for _ in 0..frames {
        app.update();
    }
    let data = slot.lock().unwrap().take().expect("read-back");
    data.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect()
}

#[test]
fn radius_layers_and_refinement_change_the_read_back() {
    let mut s = setup(SceneId::RingPlate, settings());
    let (mut app, slot) = harness::app(&s);
    app.finish();
    app.cleanup();
    // WIDTH * 4 = 384 bytes: rows are padded to 512 in the read-back; compare raw rows.
    let base = run(&mut app, &slot, 6);

    let changed = |app: &mut App, f: &dyn Fn(&mut FinLight, &mut FinShadowSettings)| {
        let mut q = app.world_mut().query::<(&mut FinLight, &mut FinShadowSettings)>();
        for (mut l, mut st) in q.iter_mut(app.world_mut()) {
            f(&mut l, &mut st);
        }
    };
    let differs = |a: &[f32], b: &[f32]| a.iter().zip(b).filter(|(x, y)| (*x - *y).abs() > 0.05).count();

    changed(&mut app, &|l, _| l.radius *= 2.0);
    let bigger = run(&mut app, &slot, 4);
    assert!(differs(&base, &bigger) > 100, "doubling the radius must widen the penumbrae");

    changed(&mut app, &|l, st| {
        l.radius /= 2.0;
        st.layers = 1;
    });
    let single = run(&mut app, &slot, 4);
    assert!(differs(&base, &single) > 20, "one layer leaks light under the plate (fig. 7)");
    let layers = app.world().resource::<FinFrame>().0.as_ref().unwrap().stats.layers;
    assert_eq!(layers, 1);

    changed(&mut app, &|_, st| {
        st.layers = 16;
        st.refinement = false;
    });
    let unrefined = run(&mut app, &slot, 4);
    assert!(differs(&base, &unrefined) > 20, "refinement off must change the penumbrae");

    // And the last state still agrees with the oracle for those settings.
    s.settings.refinement = false;
    let expected = oracle(&s, Method::MultiLayer);
    let shot =
        harness::Shot { width: WIDTH, height: HEIGHT, visibility: unpadded(&unrefined), stats: Default::default() };
    let (mad, _) = compare(&shot, &expected);
    assert!(mad <= 0.01, "after the change: mean difference {mad}");
}

fn unpadded(raw: &[f32]) -> Vec<f32> {
    let row = WIDTH as usize;
    let padded = (row * 4).div_ceil(256) * 256 / 4;
    (0..HEIGHT as usize).flat_map(|y| raw[y * padded..y * padded + row].to_vec()).collect()
}
