//! PLY (ASCII, binary little and big endian) with ply-rs-bw: `vertex` x/y/z, `face` vertex_indices (fanned).

use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{DefaultElement, PropertyAccess, PropertyAccessResult};

use super::limits::limit_message;
use super::polygon::triangulate;
use super::soup::{Provenance, SoupBuilder};
use super::{ErrorKind, ImportLimits, Located};

#[derive(Default)]
struct Vertex([f64; 3]);

impl Vertex {
    fn set(&mut self, name: &str, value: f64) -> PropertyAccessResult {
        let axis = match name {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            _ => return PropertyAccessResult::Ignored,
        };
        self.0[axis] = value;
        PropertyAccessResult::Set
    }
}

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Vertex::default()
    }
    fn set_float(&mut self, name: &str, value: f32) -> PropertyAccessResult {
        self.set(name, f64::from(value))
    }
    fn set_double(&mut self, name: &str, value: f64) -> PropertyAccessResult {
        self.set(name, value)
    }
}

/// A `face` or `tristrips` record: its vertex index list as read (strips use -1 as a restart marker).
#[derive(Default)]
struct Face(Vec<i64>);

impl Face {
    fn set<T: Into<i64> + Copy>(&mut self, name: &str, values: &[T]) -> PropertyAccessResult {
        if name != "vertex_indices" && name != "vertex_index" {
            return PropertyAccessResult::Ignored;
        }
        self.0 = values.iter().map(|&v| v.into()).collect();
        PropertyAccessResult::Set
    }
}

/// Triangles of a strip: `(s[k], s[k+1], s[k+2])` with every second one flipped to keep the winding; -1
/// restarts the strip; triangles with a repeated index (the joins of stitched strips) are skipped.
fn strip_triangles(strip: &[i64], triangles: &mut Vec<[u32; 3]>) {
    for run in strip.split(|&v| v < 0) {
        for (k, w) in run.windows(3).enumerate() {
            let [a, b, c] = [w[0], w[1], w[2]].map(|v| v as u32); // checked by the caller
            if a == b || b == c || a == c {
                continue;
            }
            triangles.push(if k % 2 == 0 { [a, b, c] } else { [b, a, c] });
        }
    }
}

impl PropertyAccess for Face {
    fn new() -> Self {
        Face::default()
    }
    fn set_list_int(&mut self, name: &str, value: Vec<i32>) -> PropertyAccessResult {
        self.set(name, &value)
    }
    fn set_list_uint(&mut self, name: &str, value: Vec<u32>) -> PropertyAccessResult {
        self.set(name, &value)
    }
    fn set_list_ushort(&mut self, name: &str, value: Vec<u16>) -> PropertyAccessResult {
        self.set(name, &value)
    }
    fn set_list_short(&mut self, name: &str, value: Vec<i16>) -> PropertyAccessResult {
        self.set(name, &value)
    }
    fn set_list_uchar(&mut self, name: &str, value: Vec<u8>) -> PropertyAccessResult {
        self.set(name, &value)
    }
    fn set_list_char(&mut self, name: &str, value: Vec<i8>) -> PropertyAccessResult {
        self.set(name, &value)
    }
}

pub(super) fn read(bytes: &[u8], limits: &ImportLimits, builder: &mut SoupBuilder) -> Result<(), Located> {
    let mut reader = Reader::new(bytes);
    let vertex_parser = Parser::<Vertex>::new();
    let header =
        vertex_parser.read_header(&mut reader).map_err(|e| Located::new("header", format!("malformed PLY: {e}")))?;
    check_declared_counts(&header, bytes.len(), limits)?;
    let mut source: Vec<[f64; 3]> = Vec::new();
    let mut polygons: Vec<Vec<i64>> = Vec::new();
    let mut strips: Vec<Vec<i64>> = Vec::new();
    for (name, element) in &header.elements {
        let at = format!("element '{name}'");
        let malformed = |e: &dyn std::fmt::Display| Located::new(&at, format!("malformed PLY: {e}"));
        match name.as_str() {
            "vertex" => {
                let has_xyz = ["x", "y", "z"].iter().all(|p| element.properties.contains_key(*p));
                if !has_xyz {
                    return Err(Located::new(&at, "has no x, y and z properties".to_string()));
                }
                let vertices =
                    vertex_parser.read_payload_for_element(&mut reader, element, &header).map_err(|e| malformed(&e))?;
                source = vertices.into_iter().map(|v| v.0).collect();
            }
            "face" | "tristrips" => {
                let records = Parser::<Face>::new()
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(|e| malformed(&e))?;
                let target = if name == "face" { &mut polygons } else { &mut strips };
                target.extend(records.into_iter().map(|r| r.0));
            }
            _ => {
                Parser::<DefaultElement>::new()
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(|e| malformed(&e))?;
            }
        }
    }
    let positions: Vec<[f32; 3]> = source.iter().map(|p| p.map(|c| c as f32)).collect();
    if let Some(i) = positions.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(Located::new(&format!("vertex {i}"), format!("position {:?} is not finite in f32", source[i])));
    }
    let vertex_count = positions.len();
    let mut triangles = Vec::new();
    for (f, face) in polygons.iter().enumerate() {
        let polygon = checked_indices(face, vertex_count).map_err(|e| Located::new(&format!("face {f}"), e))?;
        if polygon.len() as u64 > limits.max_polygon_vertices {
            let message = limit_message(
                polygon.len() as u64,
                limits.max_polygon_vertices,
                "polygon vertices",
                "--max-polygon-vertices",
            );
            return Err(Located::of_kind(ErrorKind::Limit, &format!("face {f}"), message));
        }
        triangulate(&polygon, &positions, &mut triangles);
    }
    for (s, strip) in strips.iter().enumerate() {
        let valid: Vec<i64> = strip.iter().copied().filter(|&v| v >= 0).collect();
        checked_indices(&valid, vertex_count).map_err(|e| Located::new(&format!("tristrips {s}"), e))?;
        strip_triangles(strip, &mut triangles);
    }
    builder
        .add_mesh_in_place(Provenance::NONE, &source, &positions, &triangles, None)
        .map_err(|(kind, e)| Located::of_kind(kind, "faces", e))?;
    Ok(())
}

/// Checks the header's element counts before any payload is parsed (the parser reserves room for each record):
/// every record takes at least one byte of the file, vertices count against the decoded-values budget and
/// faces and strips against the triangle budget.
fn check_declared_counts(
    header: &ply_rs_bw::ply::Header,
    file_byte_len: usize,
    limits: &ImportLimits,
) -> Result<(), Located> {
    for (name, element) in &header.elements {
        let at = format!("element '{name}'");
        let count = element.count as u64;
        if count > file_byte_len as u64 {
            return Err(Located::new(
                &at,
                format!("declares {count} records but the file has only {file_byte_len} bytes"),
            ));
        }
        let (amount, limit, what, option) = match name.as_str() {
            "vertex" => {
                (count.saturating_mul(3), limits.max_decoded_values, "vertex coordinates", "--max-decoded-values")
            }
            "face" | "tristrips" => (count, limits.max_triangles, "faces", "--max-triangles"),
            _ => continue,
        };
        if amount > limit {
            return Err(Located::of_kind(ErrorKind::Limit, &at, limit_message(amount, limit, what, option)));
        }
    }
    Ok(())
}

/// Indices as u32, each below `vertex_count`.
fn checked_indices(indices: &[i64], vertex_count: usize) -> Result<Vec<u32>, String> {
    indices
        .iter()
        .map(|&v| {
            u32::try_from(v)
                .ok()
                .filter(|&v| (v as usize) < vertex_count)
                .ok_or_else(|| format!("vertex index {v} out of range ({vertex_count} vertices)"))
        })
        .collect()
}
