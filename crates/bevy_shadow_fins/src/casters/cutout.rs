//! Alpha-masked casters as Bevy draws them: a mesh whose `StandardMaterial`
//! is `AlphaMode::Mask(cutoff)` (or `AlphaToCoverage`, a mask at 0.5 without
//! MSAA, which fin-shadowed views run without) casts only where the alpha of
//! its base colour — the base colour texture's, read by its sampler's wrap
//! modes at the material's `uv_transform`ed UVs, times the base colour's
//! alpha — reaches the cutoff. The core's [`shadow_fins::cutout`] models it:
//! the mask and the outline of the opaque region, built once per mesh and
//! material (per pose for a posed mesh) and shared by every instance.
//!
//! What is modelled solid: a texture still loading (re-read when it
//! arrives), and — said once in the log — a compressed texture or one kept
//! in the render world only (no main-world texels to read), a mesh without
//! the UV channel the material reads. A mask every texel of which passes
//! the cutoff is solid (no cut-out to pay for). Materials other than
//! `StandardMaterial` (`ExtendedMaterial`, custom) cast solid. The sampler
//! read is the image's own, or for `ImageSampler::Default` the app's
//! (`ImagePlugin::default_sampler`, [`FinDefaultImageSampler`]): its wrap
//! modes and its magnification filter (nearest: the mask's square texels,
//! [`shadow_fins::cutout::Filter`]). Approximated: the minification filter
//! and mip levels are not modelled (the shadow is the texture's at its own
//! resolution, box-filtered down past 256 texels a side:
//! [`shadow_fins::cutout::MAX_MASK_SIDE`]), and a posed (skinned, morphed)
//! masked mesh builds its outline again at every new pose. Vertex colour
//! alpha is not applied, as in Bevy's own shadow and depth prepasses
//! (`pbr_prepass_functions.wgsl`'s `prepass_alpha_discard` reads the
//! material and its texture only); Bevy's main pass does multiply it in, so
//! a card cut by its vertex alpha alone is drawn with holes that neither
//! Bevy's shadow nor the fins' have.

use std::{collections::HashMap, sync::Arc};

use crate::casters::gpu_geometry::GpuMeshGeometry;

use bevy::{
    asset::AssetId,
    image::{ImageAddressMode, ImageSampler},
    math::Affine2,
    mesh::{UvChannel, VertexAttributeValues},
    prelude::*,
};
use shadow_fins::{
    cutout::{Address, AlphaMask, Cutout, Filter, Outline},
    glam::Vec2,
    mesh::{Mesh as CoreMesh, Topology},
};

/// The alpha mask a `StandardMaterial` casts with, if any: what it was made
/// from (to tell a change that matters from one that does not) and the mask.
#[derive(Clone)]
struct MaterialMask {
    key: MaskKey,
    /// `None`: the material casts solid.
    mask: Option<Arc<AlphaMask>>,
    /// The texture it reads, still loading: read again when it arrives.
    waiting_for: Option<AssetId<Image>>,
}

/// What a material's mask depends on.
#[derive(Clone, PartialEq)]
struct MaskKey {
    cutoff: Option<u32>,
    base_alpha: u32,
    texture: Option<AssetId<Image>>,
    channel: u8,
    uv_transform: [u32; 6],
}

/// A material's mask inputs; all alike for a material that is no mask, so
/// that fading a blended material or animating its texture changes nothing.
fn key_of(material: &StandardMaterial) -> MaskKey {
    let cutoff = match material.alpha_mode {
        AlphaMode::Mask(c) => Some(c.to_bits()),
        // Without MSAA (fin-shadowed views have none) Bevy draws it as a mask at 0.5.
        AlphaMode::AlphaToCoverage => Some(0.5f32.to_bits()),
        _ => None,
    };
    if cutoff.is_none() {
        return MaskKey { cutoff, base_alpha: 0, texture: None, channel: 0, uv_transform: [0; 6] };
    }
    let t = material.uv_transform;
    MaskKey {
        cutoff,
        base_alpha: material.base_color.alpha().to_bits(),
        texture: material.base_color_texture.as_ref().map(|h| h.id()),
        channel: match material.base_color_channel {
            UvChannel::Uv0 => 0,
            UvChannel::Uv1 => 1,
        },
        uv_transform: [
            t.matrix2.x_axis.x,
            t.matrix2.x_axis.y,
            t.matrix2.y_axis.x,
            t.matrix2.y_axis.y,
            t.translation.x,
            t.translation.y,
        ]
        .map(f32::to_bits),
    }
}

/// Per material its mask, and per (mesh, material) the cut-out.
#[derive(Resource, Default)]
pub(crate) struct CutoutCache {
    masks: HashMap<AssetId<StandardMaterial>, MaterialMask>,
    cutouts: HashMap<(AssetId<Mesh>, AssetId<StandardMaterial>), Option<Cutout>>,
    /// Per (mesh, material, whether the GPU poses it): the GPU extraction's
    /// packing of the mesh with its cached cut-out's outline (for a posed
    /// one, at rest with a pose section that poses the outline too:
    /// `pack_posable`), and the outline it was packed with.
    outlined: HashMap<(AssetId<Mesh>, AssetId<StandardMaterial>, bool), (Arc<Outline>, Arc<GpuMeshGeometry>)>,
    /// Bumped whenever what some material cuts out may have changed: the
    /// frame builder rebuilds when it moved (whoever read the events first,
    /// the builder or a `scene_snapshot`).
    generation: u64,
}

impl CutoutCache {
    /// Forgets the cut-outs of a mesh asset that changed.
    pub(crate) fn forget_mesh(&mut self, id: AssetId<Mesh>) {
        self.cutouts.retain(|(mesh, _), _| *mesh != id);
        self.outlined.retain(|(mesh, _, _), _| *mesh != id);
    }

    pub(crate) fn generation(&self) -> u64 {
        self.generation
    }

    /// The packing kept for `key` when it was packed with `outline` (the
    /// cached cut-out's own, not one rebuilt since); else `pack`'s, kept.
    fn packed_once(
        &mut self,
        key: (AssetId<Mesh>, AssetId<StandardMaterial>, bool),
        outline: &Arc<Outline>,
        pack: impl FnOnce() -> Option<Arc<GpuMeshGeometry>>,
    ) -> Option<Arc<GpuMeshGeometry>> {
        if let Some((kept, packing)) = self.outlined.get(&key)
            && Arc::ptr_eq(kept, outline)
        {
            return Some(packing.clone());
        }
        let packing = pack()?;
        self.outlined.insert(key, (outline.clone(), packing.clone()));
        Some(packing)
    }
}

/// The sampler an image with `ImageSampler::Default` is drawn with: the
/// app's `ImagePlugin::default_sampler` (read when the plugin finishes,
/// unless the app inserted this resource itself; Bevy's linear, clamping
/// default without an `ImagePlugin`). Alpha masks read their wrap modes and
/// filter from it when they are built: a change later reaches masks built
/// after it (a material or texture changed), not those already cached.
#[derive(Resource, Clone, Debug)]
pub struct FinDefaultImageSampler(pub bevy::image::ImageSamplerDescriptor);

impl Default for FinDefaultImageSampler {
    fn default() -> Self {
        Self(bevy::image::ImageSamplerDescriptor::linear())
    }
}

/// Keeps the app's default image sampler for the masks (called from the
/// plugin's `finish`, once every plugin is added).
pub(crate) fn finish(app: &mut App) {
    if app.world().contains_resource::<FinDefaultImageSampler>() {
        return;
    }
    let sampler = app
        .get_added_plugins::<bevy::image::ImagePlugin>()
        .first()
        .map(|p| FinDefaultImageSampler(p.default_sampler.clone()))
        .unwrap_or_default();
    app.insert_resource(sampler);
}

/// What the frame builder reads of the casters' materials.
#[derive(bevy::ecs::system::SystemParam)]
pub(crate) struct CasterMaterials<'w, 's> {
    of: Query<'w, 's, &'static MeshMaterial3d<StandardMaterial>>,
    default_sampler: Option<Res<'w, FinDefaultImageSampler>>,
    materials: Option<Res<'w, Assets<StandardMaterial>>>,
    images: Option<Res<'w, Assets<Image>>>,
    // Optional: a world without Bevy's PBR or image plugins has none.
    material_events: Option<MessageReader<'w, 's, AssetEvent<StandardMaterial>>>,
    image_events: Option<MessageReader<'w, 's, AssetEvent<Image>>>,
    pub(crate) cache: ResMut<'w, CutoutCache>,
}

/// The asset an event says arrived, changed or went (not one merely unused).
fn changed_asset<A: Asset>(event: &AssetEvent<A>) -> Option<AssetId<A>> {
    match event {
        AssetEvent::Added { id }
        | AssetEvent::Modified { id }
        | AssetEvent::Removed { id }
        | AssetEvent::LoadedWithDependencies { id } => Some(*id),
        AssetEvent::Unused { .. } => None,
    }
}

impl CasterMaterials<'_, '_> {
    /// Reads this frame's material and texture events. Forgets (and bumps
    /// the cache's generation for) what they make stale: a material whose
    /// mask inputs changed, one that arrived as a mask, a texture a mask reads
    /// or waits for. A colour change, a non-mask material's, is none. (A
    /// caster whose material was swapped is signed again by itself: its
    /// material id is in its signature, `casters/mod.rs`.)
    pub(crate) fn refresh(&mut self) {
        let CutoutCache { masks, cutouts, outlined, generation } = &mut *self.cache;
        let mut stale = false;
        if let Some(events) = self.material_events.as_mut() {
            for id in events.read().filter_map(changed_asset) {
                let id = &id;
                let now = self.materials.as_ref().and_then(|m| m.get(*id)).map(key_of);
                let was = masks.get(id).map(|m| &m.key);
                let is_mask = |k: Option<&MaskKey>| k.is_some_and(|k| k.cutoff.is_some());
                // A change that matters: the key moved, or a mask arrived unseen.
                let matters = match was {
                    Some(was) => Some(was) != now.as_ref(),
                    None => is_mask(now.as_ref()),
                };
                if matters {
                    masks.remove(id);
                    cutouts.retain(|(_, material), _| material != id);
                    outlined.retain(|(_, material, _), _| material != id);
                    stale = true;
                }
            }
        }
        if let Some(events) = self.image_events.as_mut() {
            for id in events.read().filter_map(changed_asset) {
                let reading: Vec<AssetId<StandardMaterial>> = masks
                    .iter()
                    .filter(|(_, m)| m.key.texture == Some(id) || m.waiting_for == Some(id))
                    .map(|(k, _)| *k)
                    .collect();
                for material in reading {
                    masks.remove(&material);
                    cutouts.retain(|(_, m), _| *m != material);
                    outlined.retain(|(_, m, _), _| *m != material);
                    stale = true;
                }
            }
        }
        if stale {
            *generation += 1;
        }
    }

    /// The material id an entity casts with, for the frame's signature.
    pub(crate) fn material_of(&self, entity: Entity) -> Option<AssetId<StandardMaterial>> {
        self.of.get(entity).ok().map(|m| m.id())
    }

    /// The cut-out `entity`'s mesh casts with: `None` when it casts solid.
    /// `posed` meshes (their topology changes with the pose) are not cached.
    pub(crate) fn cutout(
        &mut self,
        entity: Entity,
        mesh_id: AssetId<Mesh>,
        mesh: &Mesh,
        core: &CoreMesh,
        topology: &Topology,
        posed: bool,
    ) -> Option<Cutout> {
        let material_id = self.material_of(entity)?;
        let mask = self.mask(material_id)?;
        if !posed && let Some(c) = self.cache.cutouts.get(&(mesh_id, material_id)) {
            return c.clone();
        }
        let material = self.materials.as_ref()?.get(material_id)?;
        let cutout = build_cutout(mask, material, mesh, core, topology, mesh_id);
        if !posed {
            self.cache.cutouts.insert((mesh_id, material_id), cutout.clone());
        }
        cutout
    }

    /// `topology` packed for the GPU extraction with `cutout`'s outline
    /// (`GpuMeshGeometry::pack_outlined`), once per mesh and material;
    /// `posed` meshes are packed each time (their cut-out is new each time).
    pub(crate) fn outlined_packing(
        &mut self,
        entity: Entity,
        mesh_id: AssetId<Mesh>,
        topology: &Topology,
        cutout: &Cutout,
        posed: bool,
    ) -> Arc<GpuMeshGeometry> {
        let pack = || Arc::new(GpuMeshGeometry::pack_outlined(topology, cutout));
        let Some(material_id) = self.material_of(entity).filter(|_| !posed) else {
            return pack();
        };
        self.cache.packed_once((mesh_id, material_id, false), &cutout.outline, || Some(pack())).unwrap_or_else(pack)
    }

    /// For a mesh the GPU poses (`pose.wgsl`): its topology at rest packed
    /// with the outline of its rest cut-out and a pose section that poses
    /// the outline with the mesh (the outline's vertices are points of its
    /// faces, fixed there by the UVs), once per mesh and material. `None`
    /// when it casts solid or its cut-out does not fit: the GPU cannot
    /// cut it, and its light frames extract on the CPU.
    pub(crate) fn outlined_posable_packing(
        &mut self,
        entity: Entity,
        mesh_id: AssetId<Mesh>,
        mesh: &Mesh,
        rest: (&CoreMesh, &Topology),
    ) -> Option<Arc<GpuMeshGeometry>> {
        let material_id = self.material_of(entity)?;
        let cutout = self.cutout(entity, mesh_id, mesh, rest.0, rest.1, false)?;
        if cutout.face_uvs.len() != rest.1.faces.len() {
            return None;
        }
        self.cache.packed_once((mesh_id, material_id, true), &cutout.outline, || {
            let at_rest = GpuMeshGeometry::pack_outlined(rest.1, &cutout);
            let source = crate::casters::pose::pose_source(mesh);
            GpuMeshGeometry::pack_posable(&at_rest, rest.1, &source, Some(&cutout.outline)).map(Arc::new)
        })
    }

    /// A material's mask, read once (and again when it or its texture changes).
    fn mask(&mut self, id: AssetId<StandardMaterial>) -> Option<Arc<AlphaMask>> {
        if let Some(m) = self.cache.masks.get(&id) {
            return m.mask.clone();
        }
        let material = self.materials.as_ref()?.get(id)?;
        let key = key_of(material);
        let mut waiting_for = None;
        let mask = key.cutoff.and_then(|cutoff| {
            let cutoff = f32::from_bits(cutoff);
            let base_alpha = material.base_color.alpha();
            let Some(texture) = &material.base_color_texture else {
                // The base alpha alone: solid, or (below the cutoff) a card that casts nothing.
                return AlphaMask::new(0, 0, vec![], base_alpha, cutoff).ok().filter(|m| !m.is_solid()).map(Arc::new);
            };
            let Some(image) = self.images.as_ref().and_then(|i| i.get(texture)) else {
                // Still loading: solid until it arrives (an image event re-reads it).
                waiting_for = Some(texture.id());
                return None;
            };
            let fallback = FinDefaultImageSampler::default();
            let default_sampler = self.default_sampler.as_deref().unwrap_or(&fallback);
            match mask_of_image(image, base_alpha, cutoff, &default_sampler.0) {
                // Every texel passes: solid, and no cut-out to pay for.
                Ok(mask) if mask.is_solid() => None,
                Ok(mask) => Some(Arc::new(mask)),
                Err(why) => {
                    warn_once!("fin shadows: an alpha-masked material casts solid: {why}");
                    None
                }
            }
        });
        self.cache.masks.insert(id, MaterialMask { key, mask: mask.clone(), waiting_for });
        mask
    }
}

/// The alpha channel of `image` (its first layer and mip level) as a mask,
/// with its sampler's wrap modes and magnification filter (`default_sampler`
/// for `ImageSampler::Default`: the app's, [`FinDefaultImageSampler`]).
pub fn mask_of_image(
    image: &Image,
    base_alpha: f32,
    cutoff: f32,
    default_sampler: &bevy::image::ImageSamplerDescriptor,
) -> Result<AlphaMask, String> {
    use bevy::render::render_resource::TextureFormat as F;
    let (w, h) = (image.width(), image.height());
    let Some(data) = image.data.as_ref() else {
        return Err("its texture has no main-world data (RenderAssetUsages::RENDER_WORLD only)".into());
    };
    let texels = w as usize * h as usize;
    let format = image.texture_descriptor.format;
    let alpha: Vec<u8> = match format {
        F::Rgba8Unorm | F::Rgba8UnormSrgb | F::Bgra8Unorm | F::Bgra8UnormSrgb => {
            if data.len() < texels * 4 {
                return Err(format!("its {w} x {h} texture holds {} bytes", data.len()));
            }
            data.chunks_exact(4).take(texels).map(|t| t[3]).collect()
        }
        // No alpha channel: opaque texels.
        F::R8Unorm | F::Rg8Unorm => vec![255; texels],
        _ if image.is_compressed() => return Err(format!("its texture is compressed ({format:?})")),
        _ => {
            let mut alpha = Vec::with_capacity(texels);
            for y in 0..h {
                for x in 0..w {
                    let c = image.get_color_at(x, y).map_err(|e| format!("its {format:?} texture: {e}"))?;
                    alpha.push((c.alpha().clamp(0.0, 1.0) * 255.0).round() as u8);
                }
            }
            alpha
        }
    };
    let address = |a: ImageAddressMode| match a {
        ImageAddressMode::Repeat => Address::Repeat,
        ImageAddressMode::MirrorRepeat => Address::MirroredRepeat,
        // The border colour is not known here: clamped, as is the default.
        ImageAddressMode::ClampToEdge | ImageAddressMode::ClampToBorder => Address::ClampToEdge,
    };
    let d = match &image.sampler {
        ImageSampler::Descriptor(d) => d,
        ImageSampler::Default => default_sampler,
    };
    let filter = match d.mag_filter {
        bevy::image::ImageFilterMode::Nearest => Filter::Nearest,
        bevy::image::ImageFilterMode::Linear => Filter::Linear,
    };
    Ok(AlphaMask::new(w, h, alpha, base_alpha, cutoff)
        .map_err(|e| e.to_string())?
        .with_address([address(d.address_mode_u), address(d.address_mode_v)])
        .with_filter(filter))
}

/// The cut-out of `mesh` under `material`'s mask, from the UV channel the
/// material reads, `uv_transform`ed.
fn build_cutout(
    mask: Arc<AlphaMask>,
    material: &StandardMaterial,
    mesh: &Mesh,
    core: &CoreMesh,
    topology: &Topology,
    mesh_id: AssetId<Mesh>,
) -> Option<Cutout> {
    let attribute = match material.base_color_channel {
        UvChannel::Uv0 => Mesh::ATTRIBUTE_UV_0,
        UvChannel::Uv1 => Mesh::ATTRIBUTE_UV_1,
    };
    let uvs = match mesh.try_attribute_option(attribute) {
        Ok(Some(VertexAttributeValues::Float32x2(uv))) => uv,
        _ => {
            warn_once!(
                "fin shadows: mesh {mesh_id:?} has no {attribute:?} for its alpha-masked material: it casts solid"
            );
            return None;
        }
    };
    let t: Affine2 = material.uv_transform;
    let uvs: Vec<Vec2> = uvs.iter().map(|uv| t.transform_point2(Vec2::from_array(*uv))).collect();
    match Cutout::new(mask, &uvs, core, topology) {
        Ok(c) => Some(c),
        Err(e) => {
            warn_once!("fin shadows: mesh {mesh_id:?}'s alpha mask is not usable ({e}): it casts solid");
            None
        }
    }
}

/// An RGBA image whose alpha is `mask`'s texture's (white elsewhere),
/// sampled with its wrap modes and filter: what shows a core
/// scene's masked object in Bevy as the core models it (`mesh_from_core`
/// with its UVs, a material with `AlphaMode::Mask(mask.cutoff())` and base
/// colour alpha `mask.base_alpha()`).
pub fn image_of_mask(mask: &AlphaMask) -> Image {
    use bevy::{
        asset::RenderAssetUsages,
        image::ImageSamplerDescriptor,
        render::render_resource::{Extent3d, TextureDimension, TextureFormat},
    };
    let data: Vec<u8> = mask.alpha().iter().flat_map(|&a| [255, 255, 255, a]).collect();
    let mut image = Image::new(
        Extent3d { width: mask.width(), height: mask.height(), depth_or_array_layers: 1 },
        TextureDimension::D2,
        data,
        TextureFormat::Rgba8Unorm,
        RenderAssetUsages::default(),
    );
    let address = |a: Address| match a {
        Address::Repeat => ImageAddressMode::Repeat,
        Address::MirroredRepeat => ImageAddressMode::MirrorRepeat,
        Address::ClampToEdge => ImageAddressMode::ClampToEdge,
    };
    let [u, v] = mask.address();
    image.sampler = ImageSampler::Descriptor(ImageSamplerDescriptor {
        address_mode_u: address(u),
        address_mode_v: address(v),
        ..match mask.filter() {
            Filter::Linear => ImageSamplerDescriptor::linear(),
            Filter::Nearest => ImageSamplerDescriptor::nearest(),
        }
    });
    image
}

/// Appends `m` to `words` as `cutout.wgsl` reads a mask: a header (width,
/// height, threshold bits, wrap modes and filter), then four 8-bit alphas a
/// word. Returns the word it starts at.
pub(crate) fn pack_mask(m: &shadow_fins::cutout::AlphaMask, words: &mut Vec<u32>) -> u32 {
    let at = words.len() as u32;
    let code = |a: shadow_fins::cutout::Address| match a {
        shadow_fins::cutout::Address::Repeat => 0u32,
        shadow_fins::cutout::Address::MirroredRepeat => 1,
        shadow_fins::cutout::Address::ClampToEdge => 2,
    };
    let [u, v] = m.address();
    let nearest = (m.filter() == shadow_fins::cutout::Filter::Nearest) as u32;
    words.extend([m.width(), m.height(), m.threshold().to_bits(), code(u) | code(v) << 8 | nearest << 16]);
    words.extend(m.alpha().chunks(4).map(|q| q.iter().enumerate().fold(0u32, |w, (k, &a)| w | (a as u32) << (8 * k))));
    at
}

#[cfg(test)]
mod tests {
    use bevy::{
        asset::RenderAssetUsages,
        image::ImageSamplerDescriptor,
        render::render_resource::{Extent3d, TextureDimension, TextureFormat},
    };

    use super::*;

    fn image(format: TextureFormat, texel: &[u8], sampler: ImageSampler) -> Image {
        let data = [
            texel,
            &[255, 255, 255, 255][..texel.len()],
            &[255, 255, 255, 255][..texel.len()],
            &[255, 255, 255, 255][..texel.len()],
        ]
        .concat();
        let mut image = Image::new(
            Extent3d { width: 2, height: 2, depth_or_array_layers: 1 },
            TextureDimension::D2,
            data,
            format,
            RenderAssetUsages::default(),
        );
        image.sampler = sampler;
        image
    }

    #[test]
    fn a_textures_first_row_is_v_0_and_its_sampler_wraps_the_mask() {
        let linear = ImageSamplerDescriptor::linear();
        // The first texel of the data (top-left, u and v < 0.5) is the hole.
        let repeat = ImageSampler::Descriptor(ImageSamplerDescriptor {
            address_mode_u: ImageAddressMode::Repeat,
            address_mode_v: ImageAddressMode::MirrorRepeat,
            ..ImageSamplerDescriptor::linear()
        });
        for format in [TextureFormat::Rgba8UnormSrgb, TextureFormat::Bgra8Unorm] {
            let m = mask_of_image(&image(format, &[10, 20, 30, 0], repeat.clone()), 1.0, 0.5, &linear).unwrap();
            assert!(!m.opaque(Vec2::new(0.25, 0.25)), "{format:?}: the hole is at the top left");
            assert!(
                m.opaque(Vec2::new(0.75, 0.25)) && m.opaque(Vec2::new(0.25, 0.75)) && m.opaque(Vec2::new(0.75, 0.75))
            );
            assert_eq!(m.address(), [Address::Repeat, Address::MirroredRepeat]);
        }
        // Bevy's default sampler (as `ImagePlugin::default()`'s) clamps; the base alpha scales the texels.
        let m =
            mask_of_image(&image(TextureFormat::Rgba8Unorm, &[0, 0, 0, 0], ImageSampler::Default), 0.4, 0.5, &linear)
                .unwrap();
        assert_eq!(m.address(), [Address::ClampToEdge; 2]);
        assert!(!m.opaque(Vec2::new(0.75, 0.75)), "alpha 1 × base 0.4 < 0.5");
        // Another format by its colours; no alpha channel: opaque.
        let float = image(TextureFormat::R8Unorm, &[0], ImageSampler::Default);
        assert!(mask_of_image(&float, 1.0, 0.5, &linear).unwrap().is_solid());
        let mut empty = image(TextureFormat::Rgba8Unorm, &[0, 0, 0, 0], ImageSampler::Default);
        empty.data = None;
        assert!(mask_of_image(&empty, 1.0, 0.5, &linear).is_err(), "no main-world data is an error, not a panic");
        let mut short = image(TextureFormat::Rgba8Unorm, &[0, 0, 0, 0], ImageSampler::Default);
        short.data.as_mut().unwrap().truncate(5);
        assert!(mask_of_image(&short, 1.0, 0.5, &linear).is_err(), "too few bytes is an error, not a panic");
    }

    #[test]
    fn the_plugin_keeps_the_apps_default_sampler_unless_one_was_given() {
        let mut app = App::new();
        app.add_plugins((bevy::asset::AssetPlugin::default(), bevy::image::ImagePlugin::default_nearest()));
        finish(&mut app);
        let kept = &app.world().resource::<FinDefaultImageSampler>().0;
        assert_eq!(kept.mag_filter, bevy::image::ImageFilterMode::Nearest);
        // One the app inserted itself stays.
        let mut app = App::new();
        app.add_plugins((bevy::asset::AssetPlugin::default(), bevy::image::ImagePlugin::default_nearest()));
        app.insert_resource(FinDefaultImageSampler(ImageSamplerDescriptor::linear()));
        finish(&mut app);
        assert_eq!(app.world().resource::<FinDefaultImageSampler>().0.mag_filter, bevy::image::ImageFilterMode::Linear);
        // No ImagePlugin: Bevy's default, linear.
        let mut app = App::new();
        finish(&mut app);
        assert_eq!(app.world().resource::<FinDefaultImageSampler>().0.mag_filter, bevy::image::ImageFilterMode::Linear);
    }

    #[test]
    fn the_apps_default_sampler_and_a_nearest_filter_are_read() {
        let hole = image(TextureFormat::Rgba8Unorm, &[0, 0, 0, 0], ImageSampler::Default);
        // A pixel-art app: `ImagePlugin::default_nearest()`, repeating.
        let nearest = ImageSamplerDescriptor {
            address_mode_u: ImageAddressMode::Repeat,
            address_mode_v: ImageAddressMode::Repeat,
            ..ImageSamplerDescriptor::nearest()
        };
        let m = mask_of_image(&hole, 1.0, 0.5, &nearest).unwrap();
        assert_eq!((m.address(), m.filter()), ([Address::Repeat; 2], Filter::Nearest));
        // Nearest: the hole's square ends at the texel border (bilinear: half way to the next centre).
        assert!(!m.opaque(Vec2::new(0.49, 0.25)) && m.opaque(Vec2::new(0.51, 0.25)));
        // Repeated: u = −0.25 is the opaque texel at 0.75 (clamped, the hole).
        assert!(m.opaque(Vec2::new(-0.25, 0.25)));
        let clamped = mask_of_image(&hole, 1.0, 0.5, &ImageSamplerDescriptor::linear()).unwrap();
        assert_eq!((clamped.address(), clamped.filter()), ([Address::ClampToEdge; 2], Filter::Linear));
        assert!(!clamped.opaque(Vec2::new(-0.25, 0.25)));
        // The image's own sampler wins over the default; the mask's image keeps its filter.
        let own = image(TextureFormat::Rgba8Unorm, &[0, 0, 0, 0], ImageSampler::linear());
        assert_eq!(mask_of_image(&own, 1.0, 0.5, &nearest).unwrap().filter(), Filter::Linear);
        let round_trip = mask_of_image(&image_of_mask(&m), 1.0, 0.5, &ImageSamplerDescriptor::linear()).unwrap();
        assert_eq!((round_trip.address(), round_trip.filter()), ([Address::Repeat; 2], Filter::Nearest));
    }
}
