//! The default light and camera for any scene (`shadow_fins::default_view`):
//! rooms seen from inside under their ceiling, a subject found on a ground
//! that dwarfs it, an object seen from outside, and the same view at any
//! scale.

use proptest::prelude::*;
use shadow_fins::{
    default_view::{DefaultView, default_view_of},
    glam::{Affine3A, Vec3},
    light::{DiskLight, Light},
    mesh::Mesh,
    scene::{Scene, SceneObject},
    scenes::{SceneId, default_view},
    shapes,
};

use super::common::object;

fn placed(name: &str, mesh: Mesh, at: Vec3) -> SceneObject {
    SceneObject::new(name, mesh, Affine3A::from_translation(at)).unwrap()
}

/// The scene with every object's transform scaled by `s` about the origin.
fn scaled(scene: &Scene, s: f32) -> Scene {
    let objects = scene
        .objects
        .iter()
        .map(|o| {
            let t = Affine3A::from_scale(Vec3::splat(s)) * o.transform;
            let mut scaled = SceneObject::shared(o.name.clone(), o.mesh.clone(), o.topology.clone(), t).unwrap();
            (scaled.casts_shadows, scaled.receives_shadows) = (o.casts_shadows, o.receives_shadows);
            scaled
        })
        .collect();
    Scene::new(objects)
}

fn disk(view: &DefaultView) -> DiskLight {
    match view.light {
        Light::Disk(d) => d,
        other => panic!("the default light is a disk, got {other:?}"),
    }
}

fn strictly_inside(p: Vec3, lo: Vec3, hi: Vec3) -> bool {
    p.cmpgt(lo).all() && p.cmplt(hi).all()
}

/// Every value finite, lengths positive, the clip range non-empty.
fn assert_usable(view: &DefaultView, what: &str) {
    let d = disk(view);
    let c = view.camera;
    assert!(d.center.is_finite() && d.radius.is_finite() && d.radius > 0.0, "{what}: light {d:?}");
    assert!(c.position.is_finite() && c.target.is_finite() && c.position != c.target, "{what}: camera {c:?}");
    assert!(view.light_distance.is_finite() && view.light_distance > 0.0, "{what}: light distance {view:?}");
    assert!(
        view.near > 0.0 && view.far.is_finite() && view.near < view.far,
        "{what}: near {} far {}",
        view.near,
        view.far
    );
}

/// The light's centre lies inside none of the scene's closed objects.
fn light_outside_every_object(scene: &Scene, light: &Light) -> Result<(), String> {
    let Light::Disk(d) = light else { return Err(format!("not a disk: {light:?}")) };
    for o in &scene.objects {
        let local = o.transform.inverse().transform_point3(d.center);
        if o.topology.contains_point(local) {
            return Err(format!("the light at {} is inside {}", d.center, o.name));
        }
    }
    Ok(())
}

/// A wall quad `a b c d` seen counter-clockwise from the room's inside.
fn wall(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> Mesh {
    Mesh::new(vec![a, b, c, d], vec![0, 1, 2, 0, 2, 3]).unwrap()
}

/// A Cornell-box-like room of `size` (x, y, z), its floor at y = 0 centred on
/// the y axis: floor, ceiling, back (−z), left and right walls as single
/// quads facing in; open at +z.
fn cornell_walls(size: Vec3) -> Vec<SceneObject> {
    let (x, y, z) = (size.x * 0.5, size.y, size.z * 0.5);
    let p = |sx: f32, py: f32, sz: f32| Vec3::new(sx * x, py, sz * z);
    vec![
        object("floor", wall(p(-1.0, 0.0, -1.0), p(-1.0, 0.0, 1.0), p(1.0, 0.0, 1.0), p(1.0, 0.0, -1.0))),
        object("ceiling", wall(p(-1.0, y, -1.0), p(1.0, y, -1.0), p(1.0, y, 1.0), p(-1.0, y, 1.0))),
        object("back", wall(p(-1.0, 0.0, -1.0), p(1.0, 0.0, -1.0), p(1.0, y, -1.0), p(-1.0, y, -1.0))),
        object("left", wall(p(-1.0, 0.0, -1.0), p(-1.0, y, -1.0), p(-1.0, y, 1.0), p(-1.0, 0.0, 1.0))),
        object("right", wall(p(1.0, 0.0, -1.0), p(1.0, 0.0, 1.0), p(1.0, y, 1.0), p(1.0, y, -1.0))),
    ]
}

#[test]
fn the_cornell_box_walls_face_into_the_room() {
    let size = Vec3::new(0.556, 0.549, 0.559);
    let centre = Vec3::new(0.0, size.y * 0.5, 0.0);
    for w in cornell_walls(size) {
        for [a, b, c] in w.mesh.triangles() {
            assert!((b - a).cross(c - a).dot(centre - a) > 0.0, "{} faces out", w.name);
        }
    }
}

/// A room of six slab walls (closed boxes, overlapping at the corners) around
/// the inner space `[-size/2, size/2]` in x and z, `[0, size.y]` in y.
fn slab_room(size: Vec3, thickness: f32) -> Vec<SceneObject> {
    let (h, t) = (size * 0.5, thickness);
    let mid = Vec3::new(0.0, h.y, 0.0);
    let slab = |name: &str, half: Vec3, at: Vec3| placed(name, shapes::cuboid(half), mid + at);
    vec![
        slab("floor", Vec3::new(h.x + t, t * 0.5, h.z + t), Vec3::new(0.0, -h.y - t * 0.5, 0.0)),
        slab("ceiling", Vec3::new(h.x + t, t * 0.5, h.z + t), Vec3::new(0.0, h.y + t * 0.5, 0.0)),
        slab("left", Vec3::new(t * 0.5, h.y + t, h.z + t), Vec3::new(-h.x - t * 0.5, 0.0, 0.0)),
        slab("right", Vec3::new(t * 0.5, h.y + t, h.z + t), Vec3::new(h.x + t * 0.5, 0.0, 0.0)),
        slab("back", Vec3::new(h.x + t, h.y + t, t * 0.5), Vec3::new(0.0, 0.0, -h.z - t * 0.5)),
        slab("front", Vec3::new(h.x + t, h.y + t, t * 0.5), Vec3::new(0.0, 0.0, h.z + t * 0.5)),
    ]
}

/// Inside, light strictly inside the room under its ceiling and facing down,
/// camera strictly inside the room.
fn assert_seen_from_inside(view: &DefaultView, lo: Vec3, hi: Vec3, what: &str) {
    assert_usable(view, what);
    let d = disk(view);
    assert!(view.inside, "{what}: seen from outside: {view:?}");
    assert!(strictly_inside(d.center, lo, hi), "{what}: light {} outside the room {lo}..{hi}", d.center);
    assert!(d.center.y < hi.y && d.center.y > lo.y, "{what}: light not between floor and ceiling");
    assert!(d.normal.dot(Vec3::NEG_Y) > 0.999, "{what}: light faces {}", d.normal);
    assert!(strictly_inside(view.camera.position, lo, hi), "{what}: camera {} outside the room", view.camera.position);
    // It shines on the floor (or what stands on it), not through a wall.
    assert!(view.light_distance <= d.center.y - lo.y + 1e-3 * (hi - lo).length(), "{what}: {view:?}");
}

#[test]
fn a_closed_room_of_slab_walls_is_seen_from_inside_under_its_ceiling() {
    let size = Vec3::new(4.0, 2.6, 3.2);
    let mut objects = slab_room(size, 0.05);
    objects.push(placed("chest", shapes::cuboid(Vec3::splat(0.4)), Vec3::new(0.8, 0.4, -0.5)));
    let scene = Scene::new(objects);
    let view = default_view_of(&scene).unwrap();
    let (lo, hi) = (Vec3::new(-2.0, 0.0, -1.6), Vec3::new(2.0, 2.6, 1.6));
    assert_seen_from_inside(&view, lo, hi, "slab room");
    light_outside_every_object(&scene, &view.light).unwrap();
    // 90% of the way from the room's centre up to the ceiling's underside.
    assert!((disk(&view).center.y - (1.3 + 0.9 * 1.3)).abs() < 0.01, "{view:?}");
    assert!(strictly_inside(view.camera.target, lo - Vec3::splat(1e-3), hi + Vec3::splat(1e-3)));
    assert!((view.camera.vertical_fov - 70.0).abs() < 1e-6);
}

#[test]
fn a_room_of_one_inward_facing_box_is_seen_from_inside() {
    let room = shapes::cuboid(Vec3::new(2.5, 1.5, 2.0));
    let flipped: Vec<u32> = room.indices().chunks(3).flat_map(|t| [t[0], t[2], t[1]]).collect();
    let room = Mesh::new(room.positions().to_vec(), flipped).unwrap();
    let scene = Scene::new(vec![
        placed("room", room, Vec3::new(10.0, 1.5, -4.0)),
        placed("ball", shapes::uv_sphere(0.5, 12, 24), Vec3::new(10.5, 0.5, -4.2)),
    ]);
    let view = default_view_of(&scene).unwrap();
    assert_seen_from_inside(&view, Vec3::new(7.5, 0.0, -6.0), Vec3::new(12.5, 3.0, -2.0), "inverted box");
    // Parity counts the room's inside as inside its mesh, whatever the winding: the ball only.
    light_outside_every_object(&Scene::new(vec![scene.objects[1].clone()]), &view.light).unwrap();
}

#[test]
fn a_cornell_box_in_millimetres_is_seen_through_its_open_side_with_the_light_below_its_ceiling() {
    // The Cornell box's 556 × 549 × 559 mm, and an exact cube of 0.55 m: modelled
    // edges and corners lie on the axis and diagonal probes of a cube.
    for size in [Vec3::new(0.556, 0.549, 0.559), Vec3::splat(0.55)] {
        let mut objects = cornell_walls(size);
        objects.push(placed("short-block", shapes::cuboid(Vec3::new(0.08, 0.08, 0.08)), Vec3::new(0.1, 0.08, 0.05)));
        objects.push(placed("tall-block", shapes::cuboid(Vec3::new(0.08, 0.16, 0.08)), Vec3::new(-0.1, 0.16, -0.1)));
        let scene = scaled(&Scene::new(objects), 1e-3);
        let view = default_view_of(&scene).unwrap();
        let (lo, hi) =
            (Vec3::new(-size.x * 0.5, 0.0, -size.z * 0.5) * 1e-3, Vec3::new(size.x * 0.5, size.y, size.z * 0.5) * 1e-3);
        let what = format!("Cornell box {size} mm");
        assert_seen_from_inside(&view, lo, hi, &what);
        light_outside_every_object(&scene, &view.light).unwrap();
        // From between the centre and the open side (+z), looking straight in
        // at the back wall.
        let (p, t) = (view.camera.position, view.camera.target);
        assert!(p.z > 0.0, "{what}: camera {p}");
        let forward = (t - p).normalize();
        assert!(forward.dot(Vec3::NEG_Z) > 0.999, "{what}: looks along {forward}");
        assert!((t.z - lo.z).abs() < 1e-3 * size.z * 1e-3, "{what}: target {t} not on the back wall");
        let farthest_corner = (0..8)
            .map(|i| {
                Vec3::select(shadow_fins::glam::BVec3::new(i & 1 == 0, i & 2 == 0, i & 4 == 0), lo, hi).distance(p)
            })
            .fold(0.0, f32::max);
        assert!(view.near < 0.01 * size.z * 1e-3 && view.far > farthest_corner, "{what}: {view:?}");
    }
}

#[test]
fn on_an_island_the_subject_is_the_tree_not_the_ground() {
    let tree_at = Vec3::new(20.0, 0.0, 15.0);
    let scene = Scene::new(vec![
        object("island", shapes::plane(100.0, 8)),
        placed("trunk", shapes::cuboid(Vec3::new(0.15, 1.5, 0.15)), tree_at + Vec3::new(0.0, 1.5, 0.0)),
        placed("crown", shapes::uv_sphere(1.0, 12, 24), tree_at + Vec3::new(0.0, 3.5, 0.0)),
    ]);
    let (lo, hi) = (tree_at + Vec3::new(-1.0, 0.0, -1.0), tree_at + Vec3::new(1.0, 4.5, 1.0));
    let view = default_view_of(&scene).unwrap();
    assert_usable(&view, "island");
    assert!(!view.inside);
    let d = disk(&view);
    assert!(strictly_inside(view.camera.target, lo, hi), "target {} not in the tree", view.camera.target);
    assert!(d.center.y > hi.y, "light {} not above the tree", d.center);
    assert!(d.center.x > lo.x && d.center.x < hi.x && d.center.z > lo.z && d.center.z < hi.z, "light {}", d.center);
    // Framed on the tree (one tree diagonal is ~5.3): not from 1.2 island diagonals.
    let tree_diagonal = (hi - lo).length();
    assert!(view.camera.position.distance(view.camera.target) < 2.0 * tree_diagonal, "{view:?}");
    assert!((d.radius - 0.05 * tree_diagonal).abs() < 1e-3 * tree_diagonal);
    light_outside_every_object(&scene, &view.light).unwrap();
}

#[test]
fn an_overhang_above_the_subject_brings_the_light_under_it() {
    // A ball under a roof: a light above the roof would leave it in shadow.
    let scene = Scene::new(vec![
        placed("ball", shapes::uv_sphere(0.5, 12, 24), Vec3::new(0.0, 0.5, 0.0)),
        placed("roof", shapes::cuboid(Vec3::new(1.5, 0.05, 1.5)), Vec3::new(0.0, 3.0, 0.0)),
    ]);
    let view = default_view_of(&scene).unwrap();
    assert_usable(&view, "roof");
    assert!(!view.inside);
    let y = disk(&view).center.y;
    assert!(y > 1.0 && y < 2.95, "light at {y}: not between the ball and the roof");
    // The ball's top is what it lights first.
    assert!((view.light_distance - (y - 1.0)).abs() < 0.01, "{view:?}");
    light_outside_every_object(&scene, &view.light).unwrap();
}

#[test]
fn a_part_of_the_subject_above_its_centre_is_no_overhang() {
    // The figure's chin is above its hips' centre, the tilted receiver's box
    // above the ramp's: their shadows are the point, so the light stays above.
    for id in [SceneId::Figure, SceneId::TiltedReceiver] {
        let s = id.build();
        let view = default_view_of(&s.scene).unwrap();
        let top = s.scene.bounds().unwrap().1.y;
        assert!(disk(&view).center.y > top, "{}: light {} below the top {top}", id.name(), disk(&view).center);
    }
}

#[test]
fn an_object_on_the_ground_is_seen_from_outside_with_the_light_above_it() {
    let s = SceneId::BoxOverPlane.build();
    let view = default_view_of(&s.scene).unwrap();
    assert_usable(&view, "box-over-plane");
    assert!(!view.inside);
    // The subject is the box, 1 wide at y 1..2; the 10-wide ground is not.
    let (lo, hi) = (Vec3::new(-0.5, 1.0, -0.5), Vec3::new(0.5, 2.0, 0.5));
    let d = disk(&view);
    let diagonal = 3f32.sqrt();
    assert!((d.center - Vec3::new(0.0, 1.5 + diagonal, 0.0)).length() < 1e-4, "light at {}", d.center);
    assert!((d.radius - 0.05 * diagonal).abs() < 1e-5 && d.normal.dot(Vec3::NEG_Y) > 0.999);
    // It first meets the box's top.
    assert!((view.light_distance - (d.center.y - 2.0)).abs() < 1e-3, "{view:?}");
    let p = view.camera.position;
    assert!(!(p.cmpge(lo).all() && p.cmple(hi).all()), "camera {p} in the box");
    assert!((p.distance(view.camera.target) - 1.2 * diagonal).abs() < 1e-4);
    assert!((view.camera.target - Vec3::new(0.0, 1.5, 0.0)).length() < 1e-5);
    assert_eq!(view.camera.vertical_fov, 45.0);
    light_outside_every_object(&s.scene, &view.light).unwrap();
}

#[test]
fn every_built_in_scene_gets_a_view_with_the_light_outside_every_object() {
    for id in SceneId::ALL {
        let s = id.build();
        let view = default_view_of(&s.scene).unwrap_or_else(|| panic!("{}: no view", id.name()));
        let d = disk(&view);
        println!(
            "{}: light {} r {:.3} at {:.3}, camera {} → {}, clip {:.4}..{:.2}",
            id.name(),
            d.center,
            d.radius,
            view.light_distance,
            view.camera.position,
            view.camera.target,
            view.near,
            view.far
        );
        assert_usable(&view, id.name());
        assert!(!view.inside, "{}: an object scene seen from inside", id.name());
        light_outside_every_object(&s.scene, &view.light).unwrap_or_else(|e| panic!("{}: {e}", id.name()));
    }
}

#[test]
fn an_empty_scene_has_no_view() {
    assert!(default_view_of(&Scene::default()).is_none());
    assert!(default_view(&Scene::default()).is_none());
}

/// `a` is `b` scaled by `s`: positions within `tol` of `size`, lengths within `tol` of themselves.
fn assert_scaled(a: &DefaultView, b: &DefaultView, s: f32, size: f32, tol: f32, what: &str) -> Result<(), String> {
    let (da, db) = (disk(a), disk(b));
    let close = |x: Vec3, y: Vec3| (x / s - y).length() <= tol * size;
    let near = |x: f32, y: f32| (x / s - y).abs() <= tol * y.abs();
    let checks = [
        ("light centre", close(da.center, db.center)),
        ("light radius", near(da.radius, db.radius)),
        ("light distance", near(a.light_distance, b.light_distance)),
        ("near", near(a.near, b.near)),
        ("far", near(a.far, b.far)),
        ("camera position", close(a.camera.position, b.camera.position)),
        ("camera target", close(a.camera.target, b.camera.target)),
        ("inside", a.inside == b.inside),
        ("field of view", a.camera.vertical_fov == b.camera.vertical_fov),
    ];
    match checks.iter().find(|c| !c.1) {
        Some((name, _)) => Err(format!("{what} × {s}: the {name} does not scale:\n{a:?}\nvs\n{b:?}")),
        None => Ok(()),
    }
}

#[test]
fn scaling_the_scene_from_millimetres_to_kilometres_scales_the_view() {
    let rooms = {
        let mut objects = slab_room(Vec3::new(4.0, 2.6, 3.2), 0.05);
        objects.push(placed("chest", shapes::cuboid(Vec3::splat(0.4)), Vec3::new(0.8, 0.4, -0.5)));
        Scene::new(objects)
    };
    let cornell = Scene::new(cornell_walls(Vec3::new(0.556, 0.549, 0.559)));
    for (what, scene) in [("kitbash", SceneId::Kitbash.build().scene), ("slab room", rooms), ("cornell box", cornell)] {
        let one = default_view_of(&scene).unwrap();
        let (lo, hi) = scene.bounds().unwrap();
        for s in [1e-3f32, 1e3] {
            let view = default_view_of(&scaled(&scene, s)).unwrap();
            assert_usable(&view, what);
            assert_scaled(&view, &one, s, (hi - lo).length(), 1e-4, what).unwrap();
        }
    }
}

/// A few boxes and balls anywhere, and maybe a ground under them.
fn box_soup() -> impl Strategy<Value = Scene> {
    let part = (any::<bool>(), prop::array::uniform3(-5.0f32..5.0), prop::array::uniform3(0.01f32..3.0));
    (prop::collection::vec(part, 1..7), any::<bool>()).prop_map(|(parts, with_ground)| {
        let mut objects: Vec<SceneObject> = parts
            .into_iter()
            .enumerate()
            .map(|(i, (ball, at, half))| {
                let mesh = if ball { shapes::uv_sphere(half[0], 8, 12) } else { shapes::cuboid(Vec3::from(half)) };
                placed(&format!("part-{i}"), mesh, Vec3::from(at))
            })
            .collect();
        if with_ground {
            objects.push(placed("ground", shapes::plane(80.0, 2), Vec3::new(0.0, -6.0, 0.0)));
        }
        Scene::new(objects)
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// A power of two scales every float exactly, so the view must scale
    /// exactly too, whatever the probes meet.
    #[test]
    fn any_box_soup_gets_a_finite_view_that_scales_with_it(scene in box_soup(), k in -10i32..=10) {
        let one = default_view_of(&scene).unwrap();
        assert_usable(&one, "soup");
        light_outside_every_object(&scene, &one.light).map_err(TestCaseError::fail)?;
        let s = 2f32.powi(k);
        let view = default_view_of(&scaled(&scene, s)).unwrap();
        let (lo, hi) = scene.bounds().unwrap();
        assert_scaled(&view, &one, s, (hi - lo).length(), 1e-5, "soup").map_err(TestCaseError::fail)?;
    }
}

#[test]
fn a_subject_alone_gets_a_ground_under_it_and_a_scene_with_one_does_not() {
    // A helmet-like ball and a character-like column, exported on their own,
    // at a millimetre, a metre and a kilometre.
    for scale in [1e-3f32, 1.0, 1e3] {
        let alone = scaled(
            &Scene::new(vec![
                placed("ball", shapes::uv_sphere(0.5, 12, 24), Vec3::new(3.0, 1.5, -2.0)),
                placed("column", shapes::cuboid(Vec3::new(0.2, 1.0, 0.2)), Vec3::new(3.6, 1.0, -2.0)),
            ]),
            scale,
        );
        let view = default_view_of(&alone).unwrap();
        let ground = view.missing_ground.unwrap_or_else(|| panic!("no ground proposed at scale {scale}"));
        let subject_diagonal = Vec3::new(1.3, 2.0, 1.0).length() * scale;
        // Just under the column's foot, centred under the subject, a few subject diagonals wide.
        assert!(ground.center.y < 0.0 && ground.center.y > -0.01 * subject_diagonal, "{ground:?}");
        assert!((ground.center.x - 3.15 * scale).abs() < 0.01 * subject_diagonal, "{ground:?}");
        assert!((ground.center.z + 2.0 * scale).abs() < 0.01 * subject_diagonal, "{ground:?}");
        assert!((ground.half_size / subject_diagonal - shadow_fins::default_view::GROUND_HALF_SIZE).abs() < 0.01);
        // The default light shines down onto it: the ground is under the light.
        let d = disk(&view);
        assert!((d.center.x - ground.center.x).abs() < ground.half_size && d.center.y > ground.center.y);
    }
    // A figure of two boxes, its body's flat underside on nothing: that base is no ground.
    let figure = Scene::new(vec![
        placed("body", shapes::cuboid(Vec3::new(0.25, 0.8, 0.15)), Vec3::new(0.0, 0.8, 0.0)),
        placed("head", shapes::cuboid(Vec3::splat(0.2)), Vec3::new(0.0, 1.85, 0.0)),
    ]);
    assert!(default_view_of(&figure).unwrap().missing_ground.is_some());
    // The same subject on a ground (an island, a floor of its own size) has one.
    let mut on_ground = vec![
        placed("ball", shapes::uv_sphere(0.5, 12, 24), Vec3::new(3.0, 1.5, -2.0)),
        placed("column", shapes::cuboid(Vec3::new(0.2, 1.0, 0.2)), Vec3::new(3.6, 1.0, -2.0)),
    ];
    on_ground.push(placed("floor", shapes::plane(4.0, 2), Vec3::new(3.0, 0.0, -2.0)));
    assert_eq!(default_view_of(&Scene::new(on_ground.clone())).unwrap().missing_ground, None);
    on_ground.pop();
    on_ground.push(object("island", shapes::plane(100.0, 8)));
    assert_eq!(default_view_of(&Scene::new(on_ground)).unwrap().missing_ground, None);
    // A room seen from inside has its floor.
    assert_eq!(default_view_of(&Scene::new(slab_room(Vec3::new(4.0, 2.6, 3.2), 0.05))).unwrap().missing_ground, None);
}

#[test]
fn the_built_in_scenes_all_have_their_ground() {
    for id in SceneId::ALL {
        let built = id.build();
        if let Some(view) = default_view_of(&built.scene) {
            assert_eq!(view.missing_ground, None, "{id:?}");
        }
    }
}

#[test]
fn the_repositorys_gltf_scenes_all_have_their_ground() {
    // The directory at run time: a binary built in another clone must not read that clone's path.
    let manifest = std::env::var("CARGO_MANIFEST_DIR").unwrap_or_else(|_| env!("CARGO_MANIFEST_DIR").into());
    for entry in std::fs::read_dir(std::path::Path::new(&manifest).join("../../assets")).unwrap() {
        let path = entry.unwrap().path();
        let import = shadow_fins::gltf_import::load_gltf(&path).unwrap();
        let view = default_view_of(&import.scene).unwrap();
        assert_eq!(view.missing_ground, None, "{}", path.display());
    }
}
