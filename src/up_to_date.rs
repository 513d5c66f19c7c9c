//! "Up to date means no work": an output is current when it verifies and its metadata records the same
//! inputs (by content hash), the same options and the same format version as the conversion about to run.

use std::path::{Path, PathBuf};

use bvhc_loader::BvhFile;
use serde_json::Value;
use xxhash_rust::xxh3::xxh3_64;

/// `xxh3-64:<16 hex digits>` of a file's bytes.
pub fn content_hash(bytes: &[u8]) -> String {
    format!("xxh3-64:{:016x}", xxh3_64(bytes))
}

/// The `inputs` metadata entry of every file read: its name relative to the main input's directory (never an
/// absolute path) and its content hash.
pub fn input_entries(main_input: &Path, files_read: &[PathBuf]) -> std::io::Result<Vec<Value>> {
    let base = main_input.parent().unwrap_or(Path::new(""));
    files_read
        .iter()
        .map(|file| {
            let bytes = std::fs::read(file)?;
            Ok(serde_json::json!({ "file_name": relative_name(base, file), "content_hash": content_hash(&bytes) }))
        })
        .collect()
}

/// `file` relative to `base` with `/` separators (`..` kept for a buffer beside the input's folder), or its
/// bare file name when no relative path exists (an absolute path, which never reaches the metadata).
fn relative_name(base: &Path, file: &Path) -> String {
    use std::path::Component;
    let relative = file.strip_prefix(base).unwrap_or(file);
    let is_relative =
        relative.components().all(|c| matches!(c, Component::Normal(_) | Component::CurDir | Component::ParentDir));
    let relative = if is_relative { relative } else { Path::new(file.file_name().unwrap_or_default()) };
    relative
        .components()
        .filter(|c| !matches!(c, Component::CurDir))
        .map(|c| c.as_os_str().to_string_lossy())
        .collect::<Vec<_>>()
        .join("/")
}

/// Whether `output` is a valid `.bvh` file whose metadata records `build` options equal to `build`, the
/// format version this writer gives such a build (1.1 with wide sections, 1.0 without), and inputs whose files (resolved next to `main_input`) still have the recorded hashes.
pub fn is_up_to_date(output: &Path, main_input: &Path, build: &Value) -> bool {
    let Ok(file) = BvhFile::read(output) else { return false };
    let view = file.view();
    if view.verify().is_err() {
        return false;
    }
    let Some(Ok(text)) = view.metadata_str() else { return false };
    let Ok(metadata) = serde_json::from_str::<Value>(text) else { return false };
    let minor = bvhc_loader::format::written_minor(!build["wide"].is_null());
    let version = format!("{}.{minor}", bvhc_loader::format::VERSION_MAJOR);
    if metadata["format_version"] != Value::String(version) || &metadata["build"] != build {
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
