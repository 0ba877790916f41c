//! A light and a camera that make any scene (an imported glTF) readable.
//!
//! [`default_view_of`] reads the scene's geometry, not only its bounds: it
//! finds the *subject* (what is worth looking at, without a ground that
//! dwarfs it), tells a room meant to be seen from inside from an object seen
//! from outside, and places a disk light and a camera to suit. Every length
//! it picks is a fraction of the scene's own sizes, so a helmet of one unit
//! and a fox of a hundred, or a room in millimetres and in kilometres, get the
//! same view, scaled.
//!
//! The probes are rays that list every crossing along their whole length.
//! Closed meshes are *solids*: crossing one of their faces enters or leaves
//! them, by the face's winding. Open meshes are *surfaces*: they stop a ray
//! but have no inside. *Free space* along a ray is where no solid contains it,
//! and a probe asks for the first stretch of free space at least
//! [`MIN_SPAN`] of the subject's diagonal long. Why: a subject's centre often
//! lies inside one of its own parts (a box, a torso, a trunk), whose faces
//! seen from inside would otherwise pass for the walls of a room or for an
//! overhang, and a crack between two touching parts is no place for a light.

use std::f32::consts::TAU;

use glam::{Quat, Vec3};

use crate::{
    bvh::{self, Bvh},
    camera::Camera,
    light::{DiskLight, Light},
    scene::Scene,
};

/// A light and a camera chosen for a scene by [`default_view_of`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DefaultView {
    /// A [`Light::Disk`] facing into the scene (down).
    pub light: Light,
    /// The core camera (position, target, up, vertical field of view in degrees).
    pub camera: Camera,
    /// Distance from the light's centre to the first surface along its normal
    /// (or to the subject's centre if nothing is hit): the caller sizes the
    /// light's power by it (illuminance ∝ power / distance²).
    pub light_distance: f32,
    /// Near clip distance that keeps the scene in front of the camera.
    pub near: f32,
    /// Far clip distance beyond the scene's farthest corner from the camera.
    pub far: f32,
    /// True when the camera was placed inside an enclosure (a room).
    pub inside: bool,
    /// Where a shadow catcher would go because nothing lies under the
    /// subject to catch its shadow (a helmet or a character exported on its
    /// own); `None` when the scene has a ground, and inside a room.
    pub missing_ground: Option<Ground>,
}

/// A horizontal square, facing up: a ground to catch a subject's shadow
/// ([`DefaultView::missing_ground`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ground {
    pub center: Vec3,
    pub half_size: f32,
}

/// An object is flat when its thinnest world extent is below this fraction of
/// its largest: a ground, a floor, a backdrop.
pub const GROUND_FLATNESS: f32 = 0.02;
/// A flat object is a ground when its largest extent is over this many times
/// the largest extent of everything else: an island under a palm tree.
pub const GROUND_DOMINANCE: f32 = 3.0;
/// Of the 26 probe directions from the subject's centre, how many must meet a
/// surface for the centre to be inside a room.
pub const ENCLOSED_DIRECTIONS: usize = 18;
/// Of the 3 × 3 columns across the subject, how many must meet a surface above
/// for the light to go under it: a roof over the subject shadows all of it,
/// but a part above the centre (a chin over the hips, a box over a ramp) is
/// the subject itself, whose shadow is the point of the view.
pub const OVERHANG_COLUMNS: usize = 7;
/// The shortest stretch of free space a probe accepts, as a fraction of the
/// subject's diagonal: shorter gaps are cracks between parts.
pub const MIN_SPAN: f32 = 0.05;
/// The disk's radius as a fraction of the subject's diagonal (outside) or of
/// the room's smaller horizontal extent (inside).
pub const LIGHT_RADIUS: f32 = 0.05;
/// The outside camera's distance from the subject's centre, in subject diagonals.
pub const CAMERA_DISTANCE: f32 = 1.2;
/// The outside camera's direction from the subject's centre (normalised):
/// above, to the right and in front, a three-quarter view.
pub const CAMERA_DIRECTION: Vec3 = Vec3::new(0.6, 0.7, 0.9);
/// The inside camera's vertical field of view in degrees: wide, as rooms are
/// seen from within a few steps of a wall.
pub const INSIDE_FOV_DEG: f32 = 70.0;

/// The ground probes stand this many subject diagonals outside the subject's
/// box (so they miss the subject) ...
pub const GROUND_PROBE_MARGIN: f32 = 0.25;
/// ... and of their 8 (the widened box's corners and edge middles), this many
/// must meet a surface below for the scene to have a ground.
pub const GROUND_PROBES_HIT: usize = 5;
/// Of the 5 × 5 columns down across the subject's box, how many must end at
/// its base for the base to be its ground.
pub const GROUND_BASE_COLUMNS: usize = 15;
/// A surface faces up within 60° of straight up (a tilted floor).
pub const GROUND_SLOPE_COS: f32 = 0.5;
/// A missing ground's half size in subject diagonals: it holds the shadow of
/// the default light and fills the default camera's view below the horizon.
pub const GROUND_HALF_SIZE: f32 = 5.0;
/// A missing ground lies this many subject diagonals below the subject's
/// lowest point: under a base that is itself flat, not in its plane.
pub const GROUND_GAP: f32 = 1e-3;

/// How many horizontal directions the inside camera chooses among.
const HORIZONTAL_DIRECTIONS: usize = 32;

/// A world-space axis-aligned box `(min, max)`.
type Aabb = (Vec3, Vec3);

/// A light and a camera that show `scene`, with the power distance and the
/// clip planes to use them with. `None` for an empty scene, one with no
/// finite position, or one too large for its view to fit in `f32`.
///
/// The rules, each a fraction of the scene's own sizes (so the view scales
/// with the scene):
///
/// - **Subject.** An object whose world box is flat ([`GROUND_FLATNESS`]) and
///   large ([`GROUND_DOMINANCE`] × the rest of the scene) is ground: a first
///   view of a plane with no tree on it shows nothing. The subject is the box
///   of the other objects (of all objects when none remains).
/// - **Enclosure.** From the subject's centre, 26 directions (the cube's
///   faces, edges and corners, tilted by a fixed 1° so that they miss the
///   modelled edges and corners of box rooms) probe for a surface beyond the
///   first free stretch; [`ENCLOSED_DIRECTIONS`] or more means a room, which
///   is meant to be seen from inside. (A bare "any hit" would call every
///   closed object a room: its own faces surround its centre.)
/// - **Inside.** The light goes 90% of the way up to the ceiling (the first
///   surface above the centre; the box's top when there is none), facing
///   down, radius [`LIGHT_RADIUS`] of the room's smaller horizontal extent:
///   a light above the ceiling leaves the whole room in its shadow. The
///   camera goes 70% of the way from the centre towards the room's open side
///   (the middle of the widest run of horizontal directions that meet
///   nothing; the box's side stands in for the wall there) or, in a closed
///   room, towards the farthest wall, never past it, and looks at the
///   surface on the opposite side at the centre's height, with a
///   [`INSIDE_FOV_DEG`]° field of view.
/// - **Outside.** The light one subject diagonal above the subject's centre,
///   facing down, radius [`LIGHT_RADIUS`] of the subject's diagonal — unless a
///   surface above the centre (an overhang) is nearer and covers the subject
///   ([`OVERHANG_COLUMNS`]): then 90% of the way up to it, so that the subject
///   is not all in its shadow. The camera
///   [`CAMERA_DISTANCE`] subject diagonals along [`CAMERA_DIRECTION`] from the
///   centre, looking at it, with [`Camera::looking_at`]'s field of view (45°).
/// - **Light distance.** The first surface below the light's centre, else the
///   subject's centre: what the light's power must reach.
/// - **Clip planes.** `near` is half the camera's distance to the scene's box
///   (no nearer than 1e-6 of the scene's diagonal), or 1e-3 of the diagonal
///   when the camera is in the box or in a room; `far` is 1.5 × the distance
///   to the box's farthest corner. Both are finite and `near < far`.
pub fn default_view_of(scene: &Scene) -> Option<DefaultView> {
    let geometry = Geometry::of(scene);
    let scene_box = geometry.boxes.iter().flatten().copied().reduce(union)?;
    let subject_box = subject_of(&geometry.boxes).unwrap_or(scene_box);
    let diagonal = (scene_box.1 - scene_box.0).length();
    if !diagonal.is_finite() {
        return None;
    }
    // Only a scene whose every vertex rounds to one point has no size; give it one.
    let diagonal = if diagonal > 0.0 { diagonal } else { (scene_box.0.abs().max_element() * 1e-6).max(1e-30) };
    let center = (subject_box.0 + subject_box.1) * 0.5;
    let subject_diagonal = (subject_box.1 - subject_box.0).length().max(diagonal * 1e-6);
    let probe = Probe {
        bvh: Bvh::new(&geometry.triangles),
        geometry: &geometry,
        // Off the surface a probe starts on, at the precision of the coordinates.
        t_min: 1e-6 * diagonal.max(center.abs().max_element()),
        min_span: MIN_SPAN * subject_diagonal,
    };

    // Off every modelled axis and diagonal (the axis `Topology::contains_point` casts along).
    let tilt = Quat::from_axis_angle(Vec3::new(0.3112, 0.8597, 0.4049).normalize(), 1f32.to_radians());
    let inside =
        cube_directions().filter(|&d| probe.open_span(center, tilt * d).1.is_some()).count() >= ENCLOSED_DIRECTIONS;

    // The light straight above the centre, at a height found along the tilted "up".
    let up = tilt * Vec3::Y;
    let (start, end) = probe.open_span(center, up);
    let below_end = end.map(|end| start + 0.9 * (end - start));
    let t_light = if inside {
        below_end.unwrap_or_else(|| {
            let top = box_exit(center, up, subject_box).max(start + probe.min_span);
            start + 0.9 * (top - start)
        })
    } else {
        let above = (subject_diagonal / up.y).max(start + probe.min_span);
        overhang(&probe, center, up, subject_box, (start, end)).map_or(above, |b| b.min(above))
    };
    let light_center = center + Vec3::Y * (t_light * up.y);
    let radius = if inside {
        let room = subject_box.1 - subject_box.0;
        (LIGHT_RADIUS * room.x.min(room.z)).max(1e-4 * subject_diagonal)
    } else {
        LIGHT_RADIUS * subject_diagonal
    };
    let light = DiskLight::new(light_center, Vec3::NEG_Y, radius).ok()?;
    let light_distance =
        probe.closest(light_center, tilt * Vec3::NEG_Y).unwrap_or_else(|| (light_center - center).length());

    let camera = if inside {
        inside_camera(&probe, center, subject_box)
    } else {
        Camera::looking_at(center + CAMERA_DIRECTION.normalize() * (CAMERA_DISTANCE * subject_diagonal), center)
    };

    let to_box = (scene_box.0 - camera.position).max(camera.position - scene_box.1).max(Vec3::ZERO).length();
    let near = if inside || !(to_box > 0.0) { 1e-3 * diagonal } else { (0.5 * to_box).max(1e-6 * diagonal) };
    let farthest = (0..8)
        .map(|i| {
            let pick = |bit: usize, k: usize| if i & bit == 0 { scene_box.0[k] } else { scene_box.1[k] };
            (Vec3::new(pick(1, 0), pick(2, 1), pick(4, 2)) - camera.position).length()
        })
        .fold(0.0, f32::max);
    let far = (1.5 * farthest).max(2.0 * near);

    let missing_ground = if inside { None } else { missing_ground(&probe, subject_box, subject_diagonal, tilt) };
    let view = DefaultView { light: Light::Disk(light), camera, light_distance, near, far, inside, missing_ground };
    view.is_usable().then_some(view)
}

impl DefaultView {
    /// Every value finite, the distances positive and the clip range non-empty.
    fn is_usable(&self) -> bool {
        let Light::Disk(d) = self.light else { return false };
        let c = &self.camera;
        d.center.is_finite()
            && d.radius.is_finite()
            && c.position.is_finite()
            && c.target.is_finite()
            && c.position != c.target
            && self.light_distance.is_finite()
            && self.light_distance > 0.0
            && self.near > 0.0
            && self.far.is_finite()
            && self.near < self.far
    }
}

/// A ground under the subject when the scene has none. It has one when rays
/// cast down from 8 points around the subject ([`GROUND_PROBE_MARGIN`]
/// outside its box, a [`MIN_SPAN`] above its lowest point, so that a ground
/// it stands on is met) meet something below, [`GROUND_PROBES_HIT`] of them
/// at least — or when the subject's own base is its ground: of the 5 × 5
/// columns down across its box, [`GROUND_BASE_COLUMNS`] end on a surface
/// facing up ([`GROUND_SLOPE_COS`]: a floor, tilted or not), or cross one
/// within [`MIN_SPAN`] of its lowest point (a plate's top, over its own
/// underside). A helmet's or a character's columns end on their
/// undersides, with their last surface facing up high above the base (a
/// body's top), or miss. Else a
/// square of [`GROUND_HALF_SIZE`] subject diagonals, centred under the
/// subject, [`GROUND_GAP`] below its lowest point.
fn missing_ground(probe: &Probe, subject: Aabb, subject_diagonal: f32, tilt: Quat) -> Option<Ground> {
    let margin = Vec3::new(1.0, 0.0, 1.0) * (GROUND_PROBE_MARGIN * subject_diagonal);
    let (lo, hi) = (subject.0 - margin, subject.1 + margin);
    let (mid, half) = ((subject.0 + subject.1) * 0.5, (subject.1 - subject.0) * 0.5);
    let reach = MIN_SPAN * subject_diagonal;
    let down = tilt * Vec3::NEG_Y;
    let around = [
        (lo.x, lo.z),
        (mid.x, lo.z),
        (hi.x, lo.z),
        (hi.x, mid.z),
        (hi.x, hi.z),
        (mid.x, hi.z),
        (lo.x, hi.z),
        (lo.x, mid.z),
    ];
    let around_hits = around
        .into_iter()
        .filter(|&(x, z)| probe.closest(Vec3::new(x, subject.0.y + reach, z), down).is_some())
        .count();
    let top = subject.1.y + reach;
    let base_columns = (0..5)
        .flat_map(|i| (0..5).map(move |j| (i as f32 / 2.0 - 1.0, j as f32 / 2.0 - 1.0)))
        .filter(|&(i, j)| {
            let origin = Vec3::new(mid.x + 0.9 * i * half.x, top, mid.z + 0.9 * j * half.z);
            // Ends on a surface facing up (a floor, tilted or not), or has
            // one at the base (a slab's top, over its own underside).
            probe.column(origin, down).is_some_and(|(last_faces_up, last_up)| {
                last_faces_up || last_up.is_some_and(|t| origin.y + t * down.y <= subject.0.y + reach)
            })
        })
        .count();
    let center = Vec3::new(mid.x, subject.0.y - GROUND_GAP * subject_diagonal, mid.z);
    let ground = Ground { center, half_size: GROUND_HALF_SIZE * subject_diagonal };
    let has_ground = around_hits >= GROUND_PROBES_HIT || base_columns >= GROUND_BASE_COLUMNS;
    (!has_ground && center.is_finite() && ground.half_size.is_finite()).then_some(ground)
}

/// How far along `up` from `center` the light goes under an overhang: 90% of
/// the way to the surface above the centre (or, through a hole in it, to the
/// lowest one above the other columns); `None` when fewer than
/// [`OVERHANG_COLUMNS`] of the 3 × 3 columns across the subject (at ⅔ of its
/// half extents, the centre's height) meet a surface above. `centre_span` is
/// the centre column's [`Probe::open_span`].
fn overhang(probe: &Probe, center: Vec3, up: Vec3, subject: Aabb, centre_span: (f32, Option<f32>)) -> Option<f32> {
    let half = (subject.1 - subject.0) * (1.0 / 3.0);
    let below = |(start, end): (f32, Option<f32>)| end.map(|end| start + 0.9 * (end - start));
    let mut covered = 0;
    let mut lowest = f32::INFINITY;
    for (i, j) in (-1..=1).flat_map(|i| (-1..=1).map(move |j| (i as f32, j as f32))) {
        let span = if (i, j) == (0.0, 0.0) {
            centre_span
        } else {
            probe.open_span(center + Vec3::new(i * half.x, 0.0, j * half.z), up)
        };
        if let Some(t) = below(span) {
            covered += 1;
            lowest = lowest.min(t);
        }
    }
    // The centre column is free from its start up: the light never goes below that.
    (covered >= OVERHANG_COLUMNS).then(|| below(centre_span).unwrap_or(lowest.max(centre_span.0 + probe.min_span)))
}

/// The inside camera: towards the room's open side, or its farthest wall.
fn inside_camera(probe: &Probe, center: Vec3, room: Aabb) -> Camera {
    // Half a step off the axes, so no direction runs into a square room's corner
    // and an opening is sampled symmetrically about its middle.
    let dirs: Vec<Vec3> = (0..HORIZONTAL_DIRECTIONS)
        .map(|i| {
            let a = (i as f32 + 0.5) * TAU / HORIZONTAL_DIRECTIONS as f32;
            Vec3::new(a.sin(), 0.0, a.cos())
        })
        .collect();
    let reach = |d: Vec3| {
        let (start, end) = probe.open_span(center, d);
        (start, end.unwrap_or_else(|| box_exit(center, d, room).max(start + probe.min_span)), end.is_none())
    };
    let reaches: Vec<(f32, f32, bool)> = dirs.iter().map(|&d| reach(d)).collect();
    let open: Vec<bool> = reaches.iter().map(|r| r.2).collect();
    let dir = widest_open_run(&open)
        .map(|run| run.map(|i| dirs[i % dirs.len()]).sum::<Vec3>().normalize_or_zero())
        .filter(|d| *d != Vec3::ZERO)
        .unwrap_or_else(|| {
            // The farthest wall; near-ties (a symmetric room) go to the first,
            // whatever the rounding at this scale.
            let farthest = reaches.iter().map(|r| r.1).fold(0.0, f32::max);
            dirs[reaches.iter().position(|r| r.1 >= farthest * (1.0 - 1e-3)).unwrap_or(0)]
        });
    let (start, end, _) = reach(dir);
    let position = center + dir * (start + 0.7 * (end - start));
    let target = center - dir * reach(-dir).1;
    Camera { position, target, up: Vec3::Y, vertical_fov: INSIDE_FOV_DEG }
}

/// The longest circular run of `true` in `open`, as indices (which may run
/// past the end: take them modulo the length); `None` when none or all are open.
fn widest_open_run(open: &[bool]) -> Option<std::ops::Range<usize>> {
    let n = open.len();
    if open.iter().all(|&o| o) || !open.iter().any(|&o| o) {
        return None;
    }
    let mut best = 0..0;
    for first in (0..n).filter(|&i| open[i] && !open[(i + n - 1) % n]) {
        let len = (0..n).take_while(|&k| open[(first + k) % n]).count();
        if len > best.len() {
            best = first..first + len;
        }
    }
    Some(best)
}

/// The 26 directions to a cube's faces, edges and corners from its centre, normalised.
fn cube_directions() -> impl Iterator<Item = Vec3> {
    (0..27)
        .filter(|&i| i != 13)
        .map(|i| Vec3::new((i % 3) as f32 - 1.0, ((i / 3) % 3) as f32 - 1.0, (i / 9) as f32 - 1.0).normalize())
}

/// Where the ray from `p` (inside `b`) along `d` leaves the box `b`.
fn box_exit(p: Vec3, d: Vec3, b: Aabb) -> f32 {
    let mut t = f32::INFINITY;
    for k in 0..3 {
        if d[k] > 0.0 {
            t = t.min((b.1[k] - p[k]) / d[k]);
        } else if d[k] < 0.0 {
            t = t.min((b.0[k] - p[k]) / d[k]);
        }
    }
    if t.is_finite() { t.max(0.0) } else { 0.0 }
}

fn union(a: Aabb, b: Aabb) -> Aabb {
    (a.0.min(b.0), a.1.max(b.1))
}

fn join(a: Option<Aabb>, b: Option<Aabb>) -> Option<Aabb> {
    match (a, b) {
        (Some(a), Some(b)) => Some(union(a, b)),
        (a, b) => a.or(b),
    }
}

/// The box of every object that is not ground (`None` when all are, or none has a box).
fn subject_of(boxes: &[Option<Aabb>]) -> Option<Aabb> {
    // The rest of the scene for object i is prefix[i] ∪ suffix[i + 1]: linear in the object count.
    let mut prefix = vec![None; boxes.len() + 1];
    let mut suffix = vec![None; boxes.len() + 1];
    for (i, b) in boxes.iter().enumerate() {
        prefix[i + 1] = join(prefix[i], *b);
    }
    for (i, b) in boxes.iter().enumerate().rev() {
        suffix[i] = join(suffix[i + 1], *b);
    }
    boxes
        .iter()
        .enumerate()
        .filter_map(|(i, b)| b.filter(|b| !is_ground(*b, join(prefix[i], suffix[i + 1]))))
        .reduce(union)
}

/// Flat and much larger than the rest of the scene (an object alone is never ground).
fn is_ground(b: Aabb, rest: Option<Aabb>) -> bool {
    let extent = b.1 - b.0;
    let largest = extent.max_element();
    rest.is_some_and(|rest| {
        extent.min_element() < GROUND_FLATNESS * largest && largest > GROUND_DOMINANCE * (rest.1 - rest.0).max_element()
    })
}

/// Every object's world box and world triangles.
struct Geometry {
    /// Per object, the box of its finite world positions.
    boxes: Vec<Option<Aabb>>,
    /// World triangles, wound as the object is seen (mirroring transforms undone).
    triangles: Vec<[Vec3; 3]>,
    /// Per triangle: its mesh is closed (a solid it enters and leaves).
    solid: Vec<bool>,
}

impl Geometry {
    fn of(scene: &Scene) -> Self {
        let mut geometry = Self { boxes: Vec::new(), triangles: Vec::new(), solid: Vec::new() };
        for o in &scene.objects {
            let m = o.transform_f64();
            // A mirroring transform turns the winding inside out; glTF renders it flipped back.
            let mirrors = m.matrix3.determinant() < 0.0;
            let world: Vec<Vec3> =
                o.topology.positions.iter().map(|p| m.transform_point3(p.as_dvec3()).as_vec3()).collect();
            let bounds = world.iter().filter(|p| p.is_finite()).map(|&p| (p, p)).reduce(union);
            geometry.boxes.push(bounds);
            let closed = o.topology.is_closed_manifold();
            for f in &o.topology.faces {
                let [a, b, c] = f.map(|i| world.get(i as usize).copied().unwrap_or(Vec3::NAN));
                if a.is_finite() && b.is_finite() && c.is_finite() {
                    geometry.triangles.push(if mirrors { [a, c, b] } else { [a, b, c] });
                    geometry.solid.push(closed);
                }
            }
        }
        geometry
    }
}

/// Rays through the scene's world triangles.
struct Probe<'a> {
    bvh: Bvh,
    geometry: &'a Geometry,
    t_min: f32,
    min_span: f32,
}

impl Probe<'_> {
    /// The first stretch of free space along the ray at least `min_span` long
    /// (see the module's doc): where it starts and, when a surface or a solid
    /// bounds it, where it ends; `None` for the end when the ray leaves the
    /// scene from it.
    fn open_span(&self, origin: Vec3, dir: Vec3) -> (f32, Option<f32>) {
        // (t, depth change): +1 entering a solid, −1 leaving one, 0 a surface.
        let mut crossings: Vec<(f32, i64)> = Vec::new();
        self.bvh.for_each_hit_index(origin, dir, self.t_min, f32::INFINITY, |i| {
            let tri = &self.geometry.triangles[i as usize];
            if let Some(t) = bvh::intersect(tri, origin, dir) {
                let change = match (self.geometry.solid[i as usize], (tri[1] - tri[0]).cross(tri[2] - tri[0]).dot(dir))
                {
                    (false, _) => 0,
                    (true, facing) if facing < 0.0 => 1,
                    (true, _) => -1,
                };
                crossings.push((t, change));
            }
        });
        // Leaving before entering at one distance (two solids sharing a face).
        crossings.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        // The solids around the origin: every one of them is left once more than entered.
        let mut depth = (-crossings.iter().map(|c| c.1).sum::<i64>()).max(0);
        let mut start = 0.0;
        for (t, change) in crossings {
            if depth == 0 && t - start >= self.min_span {
                return (start, Some(t));
            }
            depth = (depth + change).max(0);
            if depth == 0 {
                start = t;
            }
        }
        (start, None)
    }

    /// Along a ray down: whether its last surface faces up
    /// ([`GROUND_SLOPE_COS`]), and the distance to its last surface facing up;
    /// `None` when it meets nothing.
    fn column(&self, origin: Vec3, dir: Vec3) -> Option<(bool, Option<f32>)> {
        let mut last: Option<(f32, bool)> = None;
        let mut last_up: Option<f32> = None;
        self.bvh.for_each_hit_index(origin, dir, self.t_min, f32::INFINITY, |i| {
            let tri = &self.geometry.triangles[i as usize];
            if let Some(t) = bvh::intersect(tri, origin, dir) {
                let up = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize_or_zero().y > GROUND_SLOPE_COS;
                if last.is_none_or(|(l, _)| t > l) {
                    last = Some((t, up));
                }
                if up && last_up.is_none_or(|l| t > l) {
                    last_up = Some(t);
                }
            }
        });
        last.map(|(_, up)| (up, last_up))
    }

    /// Distance to the first surface along the ray.
    fn closest(&self, origin: Vec3, dir: Vec3) -> Option<f32> {
        self.bvh.closest_hit(origin, dir, self.t_min).map(|h| h.t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_widest_open_run_wraps_around_and_ignores_all_or_nothing() {
        assert_eq!(widest_open_run(&[true, false, false, true, true]), Some(3..6));
        assert_eq!(widest_open_run(&[false, true, true, false, true]), Some(1..3));
        assert_eq!(widest_open_run(&[true; 4]), None);
        assert_eq!(widest_open_run(&[false; 4]), None);
    }

    #[test]
    fn there_are_26_unit_cube_directions_and_none_repeats() {
        let d: Vec<Vec3> = cube_directions().collect();
        assert_eq!(d.len(), 26);
        assert!(d.iter().all(|v| (v.length() - 1.0).abs() < 1e-6));
        assert!(d.iter().enumerate().all(|(i, a)| d[i + 1..].iter().all(|b| a.distance(*b) > 0.1)));
    }

    #[test]
    fn a_box_is_left_where_the_ray_meets_its_nearest_side() {
        let b = (Vec3::new(-1.0, -2.0, -3.0), Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(box_exit(Vec3::ZERO, Vec3::X, b), 1.0);
        assert_eq!(box_exit(Vec3::ZERO, Vec3::NEG_Z, b), 3.0);
        assert!((box_exit(Vec3::ZERO, Vec3::new(0.0, 1.0, 1.0).normalize(), b) - 2f32.sqrt() * 2.0).abs() < 1e-6);
    }

    #[test]
    fn a_flat_object_is_ground_only_when_it_dwarfs_the_rest() {
        let plane = (Vec3::new(-50.0, 0.0, -50.0), Vec3::new(50.0, 0.0, 50.0));
        let tree = Some((Vec3::new(0.0, 0.0, 0.0), Vec3::new(2.0, 4.5, 2.0)));
        assert!(is_ground(plane, tree));
        assert!(!is_ground(plane, None));
        assert!(!is_ground(plane, Some((Vec3::splat(-20.0), Vec3::splat(20.0)))));
        assert!(!is_ground((Vec3::ZERO, Vec3::splat(100.0)), tree));
    }
}
