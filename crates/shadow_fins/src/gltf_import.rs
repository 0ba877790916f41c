//! glTF 2.0 (`.gltf` with embedded or side-by-side buffers, or `.glb`) into a
//! [`Scene`], and a minimal writer for our own demo assets.
//!
//! Every triangle primitive of the default scene becomes one [`SceneObject`]
//! with its node's world transform. A primitive that cannot be used (NaN
//! positions, out-of-range indices, no area) is skipped and reported in
//! [`GltfImport::skipped`] with its typed error, so one broken mesh does not
//! lose the rest of the file; a file with no usable mesh is an error.
//!
//! Hostile files (fuzzed: `fuzz/`, and the corpus test in the suite) get a
//! typed error, never a panic, a hang or an allocation the file's own bytes do
//! not pay for: buffers are capped at [`MAX_BUFFER_BYTES`] before anything is
//! read, every accessor is checked against its buffer (type, stride, range,
//! count) before the `gltf` crate's readers touch it, the element count of the
//! whole file is capped at [`MAX_ELEMENTS`] (and at four per byte of input,
//! for sparse accessors whose zeros take no bytes), each buffer source and
//! each primitive is read once however many buffers or nodes name it, and the
//! node graph is walked with each node visited once, so a child cycle cannot
//! loop.

use std::path::Path;

use std::{collections::HashMap, sync::Arc};

use glam::{Affine3A, Mat4, Vec3};
use gltf::mesh::Mode;

use crate::{
    error::{GltfError, MeshError},
    mesh::{Mesh, Topology},
    scene::{Scene, SceneObject},
};

/// The result of an import.
#[derive(Debug)]
pub struct GltfImport {
    pub scene: Scene,
    /// The glTF scene read: the file's default scene, else its first; `None`
    /// when it has no scene (then every node is read). Bevy's loader must be
    /// asked for the same one (`GltfAssetLabel::Scene(index)`).
    pub scene_index: Option<usize>,
    /// Primitives that were skipped, with why.
    pub skipped: Vec<GltfError>,
}

/// Reads a glTF or GLB file. External buffers are resolved next to the file.
pub fn load_gltf(path: impl AsRef<Path>) -> Result<GltfImport, GltfError> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|source| GltfError::Io { path: path.display().to_string(), source })?;
    parse_gltf(&bytes, path.parent())
}

/// The largest buffer a file may declare or bring (1 GiB).
pub const MAX_BUFFER_BYTES: u64 = 1 << 30;
/// The most vertices and indices, all primitives together, a file may ask for.
pub const MAX_ELEMENTS: u64 = 1 << 27;

/// Parses glTF/GLB bytes; `base_dir` resolves external buffer files.
pub fn parse_gltf(bytes: &[u8], base_dir: Option<&Path>) -> Result<GltfImport, GltfError> {
    let gltf = parse_document(bytes)?;
    let buffers = read_buffers(&gltf, base_dir)?;
    let buffer_bytes = buffers.distinct_bytes;
    // Elements not backed by bytes (sparse accessors without a buffer view
    // are zeros but for their sparse values) are bounded by the input's size.
    let element_limit = MAX_ELEMENTS.min(4 * (bytes.len() as u64 + buffer_bytes) + 1024);

    let mut objects = Vec::new();
    let mut skipped = Vec::new();
    let scene = gltf.default_scene().or_else(|| gltf.scenes().next());
    let scene_index = scene.as_ref().map(|s| s.index());
    let roots: Vec<gltf::Node> = match &scene {
        Some(s) => s.nodes().collect(),
        None => gltf.nodes().collect(),
    };
    let mut stack: Vec<(gltf::Node, Mat4)> = roots.into_iter().map(|n| (n, Mat4::IDENTITY)).collect();
    // A valid file's nodes form a forest: each is reached once. A damaged one
    // may list a node as its own descendant; visiting each node once ends that.
    let mut visited = vec![false; gltf.nodes().len()];
    // Each primitive is read once, however many nodes instance it.
    // (A broken one is reported once and skipped at every node.)
    let mut read: HashMap<(usize, usize), Option<(Arc<Mesh>, Arc<Topology>)>> = HashMap::new();
    let mut elements = 0u64;
    while let Some((node, parent)) = stack.pop() {
        if std::mem::replace(&mut visited[node.index()], true) {
            continue;
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        stack.extend(node.children().map(|c| (c, world)));
        let Some(mesh) = node.mesh() else { continue };
        let mesh_name = mesh.name().unwrap_or("unnamed").to_string();
        for (pi, prim) in mesh.primitives().enumerate() {
            if !matches!(prim.mode(), Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
                continue; // Points and lines cast no shadow.
            }
            let key = (mesh.index(), pi);
            if !read.contains_key(&key) {
                let result = match read_primitive(&prim, &mesh_name, pi, &buffers.data, &mut elements, element_limit) {
                    Ok(m) => Some(m),
                    Err(e @ GltfError::TooLarge { .. }) => return Err(e),
                    Err(e) => {
                        skipped.push(e);
                        None
                    }
                };
                read.insert(key, result);
            }
            if let Some((mesh, topology)) = &read[&key] {
                let placed =
                    SceneObject::shared(mesh_name.clone(), mesh.clone(), topology.clone(), Affine3A::from_mat4(world));
                match placed {
                    Ok(o) => objects.push(o),
                    Err(source) => skipped.push(GltfError::Mesh { mesh: mesh_name.clone(), primitive: pi, source }),
                }
            }
        }
    }
    if objects.is_empty() {
        return Err(skipped.into_iter().next().unwrap_or(GltfError::NoMeshes));
    }
    Ok(GltfImport { scene: Scene::new(objects), scene_index, skipped })
}

/// The file's buffers, each source read once (the GLB blob and every
/// external file are shared by the buffers naming them).
struct Buffers {
    data: Vec<Arc<Vec<u8>>>,
    /// Bytes of the distinct sources, capped at [`MAX_BUFFER_BYTES`] in all.
    distinct_bytes: u64,
}

fn read_buffers(gltf: &gltf::Gltf, base_dir: Option<&Path>) -> Result<Buffers, GltfError> {
    let blob = gltf.blob.clone().map(Arc::new);
    let mut files: HashMap<String, Arc<Vec<u8>>> = HashMap::new();
    let (mut data, mut distinct_bytes) = (Vec::new(), blob.as_ref().map_or(0, |b| b.len() as u64));
    for buffer in gltf.buffers() {
        let index = buffer.index();
        let too_large =
            |amount: u64| GltfError::TooLarge { what: format!("buffer {index}"), amount, limit: MAX_BUFFER_BYTES };
        if buffer.length() as u64 > MAX_BUFFER_BYTES {
            return Err(too_large(buffer.length() as u64));
        }
        let bytes = match buffer.source() {
            gltf::buffer::Source::Bin => {
                blob.clone().ok_or_else(|| GltfError::Buffer { index, reason: "GLB has no BIN chunk".into() })?
            }
            gltf::buffer::Source::Uri(uri) => match files.get(uri) {
                Some(b) => b.clone(),
                None => {
                    let b = Arc::new(read_uri(uri, base_dir).map_err(|reason| GltfError::Buffer { index, reason })?);
                    distinct_bytes += b.len() as u64;
                    files.insert(uri.to_string(), b.clone());
                    b
                }
            },
        };
        if distinct_bytes > MAX_BUFFER_BYTES {
            return Err(GltfError::TooLarge {
                what: "buffers in all".into(),
                amount: distinct_bytes,
                limit: MAX_BUFFER_BYTES,
            });
        }
        if bytes.len() < buffer.length() {
            return Err(GltfError::Buffer {
                index,
                reason: format!("holds {} bytes, the file declares {}", bytes.len(), buffer.length()),
            });
        }
        data.push(bytes);
    }
    Ok(Buffers { data, distinct_bytes })
}

/// One triangle primitive as a mesh, its accessors checked first.
fn read_primitive(
    prim: &gltf::Primitive,
    mesh_name: &str,
    pi: usize,
    buffers: &[Arc<Vec<u8>>],
    elements: &mut u64,
    element_limit: u64,
) -> Result<(Arc<Mesh>, Arc<Topology>), GltfError> {
    let fail = |source: MeshError| GltfError::Mesh { mesh: mesh_name.to_string(), primitive: pi, source };
    let position_accessor = prim.get(&gltf::Semantic::Positions).ok_or_else(|| fail(MeshError::Empty))?;
    *elements += check_accessor(&position_accessor, Usage::Positions, buffers)?;
    if let Some(a) = prim.indices() {
        *elements += check_accessor(&a, Usage::Indices, buffers)?;
    }
    if *elements > element_limit {
        return Err(GltfError::TooLarge { what: "mesh data".into(), amount: *elements, limit: element_limit });
    }
    let reader = prim.reader(|b| buffers.get(b.index()).map(|d| d.as_slice()));
    let positions: Vec<Vec3> = reader.read_positions().ok_or_else(|| fail(MeshError::Empty))?.map(Vec3::from).collect();
    let raw: Vec<u32> = match reader.read_indices() {
        Some(i) => i.into_u32().collect(),
        None => (0..positions.len() as u32).collect(),
    };
    let indices = match prim.mode() {
        Mode::TriangleStrip => strip_to_list(&raw),
        Mode::TriangleFan => fan_to_list(&raw),
        _ => raw,
    };
    let mesh = Mesh::new(positions, indices).map_err(fail)?;
    let topology = Topology::build(&mesh);
    Ok((Arc::new(mesh), Arc::new(topology)))
}

/// The document, validated, without the `gltf` crate's own validation
/// panicking: it indexes a primitive's `POSITION` accessor before checking the
/// index (found by fuzzing: "index out of bounds" in gltf-json's mesh.rs), so
/// every index that check reads is checked first; any other panic in the crate
/// becomes a parse error (the fuzz target still reports it, to fix upstream).
fn parse_document(bytes: &[u8]) -> Result<gltf::Gltf, GltfError> {
    let parse = |e: gltf::Error| GltfError::Parse(e.to_string());
    // The GLB reader subtracts its 12-byte header from the declared length
    // unchecked (found by fuzzing: overflow on a length below 12).
    if bytes.starts_with(b"glTF") {
        let declared = bytes.get(8..12).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
        if declared.is_none_or(|n| n < 12) {
            return Err(GltfError::Parse(format!("invalid GLB: its header declares {declared:?} bytes")));
        }
    }
    let unchecked = gltf::Gltf::from_slice_without_validation(bytes).map_err(parse)?;
    let json = unchecked.document.as_json();
    let accessors = json.accessors.len();
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            if let Some((_, a)) = primitive.attributes.iter().find(|(_, a)| a.value() >= accessors) {
                return Err(GltfError::Parse(format!(
                    "invalid glTF: meshes[{m}].primitives[{p}] names accessor {} of {accessors}",
                    a.value()
                )));
            }
        }
    }
    let blob = unchecked.blob;
    let json = unchecked.document.into_json();
    match std::panic::catch_unwind(move || gltf::Document::from_json(json)) {
        Ok(document) => Ok(gltf::Gltf { document: document.map_err(parse)?, blob }),
        Err(_) => Err(GltfError::Parse("invalid glTF: the glTF reader failed on it (a damaged file?)".into())),
    }
}

/// What an accessor is read as.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Usage {
    /// `VEC3` of `f32`, not normalised.
    Positions,
    /// `SCALAR` of `u8`, `u16` or `u32`.
    Indices,
}

/// Checks an accessor against what the `gltf` crate's readers assume (they
/// index and debug-assert rather than return errors) and against its buffer;
/// returns its element count.
fn check_accessor(a: &gltf::Accessor, usage: Usage, buffers: &[Arc<Vec<u8>>]) -> Result<u64, GltfError> {
    use gltf::accessor::{DataType, Dimensions};
    let bad = |reason: String| Err(GltfError::Accessor { index: a.index(), reason });
    let count = a.count() as u64;
    if count == 0 {
        return bad("its count is 0".into());
    }
    if count > MAX_ELEMENTS {
        return Err(GltfError::TooLarge {
            what: format!("accessor {}", a.index()),
            amount: count,
            limit: MAX_ELEMENTS,
        });
    }
    let element = match (usage, a.dimensions(), a.data_type()) {
        (Usage::Positions, Dimensions::Vec3, DataType::F32) if !a.normalized() => 12u64,
        (Usage::Indices, Dimensions::Scalar, DataType::U8) => 1,
        (Usage::Indices, Dimensions::Scalar, DataType::U16) => 2,
        (Usage::Indices, Dimensions::Scalar, DataType::U32) => 4,
        (u, d, t) => return bad(format!("{t:?} {d:?} cannot be read as {u:?}")),
    };
    // Every view the accessor reads must lie inside its buffer, and every
    // element inside its view.
    let check_view = |view: gltf::buffer::View, offset: u64, count: u64, element: u64| -> Result<(), GltfError> {
        let buffer = buffers.get(view.buffer().index()).map_or(0, |b| b.len() as u64);
        let (start, length) = (view.offset() as u64, view.length() as u64);
        if start.checked_add(length).is_none_or(|end| end > buffer) {
            return Err(GltfError::Accessor {
                index: a.index(),
                reason: format!("its buffer view ({start} + {length} bytes) overruns its {buffer}-byte buffer"),
            });
        }
        let stride = view.stride().map_or(element, |s| s as u64);
        if stride < element {
            return Err(GltfError::Accessor {
                index: a.index(),
                reason: format!("stride {stride} is shorter than its {element}-byte elements"),
            });
        }
        let end =
            (count - 1).checked_mul(stride).and_then(|x| x.checked_add(offset)).and_then(|x| x.checked_add(element));
        if end.is_none_or(|end| end > length) {
            return Err(GltfError::Accessor {
                index: a.index(),
                reason: format!("{count} elements from offset {offset} overrun its {length}-byte view"),
            });
        }
        Ok(())
    };
    match a.view() {
        Some(view) => check_view(view, a.offset() as u64, count, element)?,
        None if a.sparse().is_none() => return bad("it has neither a buffer view nor sparse values".into()),
        None => {}
    }
    if let Some(sparse) = a.sparse() {
        let n = sparse.count() as u64;
        if n == 0 || n > count {
            return bad(format!("{n} sparse values for {count} elements"));
        }
        let index_size = sparse.indices().index_type().size() as u64;
        check_view(sparse.indices().view(), sparse.indices().offset() as u64, n, index_size)?;
        check_view(sparse.values().view(), sparse.values().offset() as u64, n, element)?;
    }
    Ok(count)
}

fn strip_to_list(s: &[u32]) -> Vec<u32> {
    (2..s.len())
        .flat_map(|i| if i % 2 == 0 { [s[i - 2], s[i - 1], s[i]] } else { [s[i - 1], s[i - 2], s[i]] })
        .collect()
}

fn fan_to_list(s: &[u32]) -> Vec<u32> {
    (2..s.len()).flat_map(|i| [s[0], s[i - 1], s[i]]).collect()
}

fn read_uri(uri: &str, base_dir: Option<&Path>) -> Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, data) = rest.split_once(";base64,").ok_or("data URI is not base64")?;
        return base64_decode(data).ok_or_else(|| "data URI holds invalid base64".to_string());
    }
    let dir = base_dir.ok_or("external buffer but no directory to resolve it in")?;
    let file = dir.join(percent_decode(uri));
    let meta = std::fs::metadata(&file).map_err(|e| format!("cannot read {}: {e}", file.display()))?;
    // Not a device or a pipe: `/dev/zero` reports 0 bytes and never ends.
    if !meta.is_file() {
        return Err(format!("{} is not a regular file", file.display()));
    }
    let size = meta.len();
    if size > MAX_BUFFER_BYTES {
        return Err(format!(
            "{} is {size} bytes, more than the {MAX_BUFFER_BYTES} this importer reads",
            file.display()
        ));
    }
    std::fs::read(&file).map_err(|e| format!("cannot read {}: {e}", file.display()))
}

fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            if let Ok(v) = u8::from_str_radix(&s[i + 1..i + 3], 16) {
                out.push(v);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

fn base64_decode(s: &str) -> Option<Vec<u8>> {
    let val = |c: u8| match c {
        b'A'..=b'Z' => Some(c - b'A'),
        b'a'..=b'z' => Some(c - b'a' + 26),
        b'0'..=b'9' => Some(c - b'0' + 52),
        b'+' | b'-' => Some(62),
        b'/' | b'_' => Some(63),
        _ => None,
    };
    let mut out = Vec::with_capacity(s.len() * 3 / 4);
    let (mut acc, mut bits) = (0u32, 0);
    for &c in s.as_bytes().iter().filter(|c| !c.is_ascii_whitespace()) {
        if c == b'=' {
            break;
        }
        acc = (acc << 6) | val(c)? as u32;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
        }
    }
    Some(out)
}

/// Standard base64 with padding (RFC 4648 §4), for `data:` URIs.
pub fn base64_encode(data: &[u8]) -> String {
    const T: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::with_capacity(data.len().div_ceil(3) * 4);
    for chunk in data.chunks(3) {
        let n = chunk.iter().enumerate().fold(0u32, |a, (i, &b)| a | (b as u32) << (16 - 8 * i));
        for i in 0..4 {
            if i <= chunk.len() {
                out.push(T[(n >> (18 - 6 * i) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

/// Writes a scene as a self-contained `.gltf` (one embedded buffer, one node per
/// object with its matrix). Used to make the demo assets; materials are omitted
/// (Bevy gives such meshes its default `StandardMaterial`).
pub fn write_gltf(scene: &Scene) -> String {
    let mut bin: Vec<u8> = Vec::new();
    let (mut views, mut accessors, mut meshes, mut nodes) = (vec![], vec![], vec![], vec![]);
    for (i, o) in scene.objects.iter().enumerate() {
        let (lo, hi) =
            o.mesh.positions().iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(a, b), p| (a.min(*p), b.max(*p)));
        let pos_offset = bin.len();
        for p in o.mesh.positions() {
            for c in p.to_array() {
                bin.extend(c.to_le_bytes());
            }
        }
        let idx_offset = bin.len();
        for &k in o.mesh.indices() {
            bin.extend(k.to_le_bytes());
        }
        let (pv, iv) = (views.len(), views.len() + 1);
        views.push(format!(
            r#"{{"buffer":0,"byteOffset":{pos_offset},"byteLength":{},"target":34962}}"#,
            idx_offset - pos_offset
        ));
        views.push(format!(
            r#"{{"buffer":0,"byteOffset":{idx_offset},"byteLength":{},"target":34963}}"#,
            bin.len() - idx_offset
        ));
        let (pa, ia) = (accessors.len(), accessors.len() + 1);
        accessors.push(format!(
            r#"{{"bufferView":{pv},"componentType":5126,"count":{},"type":"VEC3","min":[{},{},{}],"max":[{},{},{}]}}"#,
            o.mesh.positions().len(),
            lo.x,
            lo.y,
            lo.z,
            hi.x,
            hi.y,
            hi.z
        ));
        accessors.push(format!(
            r#"{{"bufferView":{iv},"componentType":5125,"count":{},"type":"SCALAR"}}"#,
            o.mesh.indices().len()
        ));
        meshes.push(format!(
            r#"{{"name":"{}","primitives":[{{"attributes":{{"POSITION":{pa}}},"indices":{ia}}}]}}"#,
            json_escape(&o.name)
        ));
        let m = Mat4::from(o.transform).to_cols_array();
        let m: Vec<String> = m.iter().map(|v| format!("{v}")).collect();
        nodes.push(format!(r#"{{"name":"{}","mesh":{i},"matrix":[{}]}}"#, json_escape(&o.name), m.join(",")));
    }
    let node_ids: Vec<String> = (0..nodes.len()).map(|i| i.to_string()).collect();
    format!(
        concat!(
            r#"{{"asset":{{"version":"2.0","generator":"shadow_fins"}},"scene":0,"scenes":[{{"nodes":[{}]}}],"#,
            r#""nodes":[{}],"meshes":[{}],"accessors":[{}],"bufferViews":[{}],"#,
            r#""buffers":[{{"byteLength":{},"uri":"data:application/octet-stream;base64,{}"}}]}}"#
        ),
        node_ids.join(","),
        nodes.join(","),
        meshes.join(","),
        accessors.join(","),
        views.join(","),
        bin.len(),
        base64_encode(&bin)
    )
}

fn json_escape(s: &str) -> String {
    s.chars()
        .flat_map(|c| match c {
            '"' => vec!['\\', '"'],
            '\\' => vec!['\\', '\\'],
            c if (c as u32) < 0x20 => vec![' '],
            c => vec![c],
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_round_trips() {
        for n in 0..20 {
            let data: Vec<u8> = (0..n).map(|i| (i * 37 + 11) as u8).collect();
            assert_eq!(base64_decode(&base64_encode(&data)).unwrap(), data);
        }
    }

    #[test]
    fn strips_and_fans_become_lists() {
        assert_eq!(strip_to_list(&[0, 1, 2, 3]), vec![0, 1, 2, 2, 1, 3]);
        assert_eq!(fan_to_list(&[0, 1, 2, 3]), vec![0, 1, 2, 0, 2, 3]);
    }
}
