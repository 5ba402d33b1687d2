//! glTF materials: `pbrMetallicRoughness` with its factors and textures read into a
//! [`GltfPbr`], and the one function that turns it into relight's material and maps
//! ([`pbr_to_material`]).
//!
//! Textures: the image is decoded by [`Texture::decode`] (PNG, JPEG) as sRGB for the base
//! colour and linearly for the metallic-roughness and normal textures; the texture's sampler
//! (`wrapS`, `wrapT`, `magFilter`; minification is bilinear) and `KHR_texture_transform`
//! (offset, rotation, scale, on the normal texture too; a `texCoord` override other than 0 is
//! warned about and read with `TEXCOORD_0`) go with it ([`crate::texture`] defines them in glTF's image space). The
//! normal texture's `scale` multiplies the map's x and y (glTF: `normalize((2 rgb - 1)
//! (scale, scale, 1))`).

use crate::error::SceneError;
use crate::io::files::{self, LoadOptions};
use crate::material::maps::MaterialMaps;
use crate::material::Material;
use crate::texture::{Encoding, Filter, Sampler, Texture, UvTransform, Wrap};
use crate::Vec3;
use glam::Vec2;
use std::path::Path;

/// A glTF metallic-roughness material as the file states it (factors and textures).
#[derive(Clone, Debug, PartialEq)]
pub struct GltfPbr {
    /// The material's name (`material{index}` when it has none).
    pub name: String,
    /// `baseColorFactor` (linear RGBA, each in `[0, 1]`).
    pub base_color_factor: [f32; 4],
    /// `metallicFactor` in `[0, 1]`.
    pub metallic: f32,
    /// `roughnessFactor` in `[0, 1]` (perceptual: GGX `alpha = roughness^2`).
    pub roughness: f32,
    /// `baseColorTexture`, sRGB-decoded.
    pub base_color: Option<Texture>,
    /// `metallicRoughnessTexture`, linear: G = roughness, B = metallic.
    pub metallic_roughness: Option<Texture>,
    /// `normalTexture`, linear tangent-space normal map.
    pub normal: Option<Texture>,
    /// `normalTexture.scale`.
    pub normal_scale: f32,
}

impl GltfPbr {
    /// Whether any texture is present (its primitives then need texture coordinates).
    pub fn is_textured(&self) -> bool {
        self.base_color.is_some() || self.metallic_roughness.is_some() || self.normal.is_some()
    }
}

/// relight's material and maps for a glTF material: [`Material::Gltf`], the specification's
/// metallic-roughness BRDF (Appendix B; [`crate::material::gltf_pbr`]), with the factors as
/// they are, the base colour texture as the `diffuse` map (it multiplies the base colour),
/// the metallic-roughness texture as the `metallic_roughness` map (G multiplies the
/// roughness, B the metallic) and the normal texture as the `normal` map with its `scale`
/// ([`crate::material::maps`]). The alpha of `baseColorFactor` is not used (opaque).
///
/// # Errors
/// None today; the `Result` is kept for the callers' sake (a message when a map cannot be
/// made).
pub fn pbr_to_material(p: &GltfPbr) -> Result<(Material, MaterialMaps), String> {
    let c = p.base_color_factor;
    let material = Material::Gltf {
        base_color: Vec3::new(c[0], c[1], c[2]),
        metallic: p.metallic,
        roughness: p.roughness,
    };
    let maps = MaterialMaps {
        diffuse: p.base_color.clone(),
        metallic_roughness: p.metallic_roughness.clone(),
        normal: p.normal.clone(),
        normal_scale: p.normal_scale,
        ..MaterialMaps::default()
    };
    Ok((material, maps))
}

/// Decoded images, per image index and encoding (an image may be used as colour and data).
pub(crate) struct ImageCache {
    decoded: Vec<[Option<Texture>; 2]>,
}

impl ImageCache {
    pub(crate) fn new(n: usize) -> ImageCache {
        ImageCache {
            decoded: vec![[None, None]; n],
        }
    }
}

/// Read glTF material `m` (factors checked, textures decoded), pushing its warnings.
pub(crate) fn read_material(
    path: &Path,
    m: &gltf::Material,
    buffers: &[Vec<u8>],
    opts: &LoadOptions,
    images: &mut ImageCache,
    warnings: &mut Vec<String>,
) -> Result<GltfPbr, SceneError> {
    let index = m.index().unwrap_or(0);
    let name = m
        .name()
        .filter(|n| !n.is_empty())
        .map_or_else(|| format!("material{index}"), String::from);
    let at = |msg: String| SceneError::malformed(path, format!("material '{name}': {msg}"));
    let unsupported =
        |msg: String| SceneError::unsupported(path, format!("material '{name}': {msg}"));
    if m.emissive_strength().is_some() {
        return Err(unsupported(
            "KHR_materials_emissive_strength: relight's methods carry no emission".into(),
        ));
    }
    if m.emissive_texture().is_some() {
        return Err(unsupported(
            "emissiveTexture: relight's methods carry no emission".into(),
        ));
    }
    if m.emissive_factor() != [0.0; 3] {
        return Err(unsupported(format!(
            "emissiveFactor {:?}: relight's methods carry no emission",
            m.emissive_factor()
        )));
    }
    match m.alpha_mode() {
        gltf::material::AlphaMode::Opaque => {}
        mode => warnings.push(format!(
            "{}: material '{name}': alphaMode {mode:?} is drawn opaque",
            path.display()
        )),
    }
    let pbr = m.pbr_metallic_roughness();
    let factors = [
        ("baseColorFactor", pbr.base_color_factor().to_vec()),
        ("metallicFactor", vec![pbr.metallic_factor()]),
        ("roughnessFactor", vec![pbr.roughness_factor()]),
    ];
    for (what, v) in factors {
        if let Some(x) = v.iter().find(|x| !(0.0..=1.0).contains(*x)) {
            return Err(at(format!("{what} {x} is not in [0, 1]")));
        }
    }
    let mut second_uv = false;
    let mut texture = |t: gltf::texture::Texture,
                       tex_coord: u32,
                       transform: Option<(UvTransform, Option<u32>)>,
                       encoding: Encoding,
                       which: &str|
     -> Result<Texture, SceneError> {
        let transform = match transform {
            Some((t, override_coord)) => {
                if override_coord.is_some_and(|c| c != 0) {
                    second_uv = true;
                }
                if !(t.offset.is_finite() && t.rotation.is_finite() && t.scale.is_finite()) {
                    return Err(at(format!("{which}: KHR_texture_transform is not finite")));
                }
                Some(t)
            }
            None => None,
        };
        if tex_coord != 0 {
            second_uv = true;
        }
        let s = t.sampler();
        let wrap = |w: gltf::texture::WrappingMode| match w {
            gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
            gltf::texture::WrappingMode::ClampToEdge => Wrap::ClampToEdge,
            gltf::texture::WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
        };
        let sampler = Sampler {
            wrap_s: wrap(s.wrap_s()),
            wrap_t: wrap(s.wrap_t()),
            filter: match s.mag_filter() {
                Some(gltf::texture::MagFilter::Nearest) => Filter::Nearest,
                _ => Filter::Linear,
            },
        };
        let image = t.source();
        let slot = &mut images.decoded[image.index()][(encoding == Encoding::Data) as usize];
        let tex = match slot {
            Some(tex) => tex.clone(),
            None => {
                let tex = decode_image(path, &image, buffers, opts, encoding)
                    .map_err(|e| prefix(e, &format!("material '{name}': {which}: ")))?;
                *slot = Some(tex.clone());
                tex
            }
        };
        Ok(tex.with_sampler(sampler).with_transform(transform))
    };
    let base_color = match pbr.base_color_texture() {
        Some(info) => Some(texture(
            info.texture(),
            info.tex_coord(),
            info.texture_transform().map(|t| typed_transform(&t)),
            Encoding::Colour,
            "baseColorTexture",
        )?),
        None => None,
    };
    let metallic_roughness = match pbr.metallic_roughness_texture() {
        Some(info) => Some(texture(
            info.texture(),
            info.tex_coord(),
            info.texture_transform().map(|t| typed_transform(&t)),
            Encoding::Data,
            "metallicRoughnessTexture",
        )?),
        None => None,
    };
    let (normal, normal_scale) = match m.normal_texture() {
        Some(n) => {
            if !n.scale().is_finite() {
                return Err(at(format!(
                    "normalTexture.scale {} is not finite",
                    n.scale()
                )));
            }
            let tt = match n.extension_value("KHR_texture_transform") {
                Some(v) => Some(
                    json_transform(v)
                        .map_err(|m| at(format!("normalTexture: KHR_texture_transform: {m}")))?,
                ),
                None => None,
            };
            let t = texture(
                n.texture(),
                n.tex_coord(),
                tt,
                Encoding::Data,
                "normalTexture",
            )?;
            (Some(t), n.scale())
        }
        None => (None, 1.0),
    };
    if second_uv {
        warnings.push(format!(
            "{}: material '{name}': a texture uses TEXCOORD_1; read with TEXCOORD_0",
            path.display()
        ));
    }
    let c = pbr.base_color_factor();
    Ok(GltfPbr {
        name,
        base_color_factor: c,
        metallic: pbr.metallic_factor(),
        roughness: pbr.roughness_factor(),
        base_color,
        metallic_roughness,
        normal,
        normal_scale,
    })
}

/// A typed `KHR_texture_transform` and its `texCoord` override.
fn typed_transform(t: &gltf::texture::TextureTransform) -> (UvTransform, Option<u32>) {
    let uv = UvTransform {
        offset: Vec2::from(t.offset()),
        rotation: t.rotation(),
        scale: Vec2::from(t.scale()),
    };
    (uv, t.tex_coord())
}

/// A `KHR_texture_transform` from its JSON (the `gltf` crate types it on texture infos but
/// not on the normal texture): `offset` (default `[0, 0]`), `rotation` (0), `scale`
/// (`[1, 1]`), `texCoord`.
fn json_transform(v: &serde_json::Value) -> Result<(UvTransform, Option<u32>), String> {
    #[derive(serde::Deserialize)]
    #[serde(rename_all = "camelCase")]
    struct Khr {
        #[serde(default)]
        offset: [f32; 2],
        #[serde(default)]
        rotation: f32,
        #[serde(default = "one")]
        scale: [f32; 2],
        tex_coord: Option<u32>,
    }
    fn one() -> [f32; 2] {
        [1.0, 1.0]
    }
    let k: Khr = serde_json::from_value(v.clone()).map_err(|e| e.to_string())?;
    let uv = UvTransform {
        offset: Vec2::from(k.offset),
        rotation: k.rotation,
        scale: Vec2::from(k.scale),
    };
    Ok((uv, k.tex_coord))
}

/// `e` with `p` put before its message (errors keep their kind).
fn prefix(e: SceneError, p: &str) -> SceneError {
    match e {
        SceneError::Malformed { at, msg } => SceneError::Malformed {
            at,
            msg: format!("{p}{msg}"),
        },
        SceneError::Unsupported { at, msg } => SceneError::Unsupported {
            at,
            msg: format!("{p}{msg}"),
        },
        SceneError::TooLarge { at, msg } => SceneError::TooLarge {
            at,
            msg: format!("{p}{msg}"),
        },
        e => e,
    }
}

/// Decode image `image` (buffer view, data URI or file under the path policy).
fn decode_image(
    path: &Path,
    image: &gltf::Image,
    buffers: &[Vec<u8>],
    opts: &LoadOptions,
    encoding: Encoding,
) -> Result<Texture, SceneError> {
    let what = format!("image {}", image.index());
    let (bytes, mime): (std::borrow::Cow<[u8]>, Option<&str>) = match image.source() {
        gltf::image::Source::View { view, mime_type } => {
            let buf = &buffers[view.buffer().index()];
            let bytes = view
                .offset()
                .checked_add(view.length())
                .and_then(|end| buf.get(view.offset()..end))
                .ok_or_else(|| {
                    SceneError::malformed(
                        path,
                        format!("{what}: bufferView {} lies beyond its buffer", view.index()),
                    )
                })?;
            (bytes.into(), Some(mime_type))
        }
        gltf::image::Source::Uri { uri, mime_type } => {
            if mime_type == Some("image/ktx2") || uri.to_ascii_lowercase().ends_with(".ktx2") {
                return Err(SceneError::unsupported(
                    path,
                    format!("{what}: KTX2 image '{uri}' (PNG and JPEG are read)"),
                ));
            }
            let what = format!("{what} '{uri}'");
            (
                super::buffers::read_uri(path, uri, &what, files::MAX_FILE_BYTES, opts)?.into(),
                mime_type,
            )
        }
    };
    if mime == Some("image/ktx2") {
        return Err(SceneError::unsupported(
            path,
            format!("{what}: KTX2 image (PNG and JPEG are read)"),
        ));
    }
    Texture::decode(&bytes, encoding).map_err(|m| {
        if m.contains("exceed the texture limit") {
            SceneError::too_large(path, format!("{what}: {m}"))
        } else if m.contains("unsupported") {
            SceneError::unsupported(path, format!("{what}: {m}"))
        } else {
            SceneError::malformed(path, format!("{what}: {m}"))
        }
    })
}
