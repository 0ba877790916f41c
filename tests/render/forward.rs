//! Fin shadows on forward-rendered materials (issue 12, item 3): Bevy's own
//! forward PBR shading of each fin-shadowed light, times its visibility layer
//! (the forward hook, `render/forward.rs`), for every kind of Bevy light.
//!
//! Tolerances as in `lights.rs`: per pixel with tonemapping off, shadowed =
//! dark + V × (lit − dark) in 8-bit sRGB steps (≤ 0.0088 linear each; three
//! images): mean ≤ 0.005, p99 ≤ 0.02.

use bevy_shadow_fins::FinShadowSettings;
use shadow_fins::{
    light::{Light, RectLight, SphereLight},
    scenes::SceneId,
};
use shadow_fins_app::harness::Setup;

use super::common::*;

/// The box over the plane, every material forward (Bevy's default), lit by
/// one fin-shadowed Bevy light of `kind`.
fn forward_setup(kind: &str) -> Setup {
    let mut s = setup(SceneId::BoxOverPlane, FinShadowSettings { ..settings() });
    s.forward = true;
    let Light::Disk(d) = s.light else { unreachable!("box-over-plane has a disk light") };
    match kind {
        "spot" => {
            s.spot = true;
            s.intensity = 1.5e5;
        }
        "point" => {
            s.light = Light::Sphere(SphereLight::new(d.center, d.radius).expect("a valid sphere"));
            s.intensity = 2.0e5;
        }
        "rect" => {
            s.light = Light::Rect(RectLight::with_area_of(&d, 4.0).expect("a valid rectangle"));
            s.intensity = 2.0e4;
        }
        "sun" => {
            s.light = Light::Sun(shadow_fins_app::render_lab::sun::sun_over(&d, None));
            s.sun_illuminance = 1500.0;
        }
        _ => unreachable!("a Bevy light kind"),
    }
    s
}

#[test]
fn forward_materials_get_every_bevy_lights_fin_shadow() {
    for kind in ["spot", "point", "rect", "sun"] {
        let shadowed = forward_setup(kind);
        let mut dark = shadowed.clone();
        (dark.intensity, dark.sun_illuminance) = (0.0, 0.0);
        // Without the hook a forward mesh shows no fin shadow at all (Bevy's
        // maps are off for the fin-shadowed light): its umbra would be lit.
        SingleLightComposite::render(&shadowed, &dark, &format!("forward_{kind}"))
            .assert_is_the_light_times_visibility(&format!("forward {kind}"));
    }
}
