//! Our own small, license-clean glTF 2.0 test assets, written by
//! `shadow-fins-lab make-assets`: a courtyard (a node hierarchy, a spot light,
//! a camera, textures), alpha-masked leaf cards, a skinned arm and a
//! morph-target blob.
//!
//! Each file is self-contained (the buffer and the PNG textures are `data:`
//! URIs), in metres with +Y up, and has the same bytes on every run and, with
//! the same `png` crate, every machine: the numbers come from `+ − × ÷ √`
//! alone (no trigonometry, whose last bit differs between C libraries), so a
//! test can compare the committed files with the generator. The JSON has one object per line to diff well.
//!
//! A light's physical radius is its `extras.radius`: KHR lights have none, and
//! Bevy 0.19's loader sets a spot or point light's `radius` to its `range`.

use std::path::{Path, PathBuf};

use crate::LabError;

/// `obj! {"key": value, …}`: a JSON object with its keys in the order written.
macro_rules! obj {
    ($($key:literal : $value:expr),* $(,)?) => { Json::Obj(vec![$(($key, Json::from($value))),*]) };
}

/// One generated file: its name in the output folder and its text.
pub struct Asset {
    pub file: &'static str,
    pub text: String,
}

/// The files `make-assets` writes, in order.
pub const FILES: [&str; 4] = ["courtyard.gltf", "leaf-cards.gltf", "skinned-arm.gltf", "morph-blob.gltf"];

/// Every asset, in the order of [`FILES`].
pub fn all() -> Result<Vec<Asset>, LabError> {
    let texts = [courtyard()?, leaf_cards()?, skinned_arm()?, morph_blob()?];
    Ok(FILES.into_iter().zip(texts).map(|(file, text)| Asset { file, text }).collect())
}

/// Writes every asset into `dir` (made if missing); returns the paths written.
pub fn write_all(dir: &Path) -> Result<Vec<PathBuf>, LabError> {
    std::fs::create_dir_all(dir).map_err(|e| LabError::Io(dir.display().to_string(), e))?;
    all()?
        .into_iter()
        .map(|a| {
            let path = dir.join(a.file);
            std::fs::write(&path, a.text).map_err(|e| LabError::Io(path.display().to_string(), e))?;
            Ok(path)
        })
        .collect()
}

/// Where the courtyard's spot light and camera aim: the middle of the table top.
pub const COURTYARD_TARGET: [f32; 3] = [0.4, 0.88, -0.3];

/// A 12 × 12 m checker ground, a table (a root with translation, Y rotation
/// and non-uniform scale; a top and four legs, one leg placed by a `matrix`;
/// a vase on a leg, three levels down) whose top is 0.88 m up, an arch of
/// three overlapping parts (open-bottomed pillars and a lintel), a spot light
/// and a camera aimed at the table.
pub fn courtyard() -> Result<String, LabError> {
    let mut doc = Doc::default();
    let repeat = doc.sampler(REPEAT);
    let checker = doc.png_texture("checker", checker_png(64, 32, [206, 204, 194], [118, 122, 128])?, repeat);
    let wood = doc.png_texture("wood", wood_png(64)?, repeat);
    let ground_m = doc.material(textured("ground", checker));
    let wood_m = doc.material(textured("wood", wood));
    let stone_m = doc.material(coloured("stone", [0.72, 0.7, 0.64, 1.0]));
    let glaze_m = doc.material(coloured("glaze", [0.25, 0.4, 0.75, 1.0]));

    let ground = doc.mesh("ground", &Geometry::ground(12.0, 12.0), ground_m);
    let top = doc.mesh("top", &Geometry::cuboid([1.4, 0.08, 0.9], [0.0, 0.0, 0.0], false), wood_m);
    let leg = doc.mesh("leg", &Geometry::cuboid([0.08, 0.8, 0.08], [0.0, 0.0, 0.0], false), wood_m);
    let vase_profile = [[0.07, 0.0], [0.11, 0.07], [0.12, 0.15], [0.09, 0.25], [0.05, 0.3], [0.065, 0.34]];
    let vase = doc.mesh("vase", &Geometry::lathe(&vase_profile), glaze_m);
    let pillar = doc.mesh("pillar", &Geometry::cuboid([0.35, 2.0, 0.35], [0.0, 1.0, 0.0], true), stone_m);
    let lintel = doc.mesh("lintel", &Geometry::cuboid([2.2, 0.35, 0.5], [0.0, 0.0, 0.0], false), stone_m);

    let ground = doc.node(obj! {"name": "ground", "mesh": ground});
    let vase = doc.node(obj! {
        "name": "vase", "mesh": vase, "translation": [-0.15, 0.48, -0.1], "rotation": unit_quat([0.0, 0.6, 0.0, 1.0]),
    });
    let top = doc.node(obj! {"name": "top", "mesh": top, "translation": [0.0, 0.84, 0.0]});
    let mut legs = Vec::new();
    for (i, [x, z]) in [[0.6, 0.35], [-0.6, 0.35], [-0.6, -0.35]].into_iter().enumerate() {
        let mut node = obj! {"name": format!("leg.{i}"), "mesh": leg, "translation": [x, 0.4, z]};
        if i == 0 {
            node = node.with("children", vec![vase]);
        }
        legs.push(doc.node(node));
    }
    // 45° about Y and a translation, as a column-major matrix.
    let (c, s) = (0.707_106_77f32, 0.707_106_77f32);
    let matrix = [c, 0.0, -s, 0.0, 0.0, 1.0, 0.0, 0.0, s, 0.0, c, 0.0, 0.6, 0.4, -0.35, 1.0];
    legs.push(doc.node(obj! {"name": "leg.3", "mesh": leg, "matrix": matrix}));
    let mut children = vec![top];
    children.extend(legs);
    let table = doc.node(obj! {
        "name": "table", "children": children, "translation": [0.4, 0.0, -0.3],
        "rotation": unit_quat([0.0, 0.25, 0.0, 1.0]), "scale": [1.15, 1.0, 0.85],
    });
    let pillar_l = doc.node(obj! {"name": "pillar.left", "mesh": pillar, "translation": [-0.9, 0.0, 0.0]});
    let pillar_r = doc.node(obj! {"name": "pillar.right", "mesh": pillar, "translation": [0.9, 0.0, 0.0]});
    let lintel = doc.node(obj! {"name": "lintel", "mesh": lintel, "translation": [0.0, 1.9, 0.0]});
    let arch = doc.node(obj! {
        "name": "arch", "children": vec![pillar_l, pillar_r, lintel], "translation": [-2.6, 0.0, 0.8],
        "rotation": unit_quat([0.0, -0.4, 0.0, 1.0]),
    });
    doc.roots.extend([ground, table, arch]);
    doc.spot_and_camera([3.0, 6.0, 2.0], [6.0, 4.0, 8.0], COURTYARD_TARGET);
    doc.finish("courtyard")
}

/// Five double-sided, alpha-masked leaf cards (a leaf with three round holes
/// in an RGBA texture) standing and tilted above a checker ground.
pub fn leaf_cards() -> Result<String, LabError> {
    let mut doc = Doc::default();
    let (repeat, clamp) = (doc.sampler(REPEAT), doc.sampler(CLAMP_TO_EDGE));
    let checker = doc.png_texture("checker", checker_png(64, 32, [206, 204, 194], [118, 122, 128])?, repeat);
    let leaf_t = doc.png_texture("leaf", leaf_png(128)?, clamp);
    let ground_m = doc.material(textured("ground", checker));
    let leaf_m = doc.material(
        textured("leaf", leaf_t).with("alphaMode", "MASK").with("alphaCutoff", 0.5).with("doubleSided", true),
    );
    let ground = doc.mesh("ground", &Geometry::ground(8.0, 8.0), ground_m);
    // A 0.6 × 0.9 m card in the XY plane, its stem end at the origin.
    let mut card = Geometry::default();
    card.quad([0.0, 0.45, 0.0], [0.3, 0.0, 0.0], [0.0, 0.45, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0]);
    let card = doc.mesh("leaf", &card, leaf_m);
    let ground = doc.node(obj! {"name": "ground", "mesh": ground});
    doc.roots.push(ground);
    let cards: [([f32; 3], [f64; 4]); 5] = [
        ([0.0, 0.3, 0.0], [0.0, 0.2, 0.0, 1.0]),
        ([0.7, 0.5, 0.3], [-0.3, 0.5, 0.0, 1.0]),
        ([-0.6, 0.25, 0.5], [0.2, -0.6, 0.1, 1.0]),
        ([0.2, 0.9, -0.6], [-0.6, 0.1, 0.2, 1.0]),
        ([-0.3, 1.2, -0.2], [-0.9, 0.3, 0.0, 1.0]),
    ];
    for (i, (t, r)) in cards.into_iter().enumerate() {
        let node =
            doc.node(obj! {"name": format!("card.{i}"), "mesh": card, "translation": t, "rotation": unit_quat(r)});
        doc.roots.push(node);
    }
    doc.spot_and_camera([2.0, 5.0, 2.5], [2.5, 2.2, 3.5], [0.0, 0.6, 0.0]);
    doc.finish("leaf-cards")
}

/// Heights of the skinned arm's joints when bound (shoulder, elbow, wrist).
pub const ARM_JOINT_HEIGHTS: [f32; 3] = [0.2, 0.9, 1.5];

/// A 0.2 × 0.2 × 1.8 m arm of 12 segments on a pedestal, skinned to a
/// shoulder → elbow → wrist chain, and a 2 s animation `bend` that is
/// straight at 0 s and 2 s and bent over at 1 s.
pub fn skinned_arm() -> Result<String, LabError> {
    let mut doc = Doc::default();
    let repeat = doc.sampler(REPEAT);
    let checker = doc.png_texture("checker", checker_png(64, 32, [206, 204, 194], [118, 122, 128])?, repeat);
    let ground_m = doc.material(textured("ground", checker));
    let stone_m = doc.material(coloured("stone", [0.72, 0.7, 0.64, 1.0]));
    let clay_m = doc.material(coloured("clay", [0.8, 0.45, 0.3, 1.0]));
    let ground = doc.mesh("ground", &Geometry::ground(8.0, 8.0), ground_m);
    let pedestal = doc.mesh("pedestal", &Geometry::cuboid([0.5, 0.2, 0.5], [0.0, 0.1, 0.0], true), stone_m);

    let rings: Vec<f32> = (0..13).map(|k| 0.2 + 0.15 * k as f32).collect();
    let (arm, joints, weights) = arm_geometry(&rings, 0.1);
    let joints = doc.joints(&joints);
    let weights = doc.floats(&weights.concat(), "VEC4", Some(ARRAY_BUFFER), false);
    let primitive = doc.primitive(&arm, &[("JOINTS_0", joints), ("WEIGHTS_0", weights)]);
    let arm = doc.mesh_of("arm", primitive.with("material", clay_m));

    let ground = doc.node(obj! {"name": "ground", "mesh": ground});
    let pedestal = doc.node(obj! {"name": "pedestal", "mesh": pedestal});
    let [h0, h1, h2] = ARM_JOINT_HEIGHTS;
    let wrist = doc.node(obj! {"name": "wrist", "translation": [0.0, h2 - h1, 0.0]});
    let elbow = doc.node(obj! {"name": "elbow", "children": vec![wrist], "translation": [0.0, h1 - h0, 0.0]});
    let shoulder = doc.node(obj! {"name": "shoulder", "children": vec![elbow], "translation": [0.0, h0, 0.0]});
    // Each joint's bind is a translation up the arm: its inverse moves back down.
    let bind_heights = [h0, h0 + (h1 - h0), h0 + (h1 - h0) + (h2 - h1)];
    let inverse_binds: Vec<f32> = bind_heights
        .iter()
        .flat_map(|h| [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -h, 0.0, 1.0])
        .collect();
    let inverse_binds = doc.floats(&inverse_binds, "MAT4", None, false);
    let skin = doc.skins.len();
    doc.skins.push(obj! {
        "name": "arm", "joints": vec![shoulder, elbow, wrist], "skeleton": shoulder, "inverseBindMatrices": inverse_binds,
    });
    // The skinned mesh's node sits at the root: a parent's transform would not move it.
    let arm = doc.node(obj! {"name": "arm", "mesh": arm, "skin": skin});
    doc.roots.extend([ground, pedestal, arm, shoulder]);

    let times = doc.floats(&[0.0, 1.0, 2.0], "SCALAR", None, true);
    let rest = [0.0, 0.0, 0.0, 1.0];
    let mut samplers = Vec::new();
    let mut channels = Vec::new();
    for (node, bend) in [(shoulder, 0.35), (elbow, 0.6), (wrist, 0.5)] {
        let keys = [rest, unit_quat([0.0, 0.0, bend, 1.0]), rest].concat();
        let output = doc.floats(&keys, "VEC4", None, false);
        channels.push(obj! {"sampler": samplers.len(), "target": obj! {"node": node, "path": "rotation"}});
        samplers.push(obj! {"input": times, "output": output, "interpolation": "LINEAR"});
    }
    doc.animations.push(obj! {"name": "bend", "samplers": samplers, "channels": channels});
    doc.spot_and_camera([3.0, 6.0, 2.0], [4.0, 2.5, 6.0], [0.0, 1.0, 0.0]);
    doc.finish("skinned-arm")
}

/// A 1 m box whose top is a 4 × 4 grid, with two morph targets: `spike` (the
/// top's centre 1.6 m up) and `lean` (the top 0.45 m along +X), and a 2 s
/// animation `grow` through none, spike, both, lean and none again.
pub fn morph_blob() -> Result<String, LabError> {
    let mut doc = Doc::default();
    let repeat = doc.sampler(REPEAT);
    let checker = doc.png_texture("checker", checker_png(64, 32, [206, 204, 194], [118, 122, 128])?, repeat);
    let ground_m = doc.material(textured("ground", checker));
    let clay_m = doc.material(coloured("clay", [0.8, 0.45, 0.3, 1.0]));
    let ground = doc.mesh("ground", &Geometry::ground(8.0, 8.0), ground_m);

    let blob = blob_geometry();
    let targets: [Vec<[f32; 3]>; 2] = [
        blob.positions
            .iter()
            .map(|p| {
                // The top grid's rings about its middle: 0 (the middle), 1, 2 (its edge).
                let ring = (p[0] * 4.0).abs().max((p[2] * 4.0).abs());
                let rise = if p[1] != 1.0 {
                    0.0
                } else if ring == 0.0 {
                    1.6
                } else if ring == 1.0 {
                    0.35
                } else {
                    0.0
                };
                [0.0, rise, 0.0]
            })
            .collect(),
        blob.positions.iter().map(|p| if p[1] == 1.0 { [0.45, 0.0, 0.0] } else { [0.0; 3] }).collect(),
    ];
    let mut primitive = doc.primitive(&blob, &[]);
    let targets: Vec<Json> =
        targets.iter().map(|t| obj! {"POSITION": doc.floats(&t.concat(), "VEC3", Some(ARRAY_BUFFER), true)}).collect();
    primitive = primitive.with("targets", targets).with("material", clay_m);
    let blob_mesh = doc.meshes.len();
    doc.meshes.push(obj! {
        "name": "blob", "primitives": vec![primitive], "weights": [0.0, 0.0],
        "extras": obj! {"targetNames": vec!["spike", "lean"]},
    });

    let ground = doc.node(obj! {"name": "ground", "mesh": ground});
    let blob = doc.node(obj! {"name": "blob", "mesh": blob_mesh});
    doc.roots.extend([ground, blob]);
    let times = doc.floats(&[0.0, 0.5, 1.0, 1.5, 2.0], "SCALAR", None, true);
    let weights = doc.floats(&[0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 1.0, 0.0, 0.0], "SCALAR", None, false);
    doc.animations.push(obj! {
        "name": "grow",
        "samplers": vec![obj! {"input": times, "output": weights, "interpolation": "LINEAR"}],
        "channels": vec![obj! {"sampler": 0u32, "target": obj! {"node": blob, "path": "weights"}}],
    });
    doc.spot_and_camera([3.0, 6.0, 2.0], [4.0, 2.5, 6.0], [0.0, 1.2, 0.0]);
    doc.finish("morph-blob")
}

// ---------------------------------------------------------------------------
// glTF constants.

const FLOAT: u32 = 5126;
const UNSIGNED_BYTE: u32 = 5121;
const UNSIGNED_SHORT: u32 = 5123;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const REPEAT: u32 = 10497;
const CLAMP_TO_EDGE: u32 = 33071;
const LINEAR: u32 = 9729;
const LINEAR_MIPMAP_LINEAR: u32 = 9987;

// ---------------------------------------------------------------------------
// A JSON value small enough to write by hand, in a fixed key order.

#[derive(Debug, Clone)]
enum Json {
    Num(f32),
    Int(u64),
    Bool(bool),
    Str(String),
    Arr(Vec<Json>),
    Obj(Vec<(&'static str, Json)>),
}

impl From<f32> for Json {
    fn from(v: f32) -> Self {
        Json::Num(v)
    }
}
impl From<u32> for Json {
    fn from(v: u32) -> Self {
        Json::Int(v as u64)
    }
}
impl From<usize> for Json {
    fn from(v: usize) -> Self {
        Json::Int(v as u64)
    }
}
impl From<bool> for Json {
    fn from(v: bool) -> Self {
        Json::Bool(v)
    }
}
impl From<&str> for Json {
    fn from(v: &str) -> Self {
        Json::Str(v.to_string())
    }
}
impl From<String> for Json {
    fn from(v: String) -> Self {
        Json::Str(v)
    }
}
impl<T: Into<Json>> From<Vec<T>> for Json {
    fn from(v: Vec<T>) -> Self {
        Json::Arr(v.into_iter().map(Into::into).collect())
    }
}
impl<const N: usize> From<[f32; N]> for Json {
    fn from(v: [f32; N]) -> Self {
        Json::Arr(v.into_iter().map(Json::Num).collect())
    }
}

impl Json {
    /// The object with one more key (a no-op on anything but an object).
    fn with(mut self, key: &'static str, value: impl Into<Json>) -> Self {
        if let Json::Obj(pairs) = &mut self {
            pairs.push((key, value.into()));
        }
        self
    }

    fn write(&self, out: &mut String) {
        match self {
            // Rust prints the shortest text that reads back to the same f32, never in exponent form.
            Json::Num(v) => {
                assert!(v.is_finite(), "JSON has no {v}");
                out.push_str(&v.to_string())
            }
            Json::Int(v) => out.push_str(&v.to_string()),
            Json::Bool(v) => out.push_str(if *v { "true" } else { "false" }),
            Json::Str(s) => {
                out.push('"');
                for c in s.chars() {
                    match c {
                        '"' => out.push_str("\\\""),
                        '\\' => out.push_str("\\\\"),
                        c if (c as u32) < 0x20 => out.push(' '),
                        c => out.push(c),
                    }
                }
                out.push('"');
            }
            Json::Arr(items) => {
                out.push('[');
                for (i, item) in items.iter().enumerate() {
                    if i > 0 {
                        out.push(',');
                    }
                    item.write(out);
                }
                out.push(']');
            }
            Json::Obj(pairs) => {
                out.push('{');
                for (i, (key, value)) in pairs.iter().enumerate() {
                    if i > 0 {
                        out.push(',');
                    }
                    out.push('"');
                    out.push_str(key);
                    out.push_str("\":");
                    value.write(out);
                }
                out.push('}');
            }
        }
    }
}

/// The top-level object, one key per line and one array element per line.
fn document(pairs: &[(&'static str, Json)]) -> String {
    let mut out = String::from("{\n");
    for (i, (key, value)) in pairs.iter().enumerate() {
        out.push_str(if i > 0 { ",\n\"" } else { "\"" });
        out.push_str(key);
        out.push_str("\": ");
        match value {
            Json::Arr(items) => {
                out.push_str("[\n");
                for (j, item) in items.iter().enumerate() {
                    if j > 0 {
                        out.push_str(",\n");
                    }
                    item.write(&mut out);
                }
                out.push_str("\n]");
            }
            v => v.write(&mut out),
        }
    }
    out.push_str("\n}\n");
    out
}

// ---------------------------------------------------------------------------
// A glTF document under construction: one buffer, lists that grow.

#[derive(Default)]
struct Doc {
    bin: Vec<u8>,
    views: Vec<Json>,
    accessors: Vec<Json>,
    images: Vec<Json>,
    samplers: Vec<Json>,
    textures: Vec<Json>,
    materials: Vec<Json>,
    meshes: Vec<Json>,
    nodes: Vec<Json>,
    skins: Vec<Json>,
    animations: Vec<Json>,
    cameras: Vec<Json>,
    lights: Vec<Json>,
    roots: Vec<usize>,
}

fn push(list: &mut Vec<Json>, item: Json) -> usize {
    list.push(item);
    list.len() - 1
}

impl Doc {
    /// A buffer view of `bytes`, 4-byte aligned.
    fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        let mut view = obj! {"buffer": 0u32, "byteOffset": self.bin.len(), "byteLength": bytes.len()};
        if let Some(t) = target {
            view = view.with("target", t);
        }
        self.bin.extend_from_slice(bytes);
        push(&mut self.views, view)
    }

    /// An accessor of floats of type `kind` (`SCALAR`, `VEC2`, … `MAT4`), with
    /// per-component min and max when `bounds`.
    fn floats(&mut self, data: &[f32], kind: &'static str, target: Option<u32>, bounds: bool) -> usize {
        let n = match kind {
            "SCALAR" => 1,
            "VEC2" => 2,
            "VEC3" => 3,
            "VEC4" => 4,
            _ => 16,
        };
        let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, target);
        let mut accessor = obj! {"bufferView": view, "componentType": FLOAT, "count": data.len() / n, "type": kind};
        if bounds {
            let (mut lo, mut hi) = (vec![f32::INFINITY; n], vec![f32::NEG_INFINITY; n]);
            for element in data.chunks(n) {
                for (c, &v) in element.iter().enumerate() {
                    lo[c] = lo[c].min(v);
                    hi[c] = hi[c].max(v);
                }
            }
            accessor = accessor.with("min", lo).with("max", hi);
        }
        push(&mut self.accessors, accessor)
    }

    fn indices(&mut self, indices: &[u32]) -> usize {
        let bytes: Vec<u8> = indices.iter().flat_map(|&i| (i as u16).to_le_bytes()).collect();
        let view = self.view(&bytes, Some(ELEMENT_ARRAY_BUFFER));
        let accessor =
            obj! {"bufferView": view, "componentType": UNSIGNED_SHORT, "count": indices.len(), "type": "SCALAR"};
        push(&mut self.accessors, accessor)
    }

    fn joints(&mut self, joints: &[[u8; 4]]) -> usize {
        let view = self.view(&joints.concat(), Some(ARRAY_BUFFER));
        let accessor = obj! {"bufferView": view, "componentType": UNSIGNED_BYTE, "count": joints.len(), "type": "VEC4"};
        push(&mut self.accessors, accessor)
    }

    /// A triangle primitive's `attributes` (with `extra` accessors) and
    /// `indices`; no material yet.
    fn primitive(&mut self, g: &Geometry, extra: &[(&'static str, usize)]) -> Json {
        assert!(g.positions.len() <= 1 << 16, "u16 indices");
        let position = self.floats(&g.positions.concat(), "VEC3", Some(ARRAY_BUFFER), true);
        let normal = self.floats(&g.normals.concat(), "VEC3", Some(ARRAY_BUFFER), false);
        let uv = self.floats(&g.uvs.concat(), "VEC2", Some(ARRAY_BUFFER), false);
        let indices = self.indices(&g.indices);
        let mut attributes = obj! {"POSITION": position, "NORMAL": normal, "TEXCOORD_0": uv};
        for &(key, accessor) in extra {
            attributes = attributes.with(key, accessor);
        }
        obj! {"attributes": attributes, "indices": indices, "mode": 4u32}
    }

    fn mesh(&mut self, name: &str, g: &Geometry, material: usize) -> usize {
        let primitive = self.primitive(g, &[]).with("material", material);
        self.mesh_of(name, primitive)
    }

    fn mesh_of(&mut self, name: &str, primitive: Json) -> usize {
        push(&mut self.meshes, obj! {"name": name, "primitives": vec![primitive]})
    }

    fn sampler(&mut self, wrap: u32) -> usize {
        let sampler = obj! {"magFilter": LINEAR, "minFilter": LINEAR_MIPMAP_LINEAR, "wrapS": wrap, "wrapT": wrap};
        push(&mut self.samplers, sampler)
    }

    /// An embedded PNG image and a texture sampling it.
    fn png_texture(&mut self, name: &str, png: Vec<u8>, sampler: usize) -> usize {
        let uri = format!("data:image/png;base64,{}", base64(&png));
        let image = push(&mut self.images, obj! {"name": name, "uri": uri});
        push(&mut self.textures, obj! {"name": name, "sampler": sampler, "source": image})
    }

    fn material(&mut self, m: Json) -> usize {
        push(&mut self.materials, m)
    }

    fn node(&mut self, n: Json) -> usize {
        push(&mut self.nodes, n)
    }

    /// The house spot light (`KHR_lights_punctual`, radius in `extras`) and
    /// a perspective camera, both root nodes looking at `target` down their −Z.
    fn spot_and_camera(&mut self, spot_at: [f32; 3], camera_at: [f32; 3], target: [f32; 3]) {
        let light = push(
            &mut self.lights,
            obj! {
                "name": "spot", "type": "spot", "color": [1.0, 0.95, 0.88], "intensity": 80000.0, "range": 40.0,
                "spot": obj! {"innerConeAngle": 0.3, "outerConeAngle": 0.8}, "extras": obj! {"radius": 0.4},
            },
        );
        let spot = self.node(obj! {
            "name": "spot", "translation": spot_at, "rotation": look_at(spot_at, target),
            "extensions": obj! {"KHR_lights_punctual": obj! {"light": light}},
        });
        let camera = push(
            &mut self.cameras,
            obj! {"name": "camera", "type": "perspective", "perspective": obj! {"yfov": 0.8, "znear": 0.05, "zfar": 200.0}},
        );
        let camera = self.node(
            obj! {"name": "camera", "camera": camera, "translation": camera_at, "rotation": look_at(camera_at, target)},
        );
        self.roots.extend([spot, camera]);
    }

    fn finish(mut self, name: &str) -> Result<String, LabError> {
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        let mut top: Vec<(&'static str, Json)> = vec![(
            "asset",
            obj! {
                "version": "2.0", "generator": "shadow-fins-lab make-assets",
                "copyright": "made by the shadow_fins project, MIT OR Apache-2.0",
            },
        )];
        if !self.lights.is_empty() {
            top.push(("extensionsUsed", vec!["KHR_lights_punctual"].into()));
            top.push(("extensions", obj! {"KHR_lights_punctual": obj! {"lights": self.lights}}));
        }
        top.push(("scene", 0u32.into()));
        top.push(("scenes", vec![obj! {"name": name, "nodes": self.roots}].into()));
        for (key, list) in [
            ("nodes", self.nodes),
            ("cameras", self.cameras),
            ("meshes", self.meshes),
            ("skins", self.skins),
            ("animations", self.animations),
            ("materials", self.materials),
            ("textures", self.textures),
            ("samplers", self.samplers),
            ("images", self.images),
            ("accessors", self.accessors),
            ("bufferViews", self.views),
        ] {
            // glTF forbids empty arrays.
            if !list.is_empty() {
                top.push((key, Json::Arr(list)));
            }
        }
        let uri = format!("data:application/octet-stream;base64,{}", base64(&self.bin));
        top.push(("buffers", vec![obj! {"byteLength": self.bin.len(), "uri": uri}].into()));
        Ok(document(&top))
    }
}

/// A metallic-0, roughness-0.8 material coloured by a texture.
fn textured(name: &str, texture: usize) -> Json {
    obj! {
        "name": name,
        "pbrMetallicRoughness": obj! {
            "baseColorTexture": obj! {"index": texture}, "metallicFactor": 0.0, "roughnessFactor": 0.8,
        },
    }
}

/// A metallic-0, roughness-0.8 material of one colour.
fn coloured(name: &str, rgba: [f32; 4]) -> Json {
    obj! {
        "name": name,
        "pbrMetallicRoughness": obj! {"baseColorFactor": rgba, "metallicFactor": 0.0, "roughnessFactor": 0.8},
    }
}

// ---------------------------------------------------------------------------
// Rotations, with `√` the only function beyond arithmetic.

/// `[x, y, z, w]` scaled to unit length: a rotation by `2 atan(|xyz| / w)`
/// about `xyz`.
fn unit_quat(q: [f64; 4]) -> [f32; 4] {
    let n = q.iter().map(|c| c * c).sum::<f64>().sqrt();
    q.map(|c| (c / n) as f32)
}

/// The rotation that turns −Z (a glTF camera's and spot light's forward) from
/// `eye` towards `target`, keeping +X horizontal.
fn look_at(eye: [f32; 3], target: [f32; 3]) -> [f32; 4] {
    let d: [f64; 3] = std::array::from_fn(|i| target[i] as f64 - eye[i] as f64);
    let z = normalize([-d[0], -d[1], -d[2]]);
    let x = normalize(cross([0.0, 1.0, 0.0], z));
    let y = cross(z, x);
    // The unit quaternion of the matrix [x y z] (columns), by its largest diagonal term.
    let (m00, m11, m22) = (x[0], y[1], z[2]);
    let trace = m00 + m11 + m22;
    let q = if trace > 0.0 {
        let s = (trace + 1.0).sqrt() * 2.0;
        [(y[2] - z[1]) / s, (z[0] - x[2]) / s, (x[1] - y[0]) / s, s / 4.0]
    } else if m00 > m11 && m00 > m22 {
        let s = (1.0 + m00 - m11 - m22).sqrt() * 2.0;
        [s / 4.0, (y[0] + x[1]) / s, (z[0] + x[2]) / s, (y[2] - z[1]) / s]
    } else if m11 > m22 {
        let s = (1.0 + m11 - m00 - m22).sqrt() * 2.0;
        [(y[0] + x[1]) / s, s / 4.0, (z[1] + y[2]) / s, (z[0] - x[2]) / s]
    } else {
        let s = (1.0 + m22 - m00 - m11).sqrt() * 2.0;
        [(z[0] + x[2]) / s, (z[1] + y[2]) / s, s / 4.0, (x[1] - y[0]) / s]
    };
    unit_quat(q)
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn normalize(v: [f64; 3]) -> [f64; 3] {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|c| c / n)
}

// ---------------------------------------------------------------------------
// Geometry: flat-shaded where it has corners, counter-clockwise from outside.

#[derive(Default)]
struct Geometry {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    indices: Vec<u32>,
}

fn add(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// `(cos, sin)` of `k · 30°`.
const CIRCLE_12: [[f32; 2]; 12] = {
    const H: f32 = 0.866_025_4; // √3 / 2
    [
        [1.0, 0.0],
        [H, 0.5],
        [0.5, H],
        [0.0, 1.0],
        [-0.5, H],
        [-H, 0.5],
        [-1.0, 0.0],
        [-H, -0.5],
        [-0.5, -H],
        [0.0, -1.0],
        [0.5, -H],
        [H, -0.5],
    ]
};

impl Geometry {
    fn vertex(&mut self, p: [f32; 3], n: [f32; 3], uv: [f32; 2]) -> u32 {
        self.positions.push(p);
        self.normals.push(n);
        self.uvs.push(uv);
        self.positions.len() as u32 - 1
    }

    /// The rectangle `centre ± u ± v` facing `normal` (= `u × v` normalised),
    /// its texture `uv_scale` times across.
    fn quad(&mut self, centre: [f32; 3], u: [f32; 3], v: [f32; 3], normal: [f32; 3], uv_scale: [f32; 2]) {
        let [su, sv] = uv_scale;
        let a = self.vertex(sub(sub(centre, u), v), normal, [0.0, sv]);
        self.vertex(sub(add(centre, u), v), normal, [su, sv]);
        self.vertex(add(add(centre, u), v), normal, [su, 0.0]);
        self.vertex(add(sub(centre, u), v), normal, [0.0, 0.0]);
        self.indices.extend([a, a + 1, a + 2, a, a + 2, a + 3]);
    }

    /// A `size` square at y = 0 facing +Y, its texture repeated `tiles` times across.
    fn ground(size: f32, tiles: f32) -> Self {
        let mut g = Geometry::default();
        let h = size / 2.0;
        g.quad([0.0; 3], [h, 0.0, 0.0], [0.0, 0.0, -h], [0.0, 1.0, 0.0], [tiles, tiles]);
        g
    }

    /// A box of `size` around `centre`; without its bottom face when `open_bottom`.
    fn cuboid(size: [f32; 3], centre: [f32; 3], open_bottom: bool) -> Self {
        let mut g = Geometry::default();
        let [x, y, z] = size.map(|s| s / 2.0);
        let faces = [
            ([x, 0.0, 0.0], [0.0, 0.0, -z], [0.0, y, 0.0], [1.0, 0.0, 0.0]),
            ([-x, 0.0, 0.0], [0.0, 0.0, z], [0.0, y, 0.0], [-1.0, 0.0, 0.0]),
            ([0.0, y, 0.0], [x, 0.0, 0.0], [0.0, 0.0, -z], [0.0, 1.0, 0.0]),
            ([0.0, -y, 0.0], [x, 0.0, 0.0], [0.0, 0.0, z], [0.0, -1.0, 0.0]),
            ([0.0, 0.0, z], [x, 0.0, 0.0], [0.0, y, 0.0], [0.0, 0.0, 1.0]),
            ([0.0, 0.0, -z], [-x, 0.0, 0.0], [0.0, y, 0.0], [0.0, 0.0, -1.0]),
        ];
        for (offset, u, v, n) in faces {
            if !(open_bottom && n[1] < 0.0) {
                g.quad(add(centre, offset), u, v, n, [1.0, 1.0]);
            }
        }
        g
    }

    /// A 12-sided solid of revolution about +Y through `profile`'s
    /// `[radius, height]` points (bottom to top), closed by flat caps; the top
    /// cap's centre is `(0, top height, 0)`.
    fn lathe(profile: &[[f32; 2]]) -> Self {
        let mut g = Geometry::default();
        let last = profile.len() - 1;
        for (j, &[r, y]) in profile.iter().enumerate() {
            // The side's normal from the profile's slope at this ring.
            let ([r0, y0], [r1, y1]) = (profile[j.saturating_sub(1)], profile[(j + 1).min(last)]);
            let (dr, dy) = (r1 - r0, y1 - y0);
            let len = (dr * dr + dy * dy).sqrt();
            let (nr, ny) = (dy / len, -dr / len);
            for k in 0..=12 {
                let [c, s] = CIRCLE_12[k % 12];
                g.vertex([r * c, y, r * s], [nr * c, ny, nr * s], [k as f32 / 12.0, 1.0 - j as f32 / last as f32]);
            }
        }
        for j in 0..last as u32 {
            for k in 0..12 {
                let (a, b) = (j * 13 + k, j * 13 + k + 1);
                let (c, d) = (b + 13, a + 13);
                g.indices.extend([a, d, c, a, c, b]);
            }
        }
        for (&[r, y], up) in [(&profile[0], false), (&profile[last], true)] {
            let n = [0.0, if up { 1.0 } else { -1.0 }, 0.0];
            let centre = g.vertex([0.0, y, 0.0], n, [0.5, 0.5]);
            for [c, s] in CIRCLE_12 {
                g.vertex([r * c, y, r * s], n, [0.5 + 0.5 * c, 0.5 + 0.5 * s]);
            }
            for k in 0..12 {
                let (a, b) = (centre + 1 + k, centre + 1 + (k + 1) % 12);
                g.indices.extend(if up { [centre, b, a] } else { [centre, a, b] });
            }
        }
        g
    }
}

/// The arm: a `2·half`-square bar through `rings` (heights, bottom to top),
/// with capped ends, and each vertex's joints and weights: wholly its nearest
/// joint's, blended linearly over ±0.2 m around the elbow and the wrist.
fn arm_geometry(rings: &[f32], half: f32) -> (Geometry, Vec<[u8; 4]>, Vec<[f32; 4]>) {
    let mut g = Geometry::default();
    // Each side's outward normal and its horizontal direction `t` (t × up = normal).
    let sides = [
        ([1.0, 0.0, 0.0], [0.0, 0.0, -1.0]),
        ([-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
        ([0.0, 0.0, 1.0], [1.0, 0.0, 0.0]),
        ([0.0, 0.0, -1.0], [-1.0, 0.0, 0.0]),
    ];
    let last = rings.len() - 1;
    for (n, t) in sides {
        let first = g.positions.len() as u32;
        for (j, &y) in rings.iter().enumerate() {
            for e in [-1.0f32, 1.0] {
                let p = [half * (n[0] + e * t[0]), y, half * (n[2] + e * t[2])];
                g.vertex(p, n, [(e + 1.0) / 2.0, 1.0 - j as f32 / last as f32]);
            }
        }
        for j in 0..last as u32 {
            let a = first + 2 * j;
            g.indices.extend([a, a + 1, a + 3, a, a + 3, a + 2]);
        }
    }
    let (bottom, top) = (rings[0], rings[last]);
    g.quad([0.0, top, 0.0], [half, 0.0, 0.0], [0.0, 0.0, -half], [0.0, 1.0, 0.0], [1.0, 1.0]);
    g.quad([0.0, bottom, 0.0], [half, 0.0, 0.0], [0.0, 0.0, half], [0.0, -1.0, 0.0], [1.0, 1.0]);
    let [_, elbow, wrist] = ARM_JOINT_HEIGHTS;
    let skin = |y: f32| -> ([u8; 4], [f32; 4]) {
        let blend = |from: u8, centre: f32| {
            let t = (y - (centre - 0.2)) / 0.4;
            ([from, from + 1, 0, 0], [1.0 - t, t, 0.0, 0.0])
        };
        if y <= elbow - 0.2 {
            ([0; 4], [1.0, 0.0, 0.0, 0.0])
        } else if y < elbow + 0.2 {
            blend(0, elbow)
        } else if y <= wrist - 0.2 {
            ([1, 0, 0, 0], [1.0, 0.0, 0.0, 0.0])
        } else if y < wrist + 0.2 {
            blend(1, wrist)
        } else {
            ([2, 0, 0, 0], [1.0, 0.0, 0.0, 0.0])
        }
    };
    let (joints, weights) = g.positions.iter().map(|p| skin(p[1])).unzip();
    (g, joints, weights)
}

/// A 1 m box standing on y = 0, its top face a 4 × 4 grid of 0.25 m cells
/// (so a morph target can raise its middle).
fn blob_geometry() -> Geometry {
    let mut g = Geometry::default();
    for j in 0..=4 {
        for i in 0..=4 {
            let (u, v) = (i as f32 / 4.0, j as f32 / 4.0);
            g.vertex([u - 0.5, 1.0, v - 0.5], [0.0, 1.0, 0.0], [u, v]);
        }
    }
    for j in 0..4 {
        for i in 0..4 {
            let a = j * 5 + i;
            // Seen from above, +X right and +Z towards the viewer: a, a+5, a+6 turns counter-clockwise.
            g.indices.extend([a, a + 5, a + 6, a, a + 6, a + 1]);
        }
    }
    let sides = Geometry::cuboid([1.0, 1.0, 1.0], [0.0, 0.5, 0.0], false);
    for (f, face) in sides.indices.chunks(6).enumerate() {
        // The cuboid's third face is its top, replaced by the grid.
        if f == 2 {
            continue;
        }
        let first = g.positions.len() as u32;
        let base = face[0] as usize;
        for k in base..base + 4 {
            g.vertex(sides.positions[k], sides.normals[k], sides.uvs[k]);
        }
        g.indices.extend([first, first + 1, first + 2, first, first + 2, first + 3]);
    }
    g
}

// ---------------------------------------------------------------------------
// Procedural textures, as PNG.

fn png_bytes(size: u32, color: png::ColorType, data: &[u8]) -> Result<Vec<u8>, LabError> {
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, size, size);
    encoder.set_color(color);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(png::Compression::High);
    let mut writer = encoder.write_header().map_err(|e| LabError::Png(e.to_string()))?;
    writer.write_image_data(data).map_err(|e| LabError::Png(e.to_string()))?;
    writer.finish().map_err(|e| LabError::Png(e.to_string()))?;
    Ok(out)
}

/// A `size`² RGB checkerboard of `cell`-texel squares.
fn checker_png(size: u32, cell: u32, a: [u8; 3], b: [u8; 3]) -> Result<Vec<u8>, LabError> {
    let data: Vec<u8> = (0..size * size)
        .flat_map(|i| if ((i % size) / cell + (i / size) / cell).is_multiple_of(2) { a } else { b })
        .collect();
    png_bytes(size, png::ColorType::Rgb, &data)
}

/// A `size`² RGB wood grain: wavy bands of four shades along the texture's v.
fn wood_png(size: u32) -> Result<Vec<u8>, LabError> {
    const SHADES: [u32; 4] = [100, 90, 82, 94];
    let data: Vec<u8> = (0..size * size)
        .flat_map(|i| {
            let (x, y) = (i % size, i / size);
            let grain = x + (y * y * 5 + y * 3) % 7 + (y / 9) % 3;
            let shade = SHADES[((grain / 4) % 4) as usize];
            [158u32, 108, 64].map(|c| (c * shade / 100) as u8)
        })
        .collect();
    png_bytes(size, png::ColorType::Rgb, &data)
}

/// A `size`² RGBA leaf, tip at the top (v = 0) and stem at the bottom: its
/// alpha is the core's [`shadow_fins::shapes::leaf_alpha`] (the blade and
/// stem opaque, three round holes), which the core's `leaf-cards` scene
/// cuts with too; a darker midrib. The RGB outside is the leaf's green, so
/// filtering leaves no fringe.
fn leaf_png(size: u32) -> Result<Vec<u8>, LabError> {
    let alpha = shadow_fins::shapes::leaf_alpha(size);
    let data: Vec<u8> = (0..size * size)
        .flat_map(|i| {
            let (u, v) = (((i % size) as f32 + 0.5) / size as f32, ((i / size) as f32 + 0.5) / size as f32);
            let (x, s) = ((u - 0.5) * 2.0, (v - 0.05) / 0.85);
            let rib = x.abs() < 0.04 && s > 0.05;
            let [r, g, b] = if rib { [48, 96, 30] } else { [70 + ((i * 7) % 13) as u8, 132, 44] };
            [r, g, b, alpha[i as usize]]
        })
        .collect();
    png_bytes(size, png::ColorType::Rgba, &data)
}

/// Standard base64 with padding: the core's, which writes every other glTF here.
use shadow_fins::gltf_import::base64_encode as base64;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_the_rfc_4648_examples() {
        let cases =
            [("", ""), ("f", "Zg=="), ("fo", "Zm8="), ("foo", "Zm9v"), ("foob", "Zm9vYg=="), ("foobar", "Zm9vYmFy")];
        for (plain, encoded) in cases {
            assert_eq!(base64(plain.as_bytes()), encoded);
        }
    }

    #[test]
    fn look_at_turns_minus_z_towards_the_target() {
        for (eye, target) in
            [([3.0, 6.0, 2.0], [0.4, 0.88, -0.3]), ([0.0, 5.0, 0.0], [0.0, 0.0, 1.0]), ([1.0; 3], [-4.0, 1.0, 1.0])]
        {
            let [x, y, z, w] = look_at(eye, target).map(|c| c as f64);
            // −Z rotated by the quaternion: −(third column of its matrix).
            let forward = [-2.0 * (x * z + w * y), -2.0 * (y * z - w * x), -(1.0 - 2.0 * (x * x + y * y))];
            let d = normalize(std::array::from_fn(|i| target[i] as f64 - eye[i] as f64));
            let dot: f64 = (0..3).map(|i| forward[i] * d[i]).sum();
            assert!(dot > 1.0 - 1e-6, "{eye:?} → {target:?}: forward {forward:?}, wanted {d:?}");
        }
    }

    #[test]
    fn primitives_face_outward() {
        // Every triangle's winding normal agrees with its vertices' normals.
        let shapes = [
            Geometry::cuboid([1.0, 2.0, 3.0], [0.5, 0.0, 0.0], true),
            Geometry::lathe(&[[0.07, 0.0], [0.11, 0.07], [0.12, 0.15], [0.05, 0.3]]),
            Geometry::ground(4.0, 2.0),
            arm_geometry(&[0.2, 0.5, 0.8], 0.1).0,
            blob_geometry(),
        ];
        for (s, g) in shapes.iter().enumerate() {
            for t in g.indices.chunks(3) {
                let [a, b, c] = [0, 1, 2].map(|k| g.positions[t[k] as usize]);
                let w = cross(sub(b, a).map(f64::from), sub(c, a).map(f64::from));
                let n = g.normals[t[0] as usize];
                let dot: f64 = (0..3).map(|i| w[i] * n[i] as f64).sum();
                assert!(dot > 0.0, "shape {s}: triangle {t:?} faces away from its normal {n:?}");
            }
        }
    }
}
