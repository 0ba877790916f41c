//! A glTF's animations, played by Bevy's own `AnimationPlayer` (the one the
//! glTF loader puts on each animated hierarchy's root): the characters move
//! as in a game, and the fin shadows follow their current pose.
//!
//! The editor owns the clock: the player is kept paused and sought to
//! [`EditorAnimation::time`], so a time typed in, scrubbed or given on the
//! command line (`--animation-time`) is exactly the pose shown (resting, a
//! time is clamped to the clip, its last pose included; playing loops). The
//! ground truth and the analysis views trace a snapshot of the scene
//! ([`LoadedScene`]): it is taken again whenever the animation has rested at
//! a new time for as long as Bevy takes to apply it (while it plays, or while
//! a slider is dragged, they show the last pose it rested at: tracing every
//! frame's pose would never finish).

use bevy::{gltf::Gltf, prelude::*};

use crate::state::LoadedScene;

/// One clip of the loaded glTF.
#[derive(Debug, Clone)]
pub struct Clip {
    pub name: String,
    pub duration: f32,
    node: AnimationNodeIndex,
}

/// The loaded glTF's animations and where they stand.
#[derive(Resource, Debug, Default)]
pub struct EditorAnimation {
    /// The clips in the file's order (none: the scene does not animate).
    pub clips: Vec<Clip>,
    /// The clip shown.
    pub selected: usize,
    /// Advancing with the frame time (looping), or resting at `time`.
    pub playing: bool,
    /// Seconds into the selected clip.
    pub time: f32,
    /// The pose the ground truth's snapshot was taken at, (clip, time).
    pub snapshot_pose: Option<(usize, f32)>,
    players: Vec<Entity>,
    /// The pose sought last and the frame it was sought in (Bevy applies it
    /// in that frame's `PostUpdate`, or the next one's when the animation
    /// graph was added that frame: [`SNAPSHOT_DELAY_FRAMES`]).
    sought: Option<((usize, f32), u32)>,
}

impl EditorAnimation {
    /// The selected clip's length, s (0 without clips).
    pub fn duration(&self) -> f32 {
        self.clips.get(self.selected).map_or(0.0, |c| c.duration)
    }

    /// `seconds` as a time of the selected clip to rest at: clamped into its
    /// length (its last pose is a pose too), 0 where it is not a number.
    pub fn resting_at(&self, seconds: f32) -> f32 {
        if seconds.is_nan() { 0.0 } else { seconds.clamp(0.0, self.duration()) }
    }

    /// `seconds` as a time of the selected clip while it plays: wrapped into
    /// its length (it loops), 0 where it is not a finite number.
    pub fn looped(&self, seconds: f32) -> f32 {
        let d = self.duration();
        if !seconds.is_finite() || d <= 0.0 { 0.0 } else { seconds.rem_euclid(d) }
    }
}

/// Frames after a seek before the pose is surely applied: Bevy threads a new
/// animation graph in the `PostUpdate` after the one it was added in
/// (`thread_animation_graphs` waits for its asset event), so the first pose
/// of a loaded glTF lands a frame late.
const SNAPSHOT_DELAY_FRAMES: u32 = 2;

pub(crate) fn build(app: &mut App) {
    app.init_resource::<EditorAnimation>().add_systems(
        Update,
        (
            drive_animation.after(crate::state::GltfLoadsFinished),
            // Exclusive (it snapshots the world): only while a sought pose is untraced.
            snapshot_rested_pose.after(drive_animation).run_if(pose_untraced),
        ),
    );
}

/// A pose was sought that the ground truth's snapshot does not hold yet.
fn pose_untraced(animation: Res<EditorAnimation>) -> bool {
    animation.sought.is_some_and(|(pose, _)| animation.snapshot_pose != Some(pose))
}

/// Adopts the animations of the glTF `file` spawned under `root` (its
/// clips, on every animation player under `root`), held at
/// `start_time` s of the first clip. Returns what it did, for the status line.
pub(crate) fn adopt_animations(
    world: &mut World,
    root: Entity,
    file: Option<&Handle<Gltf>>,
    start_time: f32,
) -> String {
    let players = bevy_shadow_fins::descendants_with::<AnimationPlayer>(world, root);
    let clips: Vec<(String, Handle<AnimationClip>)> = file
        .and_then(|file| world.resource::<Assets<Gltf>>().get(file))
        .map(|gltf| {
            gltf.animations
                .iter()
                .enumerate()
                .map(|(k, clip)| {
                    let named = gltf.named_animations.iter().find(|(_, h)| h.id() == clip.id());
                    (named.map_or_else(|| format!("clip {k}"), |(name, _)| name.to_string()), clip.clone())
                })
                .collect()
        })
        .unwrap_or_default();
    let mut animation = EditorAnimation::default();
    if players.is_empty() || clips.is_empty() {
        world.insert_resource(animation);
        return String::new();
    }
    let (graph, nodes) = AnimationGraph::from_clips(clips.iter().map(|(_, h)| h.clone()));
    let graph = world.resource_mut::<Assets<AnimationGraph>>().add(graph);
    let durations: Vec<f32> = {
        let assets = world.resource::<Assets<AnimationClip>>();
        clips.iter().map(|(_, h)| assets.get(h).map_or(0.0, |c| c.duration())).collect()
    };
    animation.clips = clips
        .into_iter()
        .zip(nodes)
        .zip(durations)
        .map(|(((name, _), node), duration)| Clip { name, duration, node })
        .collect();
    for &player in &players {
        world.entity_mut(player).insert(AnimationGraphHandle(graph.clone()));
    }
    animation.players = players;
    animation.time = animation.resting_at(start_time);
    let line = format!(
        "animations: {} (held at {:.2} s of {:?})",
        animation.clips.len(),
        animation.time,
        animation.clips[0].name
    );
    world.insert_resource(animation);
    line
}

/// Advances a playing clip and seeks every player to the selected clip's
/// time, kept paused: Bevy's animation poses the targets this frame.
fn drive_animation(
    time: Res<Time>,
    frames: Res<bevy::diagnostic::FrameCount>,
    mut animation: ResMut<EditorAnimation>,
    mut players: Query<&mut AnimationPlayer>,
) {
    if animation.clips.is_empty() {
        return;
    }
    animation.selected = animation.selected.min(animation.clips.len() - 1);
    if animation.playing {
        let advanced = animation.time + time.delta_secs();
        animation.time = animation.looped(advanced);
    } else {
        // A typed-in time: into the clip's length, never NaN.
        animation.time = animation.resting_at(animation.time);
    }
    let pose = (animation.selected, animation.time);
    if animation.sought.is_some_and(|(p, _)| p == pose) {
        return;
    }
    let node = animation.clips[animation.selected].node;
    for &entity in &animation.players {
        let Ok(mut player) = players.get_mut(entity) else { continue };
        if !player.is_playing_animation(node) {
            player.stop_all();
            player.play(node).pause();
        }
        if let Some(active) = player.animation_mut(node) {
            active.seek_to(pose.1);
        }
    }
    animation.sought = Some((pose, frames.0));
}

/// Once the animation rests at a pose Bevy has applied, the ground truth's
/// snapshot is taken again (a new [`LoadedScene`] generation).
fn snapshot_rested_pose(world: &mut World) {
    let frame = world.resource::<bevy::diagnostic::FrameCount>().0;
    let animation = world.resource::<EditorAnimation>();
    let Some((pose, sought_in)) = animation.sought else { return };
    if animation.playing || animation.snapshot_pose == Some(pose) || frame < sought_in + SNAPSHOT_DELAY_FRAMES {
        return;
    }
    let Some(loaded) = world.get_resource::<LoadedScene>().cloned() else { return };
    let root = world.query_filtered::<Entity, With<crate::state::EditorSceneRoot>>().iter(world).next();
    let Some(root) = root else { return };
    let snapshot = bevy_shadow_fins::scene_snapshot(world, Some(root));
    world.insert_resource(LoadedScene {
        // The ground the editor added is not under the root: it comes back.
        scene: std::sync::Arc::new(crate::ground::with_shown_ground(world, snapshot.scene)),
        generation: loaded.generation + 1,
        ..loaded
    });
    world.resource_mut::<EditorAnimation>().snapshot_pose = Some(pose);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resting_times_clamp_to_the_clip_playing_ones_loop_and_none_is_nan() {
        let mut a = EditorAnimation::default();
        // No clip: every time is 0.
        assert_eq!((a.resting_at(1.5), a.looped(1.5)), (0.0, 0.0));
        a.clips.push(Clip { name: "bend".into(), duration: 2.0, node: AnimationNodeIndex::new(1) });
        assert_eq!(a.resting_at(1.5), 1.5);
        // The last pose can be rested at; past it and before 0, the ends.
        assert_eq!((a.resting_at(2.0), a.resting_at(2.5), a.resting_at(-0.5)), (2.0, 2.0, 0.0));
        assert_eq!((a.looped(2.5), a.looped(-0.5)), (0.5, 1.5));
        assert_eq!((a.resting_at(f32::INFINITY), a.resting_at(f32::NEG_INFINITY)), (2.0, 0.0));
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            assert_eq!(a.looped(bad), 0.0, "{bad}");
        }
        assert_eq!(a.resting_at(f32::NAN), 0.0);
        // A clip of no length (a single key) rests at 0.
        a.clips[0].duration = 0.0;
        assert_eq!((a.resting_at(0.7), a.looped(0.7)), (0.0, 0.0));
    }
}
