//! Typed errors. Every message says what was wrong and what to do about it.

use thiserror::Error;

/// A mesh that cannot be used as a shadow caster or receiver.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum MeshError {
    #[error("mesh has no triangles: give at least one triangle (three indices)")]
    Empty,
    #[error("index count {0} is not a multiple of 3: meshes must be triangle lists")]
    IndexCountNotTriangles(usize),
    #[error("index {index} at position {at} is out of range for {vertex_count} vertices")]
    IndexOutOfRange { at: usize, index: u32, vertex_count: usize },
    #[error("vertex {vertex} has a non-finite position {position:?}: remove NaN/Inf vertices before use")]
    NonFinitePosition { vertex: usize, position: [f32; 3] },
    #[error("every triangle of the mesh has zero area: nothing can cast or receive a shadow")]
    AllDegenerate,
    #[error("mesh transform is not finite or not invertible (determinant {0})")]
    BadTransform(f32),
}

/// A light that cannot be used.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum LightError {
    #[error("light position {0:?} is not finite")]
    NonFinitePosition([f32; 3]),
    #[error("light direction {0:?} has zero length or is not finite: give a non-zero direction")]
    BadDirection([f32; 3]),
    #[error("light radius {0} is negative or not finite: use a radius >= 0 (0 gives hard shadows)")]
    BadRadius(f32),
    #[error("sun angular radius {0} rad is outside [0, 1.4]: use a small angle (the real sun is 0.0047 rad)")]
    BadAngle(f32),
    #[error(
        "rectangle light size {0} x {1} is negative or not finite: use a width and height >= 0 (0 x 0 gives hard shadows)"
    )]
    BadRectSize(f32, f32),
}

/// Settings of the fin method that are out of range.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SettingsError {
    #[error("layer count {0} is out of range: use 1..=64")]
    Layers(u32),
    #[error("sub-layer count {0} is out of range: use 1..=65536")]
    SubLayers(u32),
    #[error("map resolution {0} is out of range: use 16..=8192")]
    MapResolution(u32),
    #[error("sample count {0} is out of range: use 1..=1048576")]
    Samples(u32),
}

/// A glTF file that cannot be turned into meshes.
#[derive(Debug, Error)]
pub enum GltfError {
    #[error("cannot read glTF file {path}: {source}")]
    Io { path: String, source: std::io::Error },
    #[error("not a valid glTF/GLB file: {0}")]
    Parse(String),
    #[error("glTF buffer {index} is missing or unreadable: {reason}")]
    Buffer { index: usize, reason: String },
    #[error("glTF mesh '{mesh}' primitive {primitive} is unusable: {source}")]
    Mesh { mesh: String, primitive: usize, source: MeshError },
    #[error("glTF file has no triangle meshes: export the scene with triangulated meshes")]
    NoMeshes,
    #[error("glTF {what} claims {amount}, more than the {limit} this importer reads: is the file damaged?")]
    TooLarge { what: String, amount: u64, limit: u64 },
    #[error("glTF accessor {index} is unusable: {reason}")]
    Accessor { index: usize, reason: String },
}
