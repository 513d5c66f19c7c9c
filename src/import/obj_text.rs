//! Checks and normalization of an OBJ file's text before tobj parses it, so that bad text is named by line and
//! cause rather than by tobj's generic "read error", and hostile counts are refused before tobj allocates:
//! a UTF-8 byte order mark is skipped; CR-only line ends (classic Mac) become LF; a NUL byte (a binary file,
//! or zeros) and invalid UTF-8 are errors naming the line; `v` records count against the decoded-values
//! budget and each `f` record's vertices against the polygon limit.

use std::borrow::Cow;

use super::limits::limit_message;
use super::{ErrorKind, ImportLimits, Located};

const BOM: &[u8] = b"\xEF\xBB\xBF";

/// The text tobj should parse: `bytes` without a BOM and with CR-only line ends turned into LF.
pub(super) fn checked_text<'a>(bytes: &'a [u8], limits: &ImportLimits) -> Result<Cow<'a, [u8]>, Located> {
    let bytes = bytes.strip_prefix(BOM).unwrap_or(bytes);
    let text: Cow<'a, [u8]> = if has_lone_cr(bytes) {
        Cow::Owned(
            bytes
                .iter()
                .enumerate()
                .map(|(i, &b)| if b == b'\r' && bytes.get(i + 1) != Some(&b'\n') { b'\n' } else { b })
                .collect(),
        )
    } else {
        Cow::Borrowed(bytes)
    };
    let mut vertex_values = 0u64;
    for (n, line) in text.split(|&b| b == b'\n').enumerate() {
        let at = || format!("line {}", n + 1);
        if let Some(column) = line.iter().position(|&b| b == 0) {
            return Err(Located::new(&at(), format!("NUL byte at column {}: this is not a text OBJ file", column + 1)));
        }
        if let Err(e) = std::str::from_utf8(line) {
            let column = e.valid_up_to() + 1;
            let byte = line[e.valid_up_to()];
            return Err(Located::new(
                &at(),
                format!("not valid UTF-8 (byte 0x{byte:02X} at column {column}); OBJ files are read as UTF-8 text"),
            ));
        }
        match line {
            [b'v', b' ' | b'\t', ..] => vertex_values += 3,
            [b'f', b' ' | b'\t', rest @ ..] => {
                let corners = rest.split(|b| b.is_ascii_whitespace()).filter(|t| !t.is_empty()).count() as u64;
                if corners > limits.max_polygon_vertices {
                    let message = limit_message(
                        corners,
                        limits.max_polygon_vertices,
                        "polygon vertices",
                        "--max-polygon-vertices",
                    );
                    return Err(Located::of_kind(ErrorKind::Limit, &at(), message));
                }
            }
            _ => {}
        }
    }
    if vertex_values > limits.max_decoded_values {
        let message =
            limit_message(vertex_values, limits.max_decoded_values, "vertex coordinates", "--max-decoded-values");
        return Err(Located::of_kind(ErrorKind::Limit, "v records", message));
    }
    Ok(text)
}

/// Whether some CR is not followed by LF.
fn has_lone_cr(bytes: &[u8]) -> bool {
    bytes.iter().enumerate().any(|(i, &b)| b == b'\r' && bytes.get(i + 1) != Some(&b'\n'))
}
