//! PLY (ASCII, binary little and big endian) with ply-rs-bw: `vertex` x/y/z, `face` vertex_indices (fanned).

use std::io::BufRead;

use ply_rs_bw::parser::{Parser, Reader};
use ply_rs_bw::ply::{DefaultElement, PropertyAccess, PropertyAccessResult};

use super::{TriangleSoup, fan};

#[derive(Default)]
struct Vertex([f32; 3]);

impl Vertex {
    fn set(&mut self, name: &str, value: f64) -> PropertyAccessResult {
        let axis = match name {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            _ => return PropertyAccessResult::Ignored,
        };
        self.0[axis] = value as f32;
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

/// An index as u32; negative or oversized ones become u32::MAX, which the soup's range check reports.
fn vertex_index(value: i64) -> u32 {
    u32::try_from(value).unwrap_or(u32::MAX)
}

/// Triangles of a strip: `(s[k], s[k+1], s[k+2])` with every second one flipped to keep the winding; -1
/// restarts the strip; triangles with a repeated index (the joins of stitched strips) are skipped.
fn strip_triangles(strip: &[i64], triangles: &mut Vec<[u32; 3]>) {
    for run in strip.split(|&v| v < 0) {
        for (k, w) in run.windows(3).enumerate() {
            let [a, b, c] = [w[0], w[1], w[2]].map(vertex_index);
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

pub(super) fn read(reader: &mut dyn BufRead) -> Result<TriangleSoup, String> {
    let mut reader = Reader::new(reader);
    let vertex_parser = Parser::<Vertex>::new();
    let header = vertex_parser.read_header(&mut reader).map_err(|e| format!("PLY header: {e}"))?;
    let mut soup = TriangleSoup::default();
    for (name, element) in &header.elements {
        match name.as_str() {
            "vertex" => {
                let vertices = vertex_parser
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(|e| format!("PLY element 'vertex': {e}"))?;
                soup.positions = vertices.into_iter().map(|v| v.0).collect();
            }
            "face" | "tristrips" => {
                let records = Parser::<Face>::new()
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(|e| format!("PLY element '{name}': {e}"))?;
                for record in records {
                    if name == "face" {
                        let polygon: Vec<u32> = record.0.iter().map(|&v| vertex_index(v)).collect();
                        fan(&polygon, &mut soup.triangles);
                    } else {
                        strip_triangles(&record.0, &mut soup.triangles);
                    }
                }
            }
            _ => {
                Parser::<DefaultElement>::new()
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(|e| format!("PLY element '{name}': {e}"))?;
            }
        }
    }
    Ok(soup)
}
