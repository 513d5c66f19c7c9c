//! The files a conversion reads and writes: which inputs an output records and whether it is up to date
//! ("up to date means no work": it verifies, and its metadata records the same inputs by content hash, the same
//! options and the same format version as the conversion about to run), and whether two paths name one file (an
//! output must never overwrite an input).

use std::path::{Path, PathBuf};

use bvhc_loader::BvhFile;
use serde_json::Value;

use super::metadata::BuildRecord;
use super::report::ConvertError;
use crate::import::inputs::relative_name;
pub use crate::import::inputs::{content_hash, input_entries};

/// Whether `output` is a valid `.bvh` file whose metadata records `build` options equal to `build`, the
/// format version this writer gives such a build (1.1 with wide sections, 1.0 without), and inputs whose files
/// (resolved next to `main_input`) still have the recorded hashes.
pub fn is_up_to_date(output: &Path, main_input: &Path, build: &BuildRecord) -> bool {
    let build = build.to_value();
    let Ok(file) = BvhFile::read(output) else { return false };
    let view = file.view();
    if view.verify().is_err() {
        return false;
    }
    let Some(Ok(text)) = view.metadata_str() else { return false };
    let Ok(metadata) = serde_json::from_str::<Value>(text) else { return false };
    let minor = bvhc_loader::format::written_minor(bvhc_loader::format::MinorFeatures {
        wide: !build["wide"].is_null(),
        source_vertices: build["write_source_vertices"] == true,
        instances: metadata["two_level"].is_object(),
        gpu: build["gpu"].is_object(),
        triangle_flags: view.triangle_flags().is_some(),
    });
    let version = format!("{}.{minor}", bvhc_loader::format::VERSION_MAJOR);
    if metadata["format_version"] != Value::String(version) || metadata["build"] != build {
        return false;
    }
    let Some(inputs) = metadata["inputs"].as_array().filter(|inputs| !inputs.is_empty()) else { return false };
    let base = main_input.parent().unwrap_or(Path::new(""));
    let main_name = relative_name(base, main_input);
    inputs[0]["file_name"].as_str() == Some(main_name.as_str())
        && inputs.iter().all(|entry| {
            let (Some(name), Some(hash)) = (entry["file_name"].as_str(), entry["content_hash"].as_str()) else {
                return false;
            };
            std::fs::read(base.join(name)).is_ok_and(|bytes| content_hash(&bytes) == hash)
        })
}

/// Fails when `output` is (the same file as) one of `inputs`.
pub fn refuse_output_among(output: &Path, inputs: &[PathBuf]) -> Result<(), ConvertError> {
    match inputs.iter().find(|input| is_same_file(output, input)) {
        Some(input) => Err(ConvertError::OutputIsInput { output: output.to_path_buf(), input: input.clone() }),
        None => Ok(()),
    }
}

/// Whether two paths name the same existing file (same device and inode on Unix, so hard links and symbolic
/// links count; the same canonical path elsewhere).
pub fn is_same_file(a: &Path, b: &Path) -> bool {
    let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) else { return false };
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        ma.dev() == mb.dev() && ma.ino() == mb.ino()
    }
    #[cfg(not(unix))]
    {
        let _ = (ma, mb);
        matches!((std::fs::canonicalize(a), std::fs::canonicalize(b)), (Ok(x), Ok(y)) if x == y)
    }
}

/// The input files an existing output records, resolved next to `main_input` (empty when unreadable).
pub fn recorded_inputs(output: &Path, main_input: &Path) -> Vec<PathBuf> {
    let base = main_input.parent().unwrap_or(Path::new(""));
    let Ok(file) = BvhFile::read(output) else { return Vec::new() };
    let Some(Ok(text)) = file.view().metadata_str() else { return Vec::new() };
    let metadata: serde_json::Value = serde_json::from_str(text).unwrap_or_default();
    metadata["inputs"]
        .as_array()
        .map(|inputs| inputs.iter().filter_map(|e| e["file_name"].as_str()).map(|name| base.join(name)).collect())
        .unwrap_or_default()
}
