//! Wavefront OBJ with tobj: every model (each `o`, `g` and material change starts one), polygons triangulated
//! (concave ones by ear clipping), negative indices resolved by tobj. `.mtl` files are never read: geometry
//! does not need them, and a missing one is not an error.

use super::obj_text::checked_text;
use super::polygon::triangulate;
use super::soup::{Provenance, SoupBuilder};
use super::{ImportLimits, Located};

pub(super) fn read(bytes: &[u8], limits: &ImportLimits, builder: &mut SoupBuilder) -> Result<(), Located> {
    let text = checked_text(bytes, limits)?;
    let bytes: &[u8] = &text;
    let options =
        tobj::LoadOptions { single_index: false, triangulate: false, ignore_points: true, ignore_lines: true };
    let (models, _materials) = tobj::load_obj_buf(&mut &bytes[..], &options, |_| Err(tobj::LoadError::OpenFileFailed))
        .map_err(|e| locate_error(bytes, e))?;
    let corners = face_corner_vertices(bytes);
    let mut corners_used = 0usize;
    let mut triangles = Vec::new();
    for (m, model) in models.iter().enumerate() {
        let mesh = &model.mesh;
        if mesh.positions.iter().any(|c| !c.is_finite()) {
            let location = first_non_finite_vertex(bytes).unwrap_or_else(|| format!("model {m}"));
            return Err(Located::new(&location, "vertex position is not finite".to_string()));
        }
        let source: Vec<[f64; 3]> = mesh.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect();
        let positions: Vec<[f32; 3]> = source.iter().map(|p| p.map(|c| c as f32)).collect();
        if let Some(i) = positions.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            let location = first_non_finite_vertex(bytes).unwrap_or_else(|| format!("model {m}"));
            return Err(Located::new(&location, format!("vertex position {:?} is not finite in f32", source[i])));
        }
        let vertex_count = positions.len();
        triangles.clear();
        let mut start = 0usize;
        let implicit_triangles = if mesh.face_arities.is_empty() { mesh.indices.len() / 3 } else { 0 };
        let arities = mesh.face_arities.iter().copied().chain(std::iter::repeat_n(3, implicit_triangles));
        for arity in arities {
            let end = start + arity as usize;
            let Some(polygon) = mesh.indices.get(start..end) else { break };
            if polygon.iter().any(|&v| v as usize >= vertex_count) {
                return Err(Located::new(
                    &format!("model {m} ('{}')", model.name),
                    "face vertex index out of range".to_string(),
                ));
            }
            triangulate(polygon, &positions, &mut triangles);
            start = end;
        }
        let file_vertex = file_vertex_numbers(&mesh.indices, vertex_count, &corners, &mut corners_used)
            .map_err(|e| Located::new(&format!("model {m} ('{}')", model.name), e))?;
        let provenance = Provenance { mesh_index: m as u32, ..Provenance::NONE };
        builder
            .add_mesh_in_place(provenance, &source, &positions, &triangles, Some(&file_vertex))
            .map_err(|(kind, e)| Located::of_kind(kind, &format!("model {m}"), e))?;
    }
    // tobj keeps only the vertices each model uses; count the file's unused ones from its text.
    builder.report.unreferenced_vertices = unreferenced_vertices(bytes);
    Ok(())
}

/// The `v` record (counted from 0, relative indices resolved) of every corner of every face, in file order, as
/// tobj reads them: `f` and `l` records of three or more corners (tobj takes those as polygons; shorter ones are
/// the points and lines it ignores here), the first number of each `v/vt/vn` corner. Corners that do not parse
/// give `u32::MAX` (tobj refuses such files first).
fn face_corner_vertices(bytes: &[u8]) -> Vec<u32> {
    let mut corners = Vec::new();
    let mut vertex_count = 0i64;
    for line in bytes.split(|&b| b == b'\n') {
        // Words split at tobj's whitespace: `char::is_whitespace`, on ASCII lines without decoding them.
        if line.is_ascii() {
            let words =
                line.split(|&b| matches!(b, b' ' | b'\t' | b'\r' | b'\x0b' | b'\x0c')).filter(|w| !w.is_empty());
            read_record(words, &mut vertex_count, &mut corners);
        } else {
            let text = std::str::from_utf8(line).unwrap_or_default();
            read_record(text.split_whitespace().map(str::as_bytes), &mut vertex_count, &mut corners);
        }
    }
    corners
}

/// One line's words: a `v` record counts, an `f` or `l` record of three or more corners adds their `v` records.
fn read_record<'a>(mut words: impl Iterator<Item = &'a [u8]>, vertex_count: &mut i64, corners: &mut Vec<u32>) {
    match words.next() {
        Some(b"v") => *vertex_count += 1,
        Some(b"f" | b"l") => {
            let first = corners.len();
            corners.extend(words.map(|word| {
                let number = word.split(|&b| b == b'/').next().and_then(|n| std::str::from_utf8(n).ok());
                let resolved =
                    number.and_then(|n| n.parse::<i64>().ok()).map(|n| if n < 0 { *vertex_count + n } else { n - 1 });
                resolved.and_then(|v| u32::try_from(v).ok()).unwrap_or(u32::MAX)
            }));
            // One or two corners are a point or a line, which tobj skips.
            if (1..3).contains(&(corners.len() - first)) {
                corners.truncate(first);
            }
        }
        _ => {}
    }
}

/// For each vertex of a tobj model (numbered in the order its faces first use them), the file's `v` record:
/// the model's corners `indices` are the next `indices.len()` of the file's `corners`, from `*used` on. Fails
/// when one model vertex would be two records (the corners do not line up with tobj's).
fn file_vertex_numbers(
    indices: &[u32],
    vertex_count: usize,
    corners: &[u32],
    used: &mut usize,
) -> Result<Vec<u32>, String> {
    let mut numbers = vec![u32::MAX; vertex_count];
    let mismatch = || "the faces' corners could not be matched to their v records".to_string();
    let file_corners = corners.get(*used..*used + indices.len()).ok_or_else(mismatch)?;
    for (&local, &record) in indices.iter().zip(file_corners) {
        let slot = numbers.get_mut(local as usize).ok_or_else(mismatch)?;
        if *slot != u32::MAX && *slot != record {
            return Err(mismatch());
        }
        *slot = record;
    }
    *used += indices.len();
    Ok(numbers)
}

/// tobj's errors carry no line number; find the first line that breaks the same rule.
fn locate_error(bytes: &[u8], error: tobj::LoadError) -> Located {
    let message = format!("malformed OBJ: {error}");
    let mut vertex_count = 0i64;
    for (n, line) in String::from_utf8_lossy(bytes).lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                if words.by_ref().take(3).filter(|w| w.parse::<f32>().is_ok()).count() < 3 {
                    return Located::new(&format!("line {}", n + 1), message);
                }
                vertex_count += 1;
            }
            Some("f") => {
                let bad = words.any(|w| {
                    let index = w.split('/').next().and_then(|i| i.parse::<i64>().ok());
                    !index.is_some_and(|i| (i > 0 && i <= vertex_count) || (i < 0 && -i <= vertex_count))
                });
                if bad {
                    return Located::new(&format!("line {}", n + 1), message);
                }
            }
            _ => {}
        }
    }
    Located::new("file", message)
}

/// The line of the first vertex whose position does not parse to a finite f32 ("nan", "inf", "1e39").
fn first_non_finite_vertex(bytes: &[u8]) -> Option<String> {
    let text = String::from_utf8_lossy(bytes);
    text.lines().enumerate().find_map(|(n, line)| {
        let mut words = line.split_whitespace();
        let bad = words.next() == Some("v") && words.take(3).any(|w| w.parse::<f32>().is_ok_and(|v| !v.is_finite()));
        bad.then(|| format!("line {}", n + 1))
    })
}

/// Vertices (`v` records) that no face (`f` record) refers to.
fn unreferenced_vertices(bytes: &[u8]) -> u64 {
    let mut referenced: Vec<bool> = Vec::new();
    for line in bytes.split(|&b| b == b'\n') {
        match line {
            [b'v', b' ' | b'\t', ..] => referenced.push(false),
            [b'f', b' ' | b'\t', rest @ ..] => {
                for token in rest.split(|b| b.is_ascii_whitespace()).filter(|t| !t.is_empty()) {
                    let first = token.split(|&b| b == b'/').next().unwrap_or(&[]);
                    let Some(index) = std::str::from_utf8(first).ok().and_then(|t| t.parse::<i64>().ok()) else {
                        continue;
                    };
                    let count = referenced.len() as i64;
                    let resolved = if index < 0 { count + index } else { index - 1 };
                    if let Some(slot) = usize::try_from(resolved).ok().and_then(|i| referenced.get_mut(i)) {
                        *slot = true;
                    }
                }
            }
            _ => {}
        }
    }
    referenced.iter().filter(|&&r| !r).count() as u64
}
