//! Alpha cut-outs from a glTF's materials, as a hit filter for `bvhc-loader`'s filtered tracer.
//!
//! A renderer keeps its own scene description; the `.bvh` file only has to lead from a hit back to it. Here that
//! takes one call: `BvhView::source_corners` gives the hit triangle's source range (glTF mesh and primitive,
//! so the material) and the primitive's vertex indices with their barycentric weights, so `TEXCOORD_n` and
//! `COLOR_0` interpolate exactly as the rasterizer would. The glTF rule (core specification, 3.9.4 "Alpha
//! coverage"): alpha is base-colour factor x texture x `COLOR_0` alpha; `MASK` keeps a point whose alpha is
//! at least `alphaCutoff` (default 0.5).
//!
//! `BLEND` has no single answer for a ray tracer; this one uses **stochastic transparency**: a candidate is
//! kept with probability alpha, decided by a hash of the ray and the triangle (the same candidate gets the
//! same answer, as a filter must give), so an average over many rays (occlusion samples, pixels) converges to
//! the blended coverage. A glass with alpha 0.3 lets 70% of the light through.
//!
//! Textures are sampled at the nearest texel with the sampler's wrap modes. Only the alpha channel matters,
//! so PNGs are decoded (as RGBA or grey-alpha; other PNGs and JPEGs have alpha 1) and other image formats are
//! refused for alpha-tested materials. `KHR_texture_transform` is not applied.

use std::path::Path;

use bvhc::loader::{BvhView, SourceCorners, filter::Candidate};
use gltf::texture::WrappingMode;

/// How a primitive's material treats alpha.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AlphaTest {
    /// `MASK`: a point is kept when its alpha is at least the cutoff.
    Mask { cutoff: f32 },
    /// `BLEND`: a candidate is kept with probability alpha (stochastic transparency).
    Blend,
}

/// The alpha of one glTF primitive whose material is not opaque.
struct PrimitiveAlpha {
    test: AlphaTest,
    factor: f32,
    /// Base-colour texture (index into [`Cutouts::images`]) and the texture coordinates it is sampled at.
    texture: Option<(usize, [WrappingMode; 2], Vec<[f32; 2]>)>,
    /// `COLOR_0`'s alpha per vertex, when the primitive has one.
    vertex_alpha: Option<Vec<[f32; 1]>>,
}

/// A decoded alpha channel.
struct AlphaImage {
    width: usize,
    height: usize,
    alpha: Vec<u8>,
}

/// Every non-opaque primitive of a glTF file, by mesh and primitive index, with the alpha channels their
/// base-colour textures need.
pub struct Cutouts {
    primitives: Vec<Vec<Option<PrimitiveAlpha>>>,
    images: Vec<Option<AlphaImage>>,
}

impl Cutouts {
    /// Reads the glTF or GLB at `path` (and the buffers and images it names beside it).
    pub fn read(path: &Path) -> Result<Cutouts, String> {
        let name = path.display();
        let bytes = std::fs::read(path).map_err(|e| format!("{name}: {e}"))?;
        let document = gltf::Gltf::from_slice(&bytes).map_err(|e| format!("{name}: {e}"))?;
        let folder = path.parent().unwrap_or(Path::new("."));
        let buffers = document
            .buffers()
            .map(|buffer| match buffer.source() {
                gltf::buffer::Source::Bin => {
                    document.blob.clone().ok_or_else(|| format!("{name}: buffer {} has no BIN chunk", buffer.index()))
                }
                gltf::buffer::Source::Uri(uri) => {
                    read_uri(folder, uri).map_err(|e| format!("{name}: buffer {}: {e}", buffer.index()))
                }
            })
            .collect::<Result<Vec<_>, String>>()?;
        let mut images: Vec<Option<AlphaImage>> = (0..document.images().len()).map(|_| None).collect();
        let mut primitives = Vec::new();
        for mesh in document.meshes() {
            let mut alphas = Vec::new();
            for primitive in mesh.primitives() {
                let material = primitive.material();
                let test = match material.alpha_mode() {
                    gltf::material::AlphaMode::Opaque => None,
                    gltf::material::AlphaMode::Mask => {
                        Some(AlphaTest::Mask { cutoff: material.alpha_cutoff().unwrap_or(0.5) })
                    }
                    gltf::material::AlphaMode::Blend => Some(AlphaTest::Blend),
                };
                let Some(test) = test else {
                    alphas.push(None);
                    continue;
                };
                let part = format!("{name}: mesh {} primitive {}", mesh.index(), primitive.index());
                let reader = primitive.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
                let pbr = material.pbr_metallic_roughness();
                let texture = match pbr.base_color_texture() {
                    None => None,
                    Some(info) => {
                        let image = info.texture().source();
                        if images[image.index()].is_none() {
                            images[image.index()] =
                                Some(decode_alpha(&buffers, folder, &image).map_err(|e| format!("{part}: {e}"))?);
                        }
                        let sampler = info.texture().sampler();
                        let uvs = reader
                            .read_tex_coords(info.tex_coord())
                            .ok_or_else(|| {
                                format!("{part}: no TEXCOORD_{} for its base-colour texture", info.tex_coord())
                            })?
                            .into_f32()
                            .collect();
                        Some((image.index(), [sampler.wrap_s(), sampler.wrap_t()], uvs))
                    }
                };
                let vertex_alpha = reader.read_colors(0).map(|colors| colors.into_rgba_f32().map(|c| [c[3]]).collect());
                alphas.push(Some(PrimitiveAlpha { test, factor: pbr.base_color_factor()[3], texture, vertex_alpha }));
            }
            primitives.push(alphas);
        }
        Ok(Cutouts { primitives, images })
    }

    /// Every alpha-tested primitive: glTF mesh index, primitive index and its test.
    pub fn alpha_tests(&self) -> Vec<(u32, u32, AlphaTest)> {
        let tested = self.primitives.iter().enumerate().flat_map(|(mesh, primitives)| {
            primitives
                .iter()
                .enumerate()
                .filter_map(move |(index, p)| Some((mesh as u32, index as u32, p.as_ref()?.test)))
        });
        tested.collect()
    }

    fn primitive(&self, mesh: u32, primitive: u32) -> Option<&PrimitiveAlpha> {
        self.primitives.get(mesh as usize)?.get(primitive as usize)?.as_ref()
    }

    /// Whether the candidate is kept: the filter a renderer passes to `Tracer::filtered`. A hit the file cannot
    /// lead back to the glTF (no source ids or vertices) is kept, as on an opaque material.
    pub fn keeps(&self, view: &BvhView<'_>, candidate: &Candidate<'_>) -> bool {
        let Some(corners) = view.source_corners(&candidate.as_hit()) else { return true };
        let Some(primitive) = self.primitive(corners.range.mesh_index, corners.range.primitive_index) else {
            return true;
        };
        let alpha = self.alpha(primitive, &corners);
        match primitive.test {
            AlphaTest::Mask { cutoff } => alpha >= cutoff,
            AlphaTest::Blend => blend_threshold(candidate) < alpha,
        }
    }

    /// Alpha at the hit: factor x nearest texel at the interpolated texture coordinates x vertex alpha.
    fn alpha(&self, primitive: &PrimitiveAlpha, corners: &SourceCorners<'_>) -> f32 {
        let mut alpha = primitive.factor;
        if let Some((image, wrap, uvs)) = &primitive.texture
            && let (Some(image), Some(uv)) = (&self.images[*image], corners.interpolate(uvs))
        {
            alpha *= image.sample(uv, *wrap);
        }
        if let Some([vertex_alpha]) = primitive.vertex_alpha.as_ref().and_then(|a| corners.interpolate(a)) {
            alpha *= vertex_alpha;
        }
        alpha
    }
}

impl AlphaImage {
    /// The nearest texel's alpha in [0, 1] at texture coordinates `uv`, wrapped as the sampler says.
    fn sample(&self, uv: [f32; 2], wrap: [WrappingMode; 2]) -> f32 {
        let texel = |coordinate: f32, size: usize, wrap: WrappingMode| -> usize {
            let x = (coordinate * size as f32).floor();
            let n = size as f32;
            let wrapped = match wrap {
                WrappingMode::ClampToEdge => x.clamp(0.0, n - 1.0),
                WrappingMode::Repeat => x.rem_euclid(n),
                WrappingMode::MirroredRepeat => {
                    let period = x.rem_euclid(2.0 * n);
                    if period < n { period } else { 2.0 * n - 1.0 - period }
                }
            };
            // A NaN coordinate (a degenerate uv) lands on texel 0; `as` saturates.
            (wrapped as usize).min(size - 1)
        };
        let (x, y) = (texel(uv[0], self.width, wrap[0]), texel(uv[1], self.height, wrap[1]));
        f32::from(self.alpha[y * self.width + x]) / 255.0
    }
}

/// A uniform number in [0, 1) that depends only on the ray and the source triangle: stochastic transparency that gives
/// the same answer to the same candidate.
fn blend_threshold(candidate: &Candidate<'_>) -> f32 {
    let ray = candidate.ray;
    // The source triangle (the same in one- and two-level files of a scene) and its placement.
    let triangle = candidate.source_triangle_id.unwrap_or(candidate.triangle_index);
    let placement = candidate.instance_index.unwrap_or(u32::MAX);
    let mut hash = 0x9e37_79b9_7f4a_7c15u64 ^ u64::from(triangle) ^ (u64::from(placement) << 32);
    for value in ray.origin.iter().chain(&ray.direction) {
        hash = (hash ^ u64::from(value.to_bits())).wrapping_mul(0xff51_afd7_ed55_8ccd);
        hash ^= hash >> 32;
    }
    (hash >> 40) as f32 / (1u64 << 24) as f32
}

/// The bytes of a buffer or image URI: a file beside the glTF or a base64 data URI.
fn read_uri(folder: &Path, uri: &str) -> Result<Vec<u8>, String> {
    if let Some(data) = uri.strip_prefix("data:") {
        let (_, payload) = data.split_once(";base64,").ok_or("a data URI that is not base64")?;
        use base64::Engine;
        return base64::engine::general_purpose::STANDARD.decode(payload).map_err(|e| e.to_string());
    }
    let decoded = percent_encoding::percent_decode_str(uri).decode_utf8_lossy();
    std::fs::read(folder.join(decoded.as_ref())).map_err(|e| format!("{decoded}: {e}"))
}

/// The alpha channel of a glTF image: decoded from a PNG; 1 everywhere for a JPEG (which has none).
fn decode_alpha(buffers: &[Vec<u8>], folder: &Path, image: &gltf::Image<'_>) -> Result<AlphaImage, String> {
    let label = format!("image {}", image.index());
    let bytes = match image.source() {
        gltf::image::Source::Uri { uri, .. } => read_uri(folder, uri).map_err(|e| format!("{label}: {e}"))?,
        gltf::image::Source::View { view, .. } => {
            let buffer = buffers.get(view.buffer().index()).ok_or_else(|| format!("{label}: no buffer"))?;
            buffer
                .get(view.offset()..view.offset() + view.length())
                .ok_or_else(|| format!("{label}: its buffer view is out of range"))?
                .to_vec()
        }
    };
    if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        return Ok(AlphaImage { width: 1, height: 1, alpha: vec![255] });
    }
    if !bytes.starts_with(b"\x89PNG") {
        return Err(format!("{label}: not a PNG or JPEG, so its alpha cannot be read here"));
    }
    let mut decoder = png::Decoder::new(std::io::Cursor::new(bytes));
    decoder.set_transformations(png::Transformations::EXPAND | png::Transformations::STRIP_16);
    let mut reader = decoder.read_info().map_err(|e| format!("{label}: {e}"))?;
    let size = reader.output_buffer_size().ok_or_else(|| format!("{label}: too large"))?;
    let mut pixels = vec![0; size];
    let frame = reader.next_frame(&mut pixels).map_err(|e| format!("{label}: {e}"))?;
    let (width, height) = (frame.width as usize, frame.height as usize);
    let channels = match frame.color_type {
        png::ColorType::Rgba => 4,
        png::ColorType::GrayscaleAlpha => 2,
        _ => return Ok(AlphaImage { width: 1, height: 1, alpha: vec![255] }),
    };
    let alpha = pixels[..frame.buffer_size()].chunks_exact(channels).map(|p| p[channels - 1]).collect();
    Ok(AlphaImage { width, height, alpha })
}
