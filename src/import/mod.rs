//! Scene import: a file -> a [`TriangleSoup`] of world-space f32 triangles.
//!
//! This first version reads PLY (ASCII and binary, polygon faces fanned) and OBJ (tobj), plain or gzipped, which
//! is what the loader's real-scene tests and benchmarks need. glTF, provenance and the full error reporting of
//! issue #3 build on this module.

mod obj;
mod ply;

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};

use flate2::read::GzDecoder;

/// Triangles as indices into a shared vertex array, in the scene's world space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleSoup {
    /// Vertex positions.
    pub positions: Vec<[f32; 3]>,
    /// Vertex indices of each triangle, counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
}

impl TriangleSoup {
    /// The three vertex positions of triangle `i`.
    pub fn vertices(&self, i: usize) -> [[f32; 3]; 3] {
        self.triangles[i].map(|v| self.positions[v as usize])
    }

    /// Every triangle's vertex positions, in order.
    pub fn triangle_vertices(&self) -> Vec<[[f32; 3]; 3]> {
        (0..self.triangles.len()).map(|i| self.vertices(i)).collect()
    }
}

/// Why a scene could not be imported; names the file and what is wrong with it.
#[derive(Debug, thiserror::Error)]
#[error("{}: {message}", path.display())]
pub struct ImportError {
    /// The file.
    pub path: PathBuf,
    /// What is wrong, and where in the file.
    pub message: String,
}

/// Imports the scene at `path`; the format follows the extension (`.ply`, `.obj`, each optionally `.gz`).
pub fn import(path: &Path) -> Result<TriangleSoup, ImportError> {
    let error = |message: String| ImportError { path: path.to_path_buf(), message };
    let name = path.file_name().map(|n| n.to_string_lossy().to_lowercase()).unwrap_or_default();
    let (stem, gzipped) = match name.strip_suffix(".gz") {
        Some(stem) => (stem.to_string(), true),
        None => (name.clone(), false),
    };
    let file = File::open(path).map_err(|e| error(format!("cannot open: {e}")))?;
    let mut reader: Box<dyn BufRead> = if gzipped {
        Box::new(BufReader::with_capacity(1 << 16, GzDecoder::new(file)))
    } else {
        Box::new(BufReader::with_capacity(1 << 16, file))
    };
    let soup = if stem.ends_with(".ply") {
        ply::read(&mut reader)
    } else if stem.ends_with(".obj") {
        obj::read(&mut reader)
    } else {
        Err(format!("unsupported file type '{name}' (expected .ply, .obj, optionally gzipped)"))
    };
    soup.and_then(check_soup).map_err(error)
}

/// Checks indices and positions of a freshly read soup.
fn check_soup(soup: TriangleSoup) -> Result<TriangleSoup, String> {
    let vertex_count = soup.positions.len();
    if let Some((i, t)) = soup.triangles.iter().enumerate().find(|(_, t)| t.iter().any(|&v| v as usize >= vertex_count))
    {
        return Err(format!("triangle {i}: vertex index in {t:?} out of range ({vertex_count} vertices)"));
    }
    if let Some((i, p)) = soup.positions.iter().enumerate().find(|(_, p)| !p.iter().all(|c| c.is_finite())) {
        return Err(format!("vertex {i}: position {p:?} is not finite"));
    }
    Ok(soup)
}

/// Reads everything from `reader` (used by readers whose crate wants a byte slice).
fn read_all(reader: &mut dyn Read) -> Result<Vec<u8>, String> {
    let mut bytes = Vec::new();
    reader.read_to_end(&mut bytes).map_err(|e| format!("read failed: {e}"))?;
    Ok(bytes)
}

/// Fans a polygon's vertex indices into triangles (convex polygons; concave ones are issue #3's).
fn fan(polygon: &[u32], triangles: &mut Vec<[u32; 3]>) {
    for k in 2..polygon.len() {
        triangles.push([polygon[0], polygon[k - 1], polygon[k]]);
    }
}
