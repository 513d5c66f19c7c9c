//! The conversion pipeline as it stands: import -> binned SAH build -> pack -> write.
//!
//! The optimizer (issue #4) and the full command line and build-script API (issue #5) extend this module.

use std::path::{Path, PathBuf};

use bvhc_loader::{BvhWriter, SourceRange, format::NO_INDEX};

use crate::build::build_binned_sah;
use crate::import::import;
use crate::pack::pack;

/// Largest leaf the initial builder makes.
pub const DEFAULT_MAX_LEAF_SIZE: usize = 4;

/// What a conversion produced.
#[derive(Clone, Debug, PartialEq)]
pub struct ConvertReport {
    /// The output file.
    pub output: PathBuf,
    /// Triangles written.
    pub triangle_count: usize,
    /// Nodes written.
    pub node_count: usize,
    /// Bytes written.
    pub file_byte_len: usize,
}

/// Why a conversion failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConvertError {
    /// The input could not be imported.
    #[error(transparent)]
    Import(#[from] crate::import::ImportError),
    /// The output could not be written.
    #[error(transparent)]
    Write(#[from] bvhc_loader::Error),
    /// The scene has more triangles than the format's u32 indices allow.
    #[error("{}: {count} triangles exceed the .bvh limit of 2^32 - 1", path.display())]
    TooLarge {
        /// The input.
        path: PathBuf,
        /// Its triangle count.
        count: usize,
    },
}

/// Converts `input` into the `.bvh` file `output`, written atomically.
pub fn convert(input: &Path, output: &Path) -> Result<ConvertReport, ConvertError> {
    let soup = import(input)?;
    let triangles = soup.triangle_vertices();
    let count = u32::try_from(triangles.len())
        .map_err(|_| ConvertError::TooLarge { path: input.to_path_buf(), count: triangles.len() })?;
    let packed = pack(&build_binned_sah(&triangles, DEFAULT_MAX_LEAF_SIZE), &triangles);
    let ranges = [SourceRange {
        first_source_triangle: 0,
        source_triangle_count: count,
        file_index: 0,
        node_index: NO_INDEX,
        mesh_index: NO_INDEX,
        primitive_index: NO_INDEX,
        instance_index: NO_INDEX,
        reserved: 0,
    }];
    let metadata = metadata_json(input);
    let mut writer = BvhWriter::new(&packed.nodes, &packed.triangles).triangle_ids(&packed.triangle_ids);
    if count > 0 {
        writer = writer.source_table(&ranges);
    }
    let file = writer.metadata(&metadata).write_atomic(output)?;
    Ok(ConvertReport {
        output: output.to_path_buf(),
        triangle_count: packed.triangles.len(),
        node_count: packed.nodes.len(),
        file_byte_len: file.as_bytes().len(),
    })
}

/// The metadata object: generator, format version, input file name (never a path), build options.
fn metadata_json(input: &Path) -> String {
    let file_name = input.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    serde_json::json!({
        "generator": concat!("bvhc ", env!("CARGO_PKG_VERSION")),
        "format_version": format!("{}.{}", bvhc_loader::format::VERSION_MAJOR, bvhc_loader::format::VERSION_MINOR),
        "inputs": [{ "file_name": file_name }],
        "build": { "builder": "binned_sah", "max_leaf_size": DEFAULT_MAX_LEAF_SIZE },
    })
    .to_string()
}
