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
    let line_of = |at: usize| format!("line {}", 1 + text[..at].iter().filter(|&&b| b == b'\n').count());
    let line_start = |at: usize| text[..at].iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
    // `contains` on bytes is a memchr; the position is looked up only when there is a NUL.
    if let Some(at) = text.contains(&0).then(|| text.iter().position(|&b| b == 0)).flatten() {
        let column = at - line_start(at) + 1;
        return Err(Located::new(&line_of(at), format!("NUL byte at column {column}: this is not a text OBJ file")));
    }
    if let Err(e) = std::str::from_utf8(&text) {
        let at = e.valid_up_to();
        let (byte, column) = (text[at], at - line_start(at) + 1);
        let message =
            format!("not valid UTF-8 (byte 0x{byte:02X} at column {column}); OBJ files are read as UTF-8 text");
        return Err(Located::new(&line_of(at), message));
    }
    let mut vertex_values = 0u64;
    // A face with more corners than the limit needs at least two bytes per corner: only longer lines are counted.
    let long_line = usize::try_from(limits.max_polygon_vertices).unwrap_or(usize::MAX).saturating_mul(2);
    for (n, line) in text.split(|&b| b == b'\n').enumerate() {
        match line {
            [b'v', b' ' | b'\t', ..] => vertex_values += 3,
            [b'f', b' ' | b'\t', rest @ ..] if line.len() > long_line => {
                let corners = rest.split(|b| b.is_ascii_whitespace()).filter(|t| !t.is_empty()).count() as u64;
                if corners > limits.max_polygon_vertices {
                    let message = limit_message(
                        corners,
                        limits.max_polygon_vertices,
                        "polygon vertices",
                        "--max-polygon-vertices",
                    );
                    return Err(Located::of_kind(ErrorKind::Limit, &format!("line {}", n + 1), message));
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
