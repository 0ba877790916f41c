//! Settings changed at runtime take effect the next frames, with no restart.

use bevy::prelude::*;
use bevy_shadow_fins::{FinLight, FinShadowSettings};
use shadow_fins::{oracle::Method, scenes::SceneId};
use shadow_fins_app::harness;

use super::common::*;

fn run(app: &mut App, slot: &harness::Slot, frames: u32) -> Vec<f32> {
    for _ in 0..frames {
        app.update();
    }
    // GPU extraction: wait for its counts of this frame (and a redo if it
    // outgrew a buffer), then for the read-back of an image rendered after it.
    for _ in 0..60 {
        if app.world().resource::<bevy_shadow_fins::FinShadowStats>().0.up_to_date {
            break;
        }
        app.update();
    }
    for _ in 0..2 {
        app.update();
    }
    let data = slot.lock().unwrap().take().expect("read-back");
    harness::unpad(WIDTH, HEIGHT, &data).map(f32::from_le_bytes).collect()
}

#[test]
fn radius_layers_and_refinement_change_the_read_back() {
    let mut s = setup(SceneId::RingPlate, settings());
    let (mut app, slots) = harness::app(&s);
    let slot = &slots[0].visibility;
    app.finish();
    app.cleanup();
    let base = run(&mut app, slot, 6);

    let changed = |app: &mut App, f: &dyn Fn(&mut FinLight, &mut FinShadowSettings)| {
        let mut q = app.world_mut().query::<(&mut FinLight, &mut FinShadowSettings)>();
        for (mut l, mut st) in q.iter_mut(app.world_mut()) {
            f(&mut l, &mut st);
        }
    };
    let differs = |a: &[f32], b: &[f32]| a.iter().zip(b).filter(|(x, y)| (*x - *y).abs() > 0.05).count();

    changed(&mut app, &|l, _| l.radius *= 2.0);
    let bigger = run(&mut app, slot, 4);
    assert!(differs(&base, &bigger) > 100, "doubling the radius must widen the penumbrae");

    changed(&mut app, &|l, st| {
        l.radius /= 2.0;
        st.layers = 1;
    });
    let single = run(&mut app, slot, 4);
    assert!(differs(&base, &single) > 20, "one layer leaks light under the plate (fig. 7)");
    let layers = app.world().resource::<bevy_shadow_fins::FinShadowStats>().0.layers;
    assert_eq!(layers, 1);

    changed(&mut app, &|_, st| {
        st.layers = 16;
        st.refinement = false;
    });
    let unrefined = run(&mut app, slot, 4);
    assert!(differs(&base, &unrefined) > 20, "refinement off must change the penumbrae");

    // And the last state still agrees with the oracle for those settings.
    s.settings.refinement = false;
    let expected = oracle(&s, Method::MultiLayer);
    let (mad, _) = compare(&unrefined, &expected);
    assert!(mad <= 0.01, "after the change: mean difference {mad}");
}
