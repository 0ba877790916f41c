//! Every record the plugin hands the GPU has a Rust struct and a WGSL struct,
//! and many constants are written on both sides (issue 38, item 2). Until
//! they are defined once, these tests check each pair: a Rust record's
//! 32-bit words (their offsets and whether each is an `f32`, a `u32`, an
//! `i32` or padding) must be its WGSL twin's under WGSL's host-shareable
//! layout rules, and each twinned constant must have one value.
//!
//! The WGSL is read as the plugin embeds it (`src/render/shaders`), with a
//! small parser for what those files use: `const` declarations with integer
//! literals, and `struct`s of scalars, vectors, matrices, fixed arrays and
//! other structs.

use std::collections::HashMap;

/// One 32-bit word of a record.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Word {
    F32,
    U32,
    I32,
    Pad,
}

/// The words a Rust field type occupies, in order (no padding inside: the
/// records are `#[repr(C)]` of 4-byte scalars and arrays of them).
trait RustWords {
    fn words() -> Vec<Word>;
}

impl RustWords for f32 {
    fn words() -> Vec<Word> {
        vec![Word::F32]
    }
}

impl RustWords for u32 {
    fn words() -> Vec<Word> {
        vec![Word::U32]
    }
}

impl RustWords for i32 {
    fn words() -> Vec<Word> {
        vec![Word::I32]
    }
}

impl<T: RustWords, const N: usize> RustWords for [T; N] {
    fn words() -> Vec<Word> {
        (0..N).flat_map(|_| T::words()).collect()
    }
}

/// The words of a `#[repr(C)]` struct, from its listed fields' offsets;
/// a word no listed field covers is padding (so a field left out of the
/// list shows up as a mismatch, not as a pass).
macro_rules! rust_record {
    ($ty:ty { $($field:ident),* $(,)? }) => {
        impl RustWords for $ty {
            fn words() -> Vec<Word> {
                let mut words = vec![Word::Pad; size_of::<$ty>() / 4];
                $(
                    let at = std::mem::offset_of!($ty, $field) / 4;
                    let field = field_words(|r: &$ty| &r.$field);
                    for (k, w) in field.into_iter().enumerate() {
                        assert_eq!(words[at + k], Word::Pad, "{}.{} overlaps another field", stringify!($ty), stringify!($field));
                        words[at + k] = w;
                    }
                )*
                words
            }
        }
    };
}

fn field_words<R, F: RustWords>(_: fn(&R) -> &F) -> Vec<Word> {
    F::words()
}

use super::{
    composite::{CompositeLight, CompositeLights, FinLightUniform},
    convolution::ConvolutionUniform,
    coverage::CoverageParams,
    extraction::ExtractParams,
    params::FinParams,
    view::FinViewUniform,
};
use crate::{
    casters::gpu_scene::GpuInstance,
    frame::{
        coverage::{GpuCoverageEdge, GpuCoverageFace},
        plateaus::{GpuSheet, PlateauUniform},
    },
    gpu_layout::{GpuCaster, GpuCutout, GpuFin},
};

rust_record!(GpuCaster { corners, normal, offset, min_depth, max_depth, layer, cutout, patch_id });
rust_record!(GpuCutout { uvs, depths, mask });
rust_record!(GpuFin { header, data });
rust_record!(GpuInstance { linear, translation, normal, light, ids, info, pose });
rust_record!(GpuSheet { ends, radii, to_axes });
rust_record!(PlateauUniform { point, normal, axis_u, axis_v, grid, dims });
rust_record!(GpuCoverageEdge { a, b, third0, third1, segment });
rust_record!(GpuCoverageFace { a, b, c });
rust_record!(ConvolutionUniform { counts, series, kernel, lookup, levels, empty });
rust_record!(FinLightUniform { position_radius, forward_inverse_square_range, color });
rust_record!(CompositeLight { own, info });
rust_record!(CompositeLights { count, lights });
rust_record!(FinViewUniform { linear, translation });
rust_record!(CoverageParams { lists, counts, light, grid, info, axis_u, axis_v, axis_n });
rust_record!(ExtractParams {
    totals,
    layering,
    capacity,
    light,
    flags,
    origin,
    axis_u,
    axis_v,
    axis_n,
    window,
    aperture
});
rust_record!(FinParams { map, counts, light, flags, origin, axis_u, axis_v, axis_n, redraw, tiles });

/// The shaders' text by file name, comments removed.
fn shaders() -> HashMap<String, String> {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src/render/shaders");
    std::fs::read_dir(&dir)
        .expect("src/render/shaders")
        .map(|e| {
            let path = e.expect("entry").path();
            let text = std::fs::read_to_string(&path).expect("a shader");
            let code = text.lines().map(|l| l.split("//").next().unwrap_or("")).collect::<Vec<_>>().join("\n");
            (path.file_name().unwrap().to_string_lossy().into_owned(), code)
        })
        .collect()
}

/// An integer literal as WGSL writes it (`16u`, `0xffffffffu`, `3`, `-1i`).
fn integer(literal: &str) -> Option<i64> {
    let s = literal.trim().trim_end_matches(['u', 'i']);
    match s.strip_prefix("0x") {
        Some(hex) => i64::from_str_radix(hex, 16).ok(),
        None => s.parse().ok(),
    }
}

/// A file's `const NAME[: type] = <integer literal>;` declarations.
fn constants(code: &str) -> HashMap<String, i64> {
    let mut out = HashMap::new();
    for line in code.lines() {
        let Some(rest) = line.trim().strip_prefix("const ") else { continue };
        let Some((name, value)) = rest.split_once('=') else { continue };
        let name = name.split(':').next().unwrap_or("").trim();
        if let Some(v) = integer(value.trim().trim_end_matches(';')) {
            out.insert(name.to_owned(), v);
        }
    }
    out
}

/// Every `struct Name { field: type, … }` of all the shaders: its fields'
/// types as written.
fn structs(shaders: &HashMap<String, String>) -> HashMap<String, Vec<String>> {
    let mut out = HashMap::new();
    for code in shaders.values() {
        let code = format!("\n{code}");
        let mut rest = code.as_str();
        while let Some(at) = rest.find("\nstruct ") {
            let after = &rest[at + 8..];
            let (Some(open), Some(close)) = (after.find('{'), after.find('}')) else { break };
            let name = after[..open].trim();
            let body = &after[open + 1..close];
            let fields = split_top_level(body)
                .into_iter()
                .filter_map(|f| f.split_once(':').map(|(_, ty)| ty.trim().to_owned()))
                .filter(|ty| !ty.is_empty())
                .collect();
            out.insert(name.to_owned(), fields);
            rest = &after[close + 1..];
        }
    }
    out
}

/// Splits at commas outside `<…>`.
fn split_top_level(s: &str) -> Vec<&str> {
    let (mut depth, mut start, mut parts) = (0, 0, vec![]);
    for (i, c) in s.char_indices() {
        match c {
            '<' => depth += 1,
            '>' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(s[start..i].trim());
                start = i + 1;
            }
            _ => {}
        }
    }
    parts.push(s[start..].trim());
    parts.into_iter().filter(|p| !p.is_empty()).collect()
}

/// A WGSL type's words (padding inside included) and alignment in words,
/// under the host-shareable layout rules (WGSL §14.4: `vec3` aligns to 16
/// bytes, an array's stride is its element's size rounded up to its
/// alignment, a struct's size is rounded up to its largest alignment).
fn wgsl_words(ty: &str, structs: &HashMap<String, Vec<String>>, consts: &HashMap<String, i64>) -> (Vec<Word>, usize) {
    let ty = ty.trim();
    let scalar = |s: &str| match s.trim() {
        "f32" => Word::F32,
        "u32" | "atomic<u32>" => Word::U32,
        "i32" | "atomic<i32>" => Word::I32,
        other => panic!("unsupported scalar {other}"),
    };
    if let Some(inner) = ty.strip_prefix("array<").and_then(|t| t.strip_suffix('>')) {
        let parts = split_top_level(inner);
        assert_eq!(parts.len(), 2, "a runtime-sized array in a checked record: {ty}");
        let count = integer(parts[1])
            .or_else(|| consts.get(parts[1]).copied())
            .unwrap_or_else(|| panic!("array count {} unknown", parts[1])) as usize;
        let (element, align) = wgsl_words(parts[0], structs, consts);
        let stride = element.len().div_ceil(align) * align;
        let mut words = vec![];
        for _ in 0..count {
            words.extend(&element);
            words.resize(words.len() + stride - element.len(), Word::Pad);
        }
        return (words, align);
    }
    for (n, align) in [(2usize, 2usize), (3, 4), (4, 4)] {
        if let Some(inner) = ty.strip_prefix(&format!("vec{n}<")).and_then(|t| t.strip_suffix('>')) {
            return (vec![scalar(inner); n], align);
        }
    }
    if let Some(inner) = ty.strip_prefix("mat4x4<").and_then(|t| t.strip_suffix('>')) {
        return (vec![scalar(inner); 16], 4);
    }
    if let Some(fields) = structs.get(ty) {
        let (mut words, mut largest) = (vec![], 1);
        for field in fields {
            let (w, align) = wgsl_words(field, structs, consts);
            words.resize(words.len().div_ceil(align) * align, Word::Pad);
            words.extend(w);
            largest = largest.max(align);
        }
        words.resize(words.len().div_ceil(largest) * largest, Word::Pad);
        return (words, largest);
    }
    (vec![scalar(ty)], 1)
}

#[test]
fn every_rust_record_has_the_words_of_its_wgsl_twin() {
    let shaders = shaders();
    let structs = structs(&shaders);
    let consts: HashMap<String, i64> = shaders.values().flat_map(|c| constants(c)).collect();
    let twins: [(&str, Vec<Word>, &str); 16] = [
        ("GpuCaster", GpuCaster::words(), "Caster"),
        ("GpuCutout", GpuCutout::words(), "CasterCutout"),
        ("GpuFin", GpuFin::words(), "Fin"),
        ("GpuInstance", GpuInstance::words(), "Instance"),
        ("GpuSheet", GpuSheet::words(), "Sheet"),
        ("PlateauUniform", PlateauUniform::words(), "PlateauParams"),
        ("GpuCoverageEdge", GpuCoverageEdge::words(), "Edge"),
        ("GpuCoverageFace", GpuCoverageFace::words(), "Face"),
        ("ConvolutionUniform", ConvolutionUniform::words(), "ConvolutionParams"),
        ("FinLightUniform", FinLightUniform::words(), "FinLightUniform"),
        ("CompositeLight", CompositeLight::words(), "CompositeLight"),
        ("CompositeLights", CompositeLights::words(), "CompositeLights"),
        ("FinViewUniform", FinViewUniform::words(), "FinView"),
        ("CoverageParams", CoverageParams::words(), "CoverageParams"),
        ("ExtractParams", ExtractParams::words(), "ExtractParams"),
        ("FinParams", FinParams::words(), "FinParams"),
    ];
    for (rust, words, wgsl) in twins {
        assert!(structs.contains_key(wgsl), "no WGSL struct {wgsl}");
        let (wgsl_words, _) = wgsl_words(wgsl, &structs, &consts);
        assert_eq!(words, wgsl_words, "{rust} (Rust) and {wgsl} (WGSL) disagree");
    }
}

/// The parser itself: a record that is known to differ is found to differ.
#[test]
fn the_layout_check_sees_a_vec3s_alignment_and_a_missing_field() {
    let code = "struct A { x: f32, v: vec3<f32>, n: array<u32, 2>, }\nstruct B { a: A, m: u32 }".to_owned();
    let structs = structs(&HashMap::from([("t.wgsl".to_owned(), code)]));
    let (a, align) = wgsl_words("A", &structs, &HashMap::new());
    use Word::*;
    assert_eq!(align, 4);
    assert_eq!(a, vec![F32, Pad, Pad, Pad, F32, F32, F32, U32, U32, Pad, Pad, Pad]);
    let (b, _) = wgsl_words("B", &structs, &HashMap::new());
    assert_eq!(b.len(), 16);
    assert_eq!(b[12], U32);
    // A Rust record missing a field: its word stays padding.
    #[repr(C)]
    #[allow(dead_code)]
    struct Two {
        x: f32,
        y: u32,
    }
    rust_record!(Two { y });
    assert_eq!(Two::words(), vec![Pad, U32]);
}

/// Constants written both in Rust and in WGSL have one value. (Two WGSL
/// files may use a name for different things: `pose.wgsl`'s `FACE_WORDS`
/// and `VERTEX_WORDS` are words of the packed geometry, `extract_common`'s
/// words of the extraction's state, so each is checked in its own file.)
#[test]
fn every_twinned_constant_has_one_value() {
    use super::{composite as c, coverage as cov, extraction as x, params as p};
    use crate::{casters::gpu_geometry as g, frame as f};
    let shaders = shaders();
    let file = |name: &str| constants(&shaders[name]);
    let (common, pose, composite) = (file("extract_common.wgsl"), file("pose.wgsl"), file("composite_types.wgsl"));
    let (plateaus, fin_types) = (file("plateaus.wgsl"), file("fin_types.wgsl"));
    let (coverage, maps) = (file("coverage_types.wgsl"), file("maps.wgsl"));
    let checks: Vec<(&str, &HashMap<String, i64>, i64)> = vec![
        ("C_ARGS_CASTERS", &common, x::C_ARGS_CASTERS as i64),
        ("C_ARGS_CASTER_THREADS", &common, x::C_ARGS_CASTER_THREADS as i64),
        ("C_ARGS_CLEAR", &common, x::C_ARGS_CLEAR as i64),
        ("C_ARGS_FINS", &common, x::C_ARGS_FINS as i64),
        ("C_ARGS_FIN_THREADS", &common, x::C_ARGS_FIN_THREADS as i64),
        ("C_ARGS_ITEMS", &common, x::C_ARGS_ITEMS as i64),
        ("C_ARGS_RETIRE", &common, x::C_ARGS_RETIRE as i64),
        ("C_ARGS_SILHOUETTES", &common, x::C_ARGS_SILHOUETTES as i64),
        ("C_HISTOGRAM", &common, x::C_HISTOGRAM as i64),
        ("C_PARAMS", &common, x::C_PARAMS as i64),
        ("C_PARTIAL", &common, x::C_PARTIAL as i64),
        ("C_REDRAWN", &common, x::C_REDRAWN as i64),
        ("DIRTY_WORDS", &common, x::DIRTY_WORDS as i64),
        ("H_DIRTY_COUNT", &common, x::H_DIRTY_COUNT as i64),
        ("H_INCREMENTAL", &common, x::H_INCREMENTAL as i64),
        ("H_INSTANCES", &common, x::H_INSTANCES as i64),
        ("H_TILES", &common, x::H_TILES as i64),
        ("INSTANCE_WORDS", &common, x::INSTANCE_WORDS as i64),
        ("FACE_WORDS", &common, x::FACE_WORDS as i64),
        ("VERTEX_WORDS", &common, x::VERTEX_WORDS as i64),
        ("FULL", &common, x::FULL as i64),
        ("WORKGROUP", &common, x::WORKGROUP as i64),
        ("EDGE_FORWARD_FIRST", &common, g::EDGE_FORWARD_FIRST as i64),
        ("EDGE_FORWARD_SECOND", &common, g::EDGE_FORWARD_SECOND as i64),
        ("EDGE_CREASE", &common, g::EDGE_CREASE as i64),
        ("EDGE_CREASE", &pose, g::EDGE_CREASE as i64),
        ("EDGE_NON_MANIFOLD", &common, g::EDGE_NON_MANIFOLD as i64),
        ("EDGE_NON_MANIFOLD", &pose, g::EDGE_NON_MANIFOLD as i64),
        ("EDGE_PATCH_ONLY", &common, g::EDGE_PATCH_ONLY as i64),
        ("EDGE_OUTLINE", &common, g::EDGE_OUTLINE as i64),
        ("G_FACE_UVS_AT", &common, g::G_FACE_UVS_AT as i64),
        ("G_MESH_VERTICES", &pose, g::G_MESH_VERTICES as i64),
        ("G_MORPH_TARGETS", &pose, g::G_MORPH_TARGETS as i64),
        ("G_POSE_AT", &pose, g::G_POSE_AT as i64),
        ("POSE_VERTEX_WORDS", &pose, g::POSE_VERTEX_WORDS as i64),
        ("KIND_OWN", &composite, c::KIND_OWN as i64),
        ("KIND_BEVY", &composite, c::KIND_BEVY as i64),
        ("KIND_BEVY_DIRECTIONAL", &composite, c::KIND_BEVY_DIRECTIONAL as i64),
        ("KIND_BEVY_RECT", &composite, c::KIND_BEVY_RECT as i64),
        ("MAX_FIN_LIGHTS", &composite, f::MAX_FIN_LIGHTS as i64),
        ("MAX_CELL_SHEETS", &plateaus, f::plateaus::MAX_CELL_SHEETS as i64),
        ("TILE", &fin_types, f::map_tiles::TILE as i64),
        ("WORKGROUP", &coverage, cov::WORKGROUP as i64),
        ("WORKGROUP", &maps, p::WORKGROUP as i64),
        ("WORKGROUP", &pose, x::WORKGROUP as i64),
    ];
    for (name, wgsl, rust) in checks {
        assert_eq!(wgsl.get(name).copied(), Some(rust), "{name}: WGSL and Rust disagree");
    }
    // Names both files share mean the same, but for the two above.
    for (name, v) in &pose {
        if let Some(w) = common.get(name).filter(|_| !matches!(name.as_str(), "FACE_WORDS" | "VERTEX_WORDS")) {
            assert_eq!(v, w, "{name}: pose.wgsl and extract_common.wgsl disagree");
        }
    }
}
