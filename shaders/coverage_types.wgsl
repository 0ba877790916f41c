// Shared types and helpers of the coverage passes (`coverage_lists.wgsl`,
// `coverage.wgsl`); the math mirrors the core's `shadow_fins::coverage`.
#define_import_path bevy_shadow_fins::coverage_types
struct CoverageParams {
    // (depth lists' region min x, min y, texel size, unused)
    lists: vec4<f32>,
    // (lists resolution, near depths K, far depths, raster work items: 0 = no casters)
    counts: vec4<u32>,
    // (light radius R or tan θ, near depth, surface epsilon floor, relative surface epsilon)
    light: vec4<f32>,
    // (edge grid min x, min y, cells per map unit x, y)
    grid: vec4<f32>,
    // (grid cells x, y, light samples N, projection: 0 disk or rectangle, 1 sun, 2 a point light's cube face)
    info: vec4<u32>,
    axis_u: vec4<f32>,
    axis_v: vec4<f32>,
    // w: a point light's sphere radius (its cube faces), else 0
    axis_n: vec4<f32>,
}


// A face the raster reference count tests its move against (`GpuCoverageFace`).
struct Face {
    a: vec4<f32>,
    b: vec4<f32>,
    c: vec4<f32>,
}

// A potential silhouette edge (`GpuCoverageEdge`): ends (a.w = faces), the
// third vertex of each face, the map segment of its near-clipped ends.
struct Edge {
    a: vec4<f32>,
    b: vec4<f32>,
    third_a: vec4<f32>,
    third_b: vec4<f32>,
    segment: vec4<f32>,
}

const INF_BITS: u32 = 0x7f800000u;
const WORKGROUP: u32 = 64u;
// Samples a u32 word counts; words per pixel (N ≤ 256); bit planes of a count.
const CHUNK: u32 = 32u;
const MAX_CHUNKS: u32 = 8u;
const PLANES: u32 = 8u;


fn list_stride(params: CoverageParams) -> u32 {
    return params.counts.y + params.counts.z + 1u;
}

fn texel_center(params: CoverageParams, x: u32, y: u32) -> vec2<f32> {
    return params.lists.xy + (vec2<f32>(f32(x), f32(y)) + 0.5) * params.lists.z;
}

fn cross2(a: vec2<f32>, b: vec2<f32>) -> f32 {
    return a.x * b.y - a.y * b.x;
}

// `shadow_fins::coverage::reference::owns`: inside, or on an edge by the
// top-left rule, the edge function evaluated with its ends in a fixed order.
fn owns(c0: vec2<f32>, c1: vec2<f32>, c2: vec2<f32>, q: vec2<f32>) -> bool {
    let area = cross2(c1 - c0, c2 - c0);
    if (!(area != 0.0)) {
        return false;
    }
    let orient = select(-1.0, 1.0, area > 0.0);
    let c = array<vec2<f32>, 3>(c0, c1, c2);
    for (var i = 0u; i < 3u; i++) {
        let a = c[i];
        let b = c[(i + 1u) % 3u];
        let a_first = a.x < b.x || (a.x == b.x && a.y < b.y);
        let lo = select(b, a, a_first);
        let hi = select(a, b, a_first);
        let sign = select(-1.0, 1.0, a_first);
        let w = cross2(hi - lo, q - lo) * sign * orient;
        let e = (b - a) * orient;
        if (!(w > 0.0 || (w == 0.0 && (e.y > 0.0 || (e.y == 0.0 && e.x < 0.0))))) {
            return false;
        }
    }
    return true;
}

