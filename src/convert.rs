//! The conversion pipeline as it stands: import -> binned SAH build -> pack -> write.
//!
//! The optimizer (issue #4) and the full command line and build-script API (issue #5) extend this module.

use std::path::{Path, PathBuf};

use bvhc_loader::BvhWriter;

use crate::build::build_binned_sah;
use crate::import::{ImportOptions, import};
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
    let soup = import(input, &ImportOptions::default())?.soup;
    let triangles = soup.triangle_vertices();
    u32::try_from(triangles.len())
        .map_err(|_| ConvertError::TooLarge { path: input.to_path_buf(), count: triangles.len() })?;
    let packed = pack(&build_binned_sah(&triangles, DEFAULT_MAX_LEAF_SIZE), &triangles);
    // The packer numbers triangles by their index in the soup; the file stores their source ids.
    let source_ids: Vec<u32> = packed.triangle_ids.iter().map(|&t| soup.source_ids[t as usize]).collect();
    let metadata = metadata_json(input);
    let file = BvhWriter::new(&packed.nodes, &packed.triangles)
        .triangle_ids(&source_ids)
        .source_table(&soup.sources)
        .metadata(&metadata)
        .write_atomic(output)?;
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
