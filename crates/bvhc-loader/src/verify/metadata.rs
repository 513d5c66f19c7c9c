//! Rules V23 and V26-V28 of `format-spec/bvh-1.md`: the metadata section is one JSON object in UTF-8 without a
//! byte order mark or NUL byte; source ranges name existing `inputs`; input names are never absolute paths;
//! `format_version` agrees with the header.

use crate::verify::json::{Map, Value};

use crate::error::{Rule, Violation, violation};
use crate::open::view::BvhView;

/// V23, V26, V27, V28. Without a metadata section only V26 applies (every `file_index` must then be 0).
pub(crate) fn verify_metadata(view: &BvhView<'_>) -> Result<(), Violation> {
    let metadata = parsed_metadata(view)?;
    let inputs = metadata.as_ref().and_then(|m| m.get("inputs")).and_then(Value::as_array);
    verify_file_indices(view, inputs.map_or(0, Vec::len), inputs.is_some())?;
    let Some(metadata) = &metadata else { return Ok(()) };
    for (i, input) in inputs.into_iter().flatten().enumerate() {
        if let Some(name) = input.get("file_name").and_then(Value::as_str)
            && is_absolute_path(name)
        {
            return Err(violation(
                Rule::AbsoluteFileName,
                format!("metadata inputs[{i}]: file_name '{name}' is an absolute path"),
            ));
        }
    }
    if let Some(stated) = metadata.get("format_version") {
        let (major, minor) = view.version();
        if stated.as_str() != Some(format!("{major}.{minor}").as_str()) {
            return Err(violation(
                Rule::FormatVersion,
                format!("metadata format_version {stated} but the header says {major}.{minor}"),
            ));
        }
    }
    Ok(())
}

/// The metadata section as a JSON object, `None` without one; V23 broken otherwise.
pub(crate) fn parsed_metadata(view: &BvhView<'_>) -> Result<Option<Map>, Violation> {
    match view.metadata_str() {
        None => Ok(None),
        Some(text) => parse(text?).map(Some),
    }
}

/// V23: one JSON object, no BOM, no NUL byte.
fn parse(text: &str) -> Result<Map, Violation> {
    if text.starts_with('\u{feff}') {
        return Err(violation(Rule::Metadata, "metadata section: starts with a byte order mark"));
    }
    if let Some(at) = text.bytes().position(|b| b == 0) {
        return Err(violation(Rule::Metadata, format!("metadata section: NUL byte at offset {at}")));
    }
    crate::verify::json::parse_object(text)
        .map_err(|e| violation(Rule::Metadata, format!("metadata section: not one JSON object ({e})")))
}

/// V26: `file_index < inputs.len()` when the metadata has `inputs`, else `file_index = 0`.
fn verify_file_indices(view: &BvhView<'_>, input_count: usize, has_inputs: bool) -> Result<(), Violation> {
    let bound = if has_inputs { input_count as u64 } else { 1 };
    for (i, range) in view.source_table().unwrap_or(&[]).iter().enumerate() {
        if u64::from(range.file_index) >= bound {
            let what = if has_inputs {
                format!("the metadata lists {input_count} inputs")
            } else {
                "without metadata inputs it must be 0".to_string()
            };
            return Err(violation(
                Rule::FileIndex,
                format!("source_table range {i}: file_index {} but {what}", range.file_index),
            ));
        }
    }
    Ok(())
}

/// Whether `name` is absolute on any common system: `/x`, `\x`, `//server`, or a drive letter `C:`.
pub(crate) fn is_absolute_path(name: &str) -> bool {
    let bytes = name.as_bytes();
    matches!(bytes.first(), Some(b'/' | b'\\'))
        || (bytes.len() >= 2 && bytes[0].is_ascii_alphabetic() && bytes[1] == b':')
}
