// Alpha-masked casters (the core's `shadow_fins::cutout`): a caster with a
// cut-out blocks a texel's centre ray only where its material's alpha, read
// bilinearly between texel centres at the perspective-correct UV, reaches
// the cutoff. Bindings 4 and 5 of the maps' and the coverage lists' layouts.
#define_import_path bevy_shadow_fins::cutout

#import bevy_shadow_fins::fin_types::{Caster, CasterCutout}

@group(0) @binding(4) var<storage, read> cutouts: array<CasterCutout>;
// Per mask: width, height, threshold (f32 bits: `AlphaMask::threshold`, the
// cutoff over the base alpha less the core's tie), wrap modes and filter
// (u | v << 8 | nearest << 16; modes 0 repeat, 1 mirrored repeat, 2 clamp),
// then the alphas, four 8-bit texels a word, row-major from v = 0.
@group(0) @binding(5) var<storage, read> mask_words: array<u32>;

fn wrap_texel(i: i32, n: i32, mode: u32) -> i32 {
    if (mode == 2u) {
        return clamp(i, 0, n - 1);
    }
    if (mode == 1u) {
        let k = ((i % (2 * n)) + 2 * n) % (2 * n);
        return select(2 * n - 1 - k, k, k < n);
    }
    return ((i % n) + n) % n;
}

fn mask_texel(m: u32, x: i32, y: i32) -> f32 {
    let w = i32(mask_words[m]);
    let h = i32(mask_words[m + 1u]);
    let modes = mask_words[m + 3u];
    let i = u32(wrap_texel(y, h, (modes >> 8u) & 0xffu) * w + wrap_texel(x, w, modes & 0xffu));
    let word = mask_words[m + 4u + i / 4u];
    return f32((word >> ((i % 4u) * 8u)) & 0xffu) / 255.0;
}

// `AlphaMask::alpha_at`: bilinear between texel centres, or the texel's own
// (nearest filter).
fn mask_alpha(m: u32, uv: vec2<f32>) -> f32 {
    let size = vec2<f32>(f32(mask_words[m]), f32(mask_words[m + 1u]));
    if (((mask_words[m + 3u] >> 16u) & 1u) == 1u) {
        let t = vec2<i32>(floor(uv * size));
        return mask_texel(m, t.x, t.y);
    }
    let p = uv * size - 0.5;
    let p0 = floor(p);
    let f = p - p0;
    let i = vec2<i32>(p0);
    let top = mix(mask_texel(m, i.x, i.y), mask_texel(m, i.x + 1, i.y), f.x);
    let bottom = mix(mask_texel(m, i.x, i.y + 1), mask_texel(m, i.x + 1, i.y + 1), f.x);
    return mix(top, bottom, f.y);
}

// `MapTriangle::opaque_at`: whether caster `c` blocks at the covered map point `q`.
fn caster_opaque(c: Caster, q: vec2<f32>, orthographic: bool) -> bool {
    if (c.cutout == 0u) {
        return true;
    }
    let k = cutouts[c.cutout - 1u];
    let a = vec2<f32>(c.corners[0], c.corners[1]);
    let b = vec2<f32>(c.corners[2], c.corners[3]);
    let d = vec2<f32>(c.corners[4], c.corners[5]);
    let area = (b.x - a.x) * (d.y - a.y) - (b.y - a.y) * (d.x - a.x);
    var w = vec3<f32>(
        (d.x - b.x) * (q.y - b.y) - (d.y - b.y) * (q.x - b.x),
        (a.x - d.x) * (q.y - d.y) - (a.y - d.y) * (q.x - d.x),
        (b.x - a.x) * (q.y - a.y) - (b.y - a.y) * (q.x - a.x),
    ) / area;
    if (!orthographic) {
        w /= max(vec3<f32>(k.depths[0], k.depths[1], k.depths[2]), vec3<f32>(1.17549435e-38));
    }
    let uv = (vec2<f32>(k.uvs[0], k.uvs[1]) * w.x + vec2<f32>(k.uvs[2], k.uvs[3]) * w.y
        + vec2<f32>(k.uvs[4], k.uvs[5]) * w.z) / (w.x + w.y + w.z);
    // Not finite (a NaN fails every comparison): blocks, as on the CPU.
    if (!all(abs(uv) <= vec2<f32>(3.0e38))) {
        return true;
    }
    return mask_alpha(k.mask, uv) >= bitcast<f32>(mask_words[k.mask + 2u]);
}
