// A camera's pixel as a receiver in the light frame: shared by the fin
// visibility pass (`visibility.wgsl`), the convolution pass
// (`convolution.wgsl`) and the plateaus pass (`plateaus.wgsl`), which read
// the same prepasses the same way; the coverage pass (`coverage.wgsl`)
// shares the view transform.
#define_import_path bevy_shadow_fins::fin_view
#import bevy_render::view::View
#import bevy_shadow_fins::fin_types::{FinParams, in_face}

// The camera's view space → the light frame, composed on the CPU in f64
// (columns of the linear part, and the translation). Positions are rebuilt in
// view space, where they are small near the camera, and never pass through
// world coordinates: at 1e5 from the origin an f32 world position is off by
// 0.008, the size of the one-texel lift.
struct FinView {
    column_x: vec4<f32>,
    column_y: vec4<f32>,
    column_z: vec4<f32>,
    // w: the coverage pass's least receiver lift (`camera_raster_error`), unused here.
    translation: vec4<f32>,
}

fn view_to_frame(fin_view: FinView, p: vec3<f32>) -> vec3<f32> {
    return fin_view.column_x.xyz * p.x + fin_view.column_y.xyz * p.y + fin_view.column_z.xyz * p.z
        + fin_view.translation.xyz;
}

fn dir_to_frame(params: FinParams, d: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(dot(d, params.axis_u.xyz), dot(d, params.axis_v.xyz), dot(d, params.axis_n.xyz));
}

// Whether the target pixel lies in the camera's viewport (split screen).
fn in_viewport(view: View, id: vec2<u32>) -> bool {
    let p = vec2<f32>(id);
    return all(p >= view.viewport.xy) && all(p < view.viewport.xy + view.viewport.zw);
}

// The light-frame position of the surface at target pixel `id` and prepass
// depth `depth`: through the viewport to clip space, to view space, to the frame.
fn pixel_position(view: View, fin_view: FinView, id: vec2<u32>, depth: f32) -> vec3<f32> {
    let uv = (vec2<f32>(id) + 0.5 - view.viewport.xy) / view.viewport.zw;
    let ndc = vec4<f32>(uv.x * 2.0 - 1.0, 1.0 - uv.y * 2.0, depth, 1.0);
    let in_view = view.view_from_clip * ndc;
    return view_to_frame(fin_view, in_view.xyz / in_view.w);
}

// The world normal Bevy's normal prepass holds at a pixel.
fn prepass_normal(encoded: vec4<f32>) -> vec3<f32> {
    return normalize(encoded.xyz * 2.0 - 1.0);
}

// What a pass does at a target pixel: background or outside the viewport
// (fully lit: the light's own half-space test is the compositing pass's),
// a receiver another cube face's pass shades (a point light's six passes
// fill its one layer between them: `in_face`), or a receiver to shade.
const PIXEL_BACKGROUND: u32 = 0u;
const PIXEL_OTHER_FACE: u32 = 1u;
const PIXEL_RECEIVER: u32 = 2u;

struct PixelReceiver {
    kind: u32,
    // Light frame.
    position: vec3<f32>,
    normal: vec3<f32>,
}

// The receiver at target pixel `id`, from its prepass depth (reverse Z: 0 is
// the far plane) and its world normal (`prepass_normal`, or
// `receiver_normal::receiver_normal` where the G-buffer is read).
fn pixel_receiver(
    view: View,
    fin_view: FinView,
    params: FinParams,
    id: vec2<u32>,
    depth: f32,
    world_normal: vec3<f32>,
) -> PixelReceiver {
    var r: PixelReceiver;
    r.kind = PIXEL_BACKGROUND;
    if (depth <= 0.0 || !in_viewport(view, id)) {
        return r;
    }
    r.position = pixel_position(view, fin_view, id, depth);
    if (params.flags.w == 2u && !in_face(r.position)) {
        r.kind = PIXEL_OTHER_FACE;
        return r;
    }
    r.normal = dir_to_frame(params, world_normal);
    r.kind = PIXEL_RECEIVER;
    return r;
}
