//! glTF buffers and accessors: loading buffers (GLB chunk, base64 `data:` URI, external file) on first use,
//! and decoding any accessor to f64 values: every component type, normalized or not (KHR_mesh_quantization),
//! any byte stride, sparse substitution. Every offset and length read from the file is checked before use.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::rc::Rc;

use base64::Engine;

use crate::import::limits::{Meter, limit_message, read_prefix, read_regular_file};
use crate::import::{ErrorKind, ImportOptions, Problem};
use gltf::json::accessor::{ComponentType, Type};
use gltf::json::validation::Checked;
use gltf::json::{self, Root};

/// An accessor's values as f64, `components` per element.
#[derive(Debug)]
pub(super) struct Decoded {
    /// Components per element (1 for SCALAR, 3 for VEC3, ...).
    pub components: usize,
    /// `count * components` values, element after element.
    pub values: Vec<f64>,
}

impl Decoded {
    pub(super) fn count(&self) -> usize {
        self.values.len().checked_div(self.components).unwrap_or(0)
    }
}

/// Buffers loaded so far and accessors decoded so far, for one glTF file.
pub(super) struct Buffers<'a> {
    root: &'a Root,
    base_dir: PathBuf,
    glb_bin: Option<&'a [u8]>,
    loaded: Vec<Option<Rc<Vec<u8>>>>,
    decoded: HashMap<usize, Rc<Decoded>>,
    /// External buffer files read, in the order they were read.
    pub files_read: Vec<PathBuf>,
    /// Values decoded so far against [`ImportLimits::max_decoded_values`](crate::import::ImportLimits).
    decoded_budget: Meter,
    max_input_bytes: u64,
    allow_outside: bool,
    /// The most values an accessor without a bufferView may declare: its elements are zeros, so no buffer bounds
    /// its count (an eighth of the decoded-values limit, as `plan.rs` holds their sum to).
    max_zero_filled: u64,
}

impl<'a> Buffers<'a> {
    pub(super) fn new(root: &'a Root, gltf_path: &Path, glb_bin: Option<&'a [u8]>, options: &ImportOptions) -> Self {
        let base_dir = gltf_path.parent().map(Path::to_path_buf).unwrap_or_default();
        Buffers {
            root,
            base_dir,
            glb_bin,
            loaded: vec![None; root.buffers.len()],
            decoded: HashMap::new(),
            files_read: Vec::new(),
            decoded_budget: Meter::new(options.limits.max_decoded_values, "accessor values", "--max-decoded-values"),
            max_input_bytes: options.limits.max_input_bytes,
            allow_outside: options.allow_buffers_outside_input_folder,
            max_zero_filled: options.limits.max_decoded_values / 8,
        }
    }

    /// The `count` accessor `index` declares, before anything is decoded.
    pub(super) fn declared_count(&self, index: usize) -> Option<u64> {
        self.root.accessors.get(index).map(|a| a.count.0)
    }

    /// The bytes of buffer `index` (at least its `byteLength`), loaded on first use.
    fn buffer(&mut self, index: usize) -> Result<Rc<Vec<u8>>, Problem> {
        let at = format!("buffer {index}");
        let Some(buffer) = self.root.buffers.get(index) else {
            return Err(format!("{at} does not exist (the file has {} buffers)", self.root.buffers.len()).into());
        };
        if let Some(Some(bytes)) = self.loaded.get(index) {
            return Ok(Rc::clone(bytes));
        }
        let bytes = match &buffer.uri {
            None => match self.glb_bin {
                Some(bin) if index == 0 => bin.to_vec(),
                _ => return Err(format!("{at} has no uri and is not the binary chunk of a GLB file").into()),
            },
            Some(uri) if uri.starts_with("data:") => decode_data_uri(uri).map_err(|e| format!("{at}: {e}"))?,
            Some(uri) => self.read_external(uri, buffer.byte_length.0).map_err(|e| e.prefixed(&format!("{at}: ")))?,
        };
        let declared = buffer.byte_length.0;
        if (bytes.len() as u64) < declared {
            return Err(format!("{at}: byteLength is {declared} but only {} bytes are available", bytes.len()).into());
        }
        let bytes = Rc::new(bytes);
        self.loaded[index] = Some(Rc::clone(&bytes));
        Ok(bytes)
    }

    /// Reads at most `byte_len` bytes of the file a relative `uri` names. Only regular files under the glTF
    /// file's folder are read (after resolving `..` and symbolic links), unless the options allow more.
    fn read_external(&mut self, uri: &str, byte_len: u64) -> Result<Vec<u8>, Problem> {
        if uri.contains("://") {
            return Err(format!("uri '{uri}' is not a relative file path; bvhc reads local files only").into());
        }
        let decoded = percent_encoding::percent_decode_str(uri)
            .decode_utf8()
            .map_err(|_| format!("uri '{uri}' is not valid percent-encoded UTF-8"))?;
        let relative = Path::new(decoded.as_ref());
        if !self.allow_outside && (relative.has_root() || relative.is_absolute()) {
            return Err(Problem::of_kind(
                ErrorKind::Unreadable,
                format!(
                    "uri '{uri}' is an absolute path; buffers are read only from the input's folder (--allow-outside-buffers allows more)"
                ),
            ));
        }
        let path = self.base_dir.join(relative);
        if !self.allow_outside {
            let folder = std::fs::canonicalize(if self.base_dir.as_os_str().is_empty() {
                Path::new(".")
            } else {
                &self.base_dir
            })
            .map_err(|e| unreadable(format!("cannot read the input's folder: {e}")))?;
            let resolved =
                std::fs::canonicalize(&path).map_err(|e| unreadable(format!("cannot read {}: {e}", path.display())))?;
            if !resolved.starts_with(&folder) {
                return Err(unreadable(format!(
                    "uri '{uri}' leaves the input's folder; buffers are read only from there (--allow-outside-buffers allows more)"
                )));
            }
        }
        if byte_len > self.max_input_bytes {
            return Err(Problem::limit(limit_message(
                byte_len,
                self.max_input_bytes,
                "bytes (byteLength)",
                "--max-input-bytes",
            )));
        }
        let bytes = match read_regular_file(&path, false, byte_len) {
            Ok(bytes) => bytes,
            // A file longer than byteLength: read its first byteLength bytes, as a glTF reader does.
            Err(e) if e.kind() == ErrorKind::Limit => {
                read_prefix(&path, byte_len).map_err(|m| unreadable(format!("{}: {m}", path.display())))?
            }
            Err(e) => return Err(Problem::of_kind(e.kind(), format!("{}: {}", path.display(), e.message()))),
        };
        self.files_read.push(path);
        Ok(bytes)
    }

    /// Accessor `index` decoded to f64 (cached: a mesh placed many times is decoded once).
    pub(super) fn accessor(&mut self, index: usize) -> Result<Rc<Decoded>, Problem> {
        if let Some(decoded) = self.decoded.get(&index) {
            return Ok(Rc::clone(decoded));
        }
        let decoded = Rc::new(self.decode(index).map_err(|e| e.prefixed(&format!("accessor {index}: ")))?);
        self.decoded.insert(index, Rc::clone(&decoded));
        Ok(decoded)
    }

    fn decode(&mut self, index: usize) -> Result<Decoded, Problem> {
        let root = self.root;
        let accessor =
            root.accessors.get(index).ok_or_else(|| format!("does not exist ({} accessors)", root.accessors.len()))?;
        let Checked::Valid(kind) = accessor.type_ else { return Err("invalid type".to_string().into()) };
        let Checked::Valid(json::accessor::GenericComponentType(component)) = accessor.component_type else {
            return Err("invalid componentType".to_string().into());
        };
        let components = components_of(kind);
        let count = usize::try_from(accessor.count.0).map_err(|_| "count too large".to_string())?;
        self.decoded_budget.take((count as u64).saturating_mul(components as u64)).map_err(Problem::limit)?;
        let layout = Layout { component, components, normalized: accessor.normalized };
        let mut values = match accessor.buffer_view {
            Some(view) => {
                let offset = accessor.byte_offset.map_or(0, |o| o.0);
                self.read_view(view.value(), offset, count, &layout, true)?
            }
            None => {
                let len = count.checked_mul(components).filter(|&n| n as u64 <= self.max_zero_filled);
                let len = len.ok_or_else(|| {
                    Problem::limit(format!(
                        "count {count} is too large for an accessor without bufferView (at most {} values, an eighth \
                         of the decoded-values limit; raise it with --max-decoded-values)",
                        self.max_zero_filled
                    ))
                })?;
                let mut zeros = Vec::new();
                zeros.try_reserve_exact(len).map_err(|_| Problem::limit(format!("out of memory for {len} values")))?;
                zeros.resize(len, 0.0);
                zeros
            }
        };
        if let Some(sparse) = &accessor.sparse {
            self.apply_sparse(sparse, count, &layout, &mut values).map_err(|e| e.prefixed("sparse: "))?;
        }
        Ok(Decoded { components, values })
    }

    /// Reads `count` elements of `layout` from bufferView `view` starting `offset` bytes into it.
    fn read_view(
        &mut self,
        view: usize,
        offset: u64,
        count: usize,
        layout: &Layout,
        strided: bool,
    ) -> Result<Vec<f64>, Problem> {
        let root = self.root;
        let at = format!("bufferView {view}");
        let buffer_view = root.buffer_views.get(view).ok_or_else(|| format!("{at} does not exist"))?;
        let bytes = self.buffer(buffer_view.buffer.value()).map_err(|e| e.prefixed(&format!("{at}: ")))?;
        let view_start = buffer_view.byte_offset.map_or(0, |o| o.0);
        let view_len = buffer_view.byte_length.0;
        let view_end = view_start.checked_add(view_len).filter(|&end| end <= bytes.len() as u64).ok_or_else(|| {
            format!("{at}: bytes {view_start}..+{view_len} lie outside its buffer of {} bytes", bytes.len())
        })?;
        let element = layout.element_byte_len() as u64;
        let stride = match buffer_view.byte_stride.filter(|_| strided) {
            Some(stride) if (stride.0 as u64) < element => {
                return Err(
                    format!("{at}: byteStride {} is smaller than an element ({element} bytes)", stride.0).into()
                );
            }
            Some(stride) => stride.0 as u64,
            None => element,
        };
        if count > 0 {
            let needed = (count as u64 - 1)
                .checked_mul(stride)
                .and_then(|n| n.checked_add(offset))
                .and_then(|n| n.checked_add(element));
            if needed.is_none_or(|n| n > view_len) {
                return Err(format!(
                    "{count} elements of {element} bytes (stride {stride}) from byte {offset} do not fit in {at} ({view_len} bytes)"
                ).into());
            }
        }
        let data = &bytes[view_start as usize..view_end as usize];
        let mut values = Vec::new();
        let len = count * layout.components;
        values.try_reserve_exact(len).map_err(|_| Problem::limit(format!("out of memory for {len} values")))?;
        for i in 0..count {
            let start = offset as usize + i * stride as usize;
            for c in 0..layout.components {
                values.push(layout.read(data, start + c * layout.component_byte_len()));
            }
        }
        Ok(values)
    }

    fn apply_sparse(
        &mut self,
        sparse: &json::accessor::sparse::Sparse,
        count: usize,
        layout: &Layout,
        values: &mut [f64],
    ) -> Result<(), Problem> {
        let substitutions = usize::try_from(sparse.count.0).map_err(|_| "count too large".to_string())?;
        let Checked::Valid(index_type) = sparse.indices.component_type else {
            return Err("invalid indices componentType".to_string().into());
        };
        let index_layout = Layout { component: index_type.0, components: 1, normalized: false };
        let indices = self.read_view(
            sparse.indices.buffer_view.value(),
            sparse.indices.byte_offset.0,
            substitutions,
            &index_layout,
            false,
        )?;
        let replacements = self.read_view(
            sparse.values.buffer_view.value(),
            sparse.values.byte_offset.0,
            substitutions,
            layout,
            false,
        )?;
        let components = layout.components;
        for (k, &target) in indices.iter().enumerate() {
            let target = target as usize;
            if target >= count {
                return Err(format!("index {target} (substitution {k}) is not below count {count}").into());
            }
            values[target * components..(target + 1) * components]
                .copy_from_slice(&replacements[k * components..(k + 1) * components]);
        }
        Ok(())
    }
}

/// How one element is stored.
struct Layout {
    component: ComponentType,
    components: usize,
    normalized: bool,
}

impl Layout {
    fn component_byte_len(&self) -> usize {
        match self.component {
            ComponentType::I8 | ComponentType::U8 => 1,
            ComponentType::I16 | ComponentType::U16 => 2,
            ComponentType::U32 | ComponentType::F32 => 4,
        }
    }

    fn element_byte_len(&self) -> usize {
        self.component_byte_len() * self.components
    }

    /// One component at byte `at` of `data` (in bounds: checked by the caller), normalized as glTF says.
    fn read(&self, data: &[u8], at: usize) -> f64 {
        let bytes = &data[at..at + self.component_byte_len()];
        let n = self.normalized;
        match self.component {
            ComponentType::I8 => {
                let v = f64::from(bytes[0] as i8);
                if n { (v / 127.0).max(-1.0) } else { v }
            }
            ComponentType::U8 => {
                let v = f64::from(bytes[0]);
                if n { v / 255.0 } else { v }
            }
            ComponentType::I16 => {
                let v = f64::from(i16::from_le_bytes([bytes[0], bytes[1]]));
                if n { (v / 32767.0).max(-1.0) } else { v }
            }
            ComponentType::U16 => {
                let v = f64::from(u16::from_le_bytes([bytes[0], bytes[1]]));
                if n { v / 65535.0 } else { v }
            }
            ComponentType::U32 => f64::from(u32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]])),
            ComponentType::F32 => f64::from(f32::from_le_bytes([bytes[0], bytes[1], bytes[2], bytes[3]])),
        }
    }
}

pub(super) fn components_of(kind: Type) -> usize {
    match kind {
        Type::Scalar => 1,
        Type::Vec2 => 2,
        Type::Vec3 => 3,
        Type::Vec4 | Type::Mat2 => 4,
        Type::Mat3 => 9,
        Type::Mat4 => 16,
    }
}

/// Decodes `data:[<media type>];base64,<data>`.
fn decode_data_uri(uri: &str) -> Result<Vec<u8>, String> {
    let (header, data) = uri.split_once(',').ok_or("data URI without ','")?;
    if !header.ends_with(";base64") {
        return Err("data URI is not base64-encoded".to_string());
    }
    let engine = base64::engine::GeneralPurpose::new(
        &base64::alphabet::STANDARD,
        base64::engine::GeneralPurposeConfig::new()
            .with_decode_padding_mode(base64::engine::DecodePaddingMode::Indifferent),
    );
    engine.decode(data.trim()).map_err(|e| format!("data URI: invalid base64 ({e})"))
}

/// A buffer that could not be read (as opposed to one that breaks a rule).
fn unreadable(message: String) -> Problem {
    Problem::of_kind(ErrorKind::Unreadable, message)
}
