//! What an import read, as the metadata records it: each file's name relative to the main input's folder and
//! the hash of its bytes (`format-spec/bvh-1.md` 5.5, `inputs`; also a refit's `refit.inputs`).

use std::path::{Path, PathBuf};

use xxhash_rust::xxh3::xxh3_64;

/// One file read.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct InputEntry {
    /// Relative to the main input's folder, `/`-separated; never absolute.
    pub file_name: String,
    /// `xxh3-64:<16 hex digits>` of the file's bytes.
    pub content_hash: String,
}

/// `xxh3-64:<16 hex digits>` of a file's bytes.
pub fn content_hash(bytes: &[u8]) -> String {
    format!("xxh3-64:{:016x}", xxh3_64(bytes))
}

/// The `inputs` metadata entry of every file read: its name relative to the main input's directory (never an
/// absolute path) and its content hash.
pub fn input_entries(main_input: &Path, files_read: &[PathBuf]) -> std::io::Result<Vec<InputEntry>> {
    let base = main_input.parent().unwrap_or(Path::new(""));
    files_read
        .iter()
        .map(|file| {
            let bytes = std::fs::read(file)?;
            Ok(InputEntry { file_name: relative_name(base, file), content_hash: content_hash(&bytes) })
        })
        .collect()
}

/// `file` relative to `base` with `/` separators (`..` kept for a buffer beside the input's folder), or its
/// bare file name when no relative path exists (an absolute path, which never reaches the metadata).
pub(crate) fn relative_name(base: &Path, file: &Path) -> String {
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
