//! Wavefront OBJ with tobj: every model (object, group, material run), faces fanned, `.mtl` files not read.

use std::io::BufRead;

use super::{TriangleSoup, fan, read_all};

pub(super) fn read(reader: &mut dyn BufRead) -> Result<TriangleSoup, String> {
    let bytes = read_all(reader)?;
    let options =
        tobj::LoadOptions { single_index: false, triangulate: false, ignore_points: true, ignore_lines: true };
    let (models, _materials) = tobj::load_obj_buf(&mut bytes.as_slice(), &options, |_| {
        Err(tobj::LoadError::OpenFileFailed) // materials are not needed for geometry
    })
    .map_err(|e| format!("OBJ: {e}"))?;
    let mut soup = TriangleSoup::default();
    for model in &models {
        let mesh = &model.mesh;
        let base = soup.positions.len() as u32;
        soup.positions.extend(mesh.positions.chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
        let mut start = 0usize;
        let arities: Vec<u32> =
            if mesh.face_arities.is_empty() { vec![3; mesh.indices.len() / 3] } else { mesh.face_arities.clone() };
        for arity in arities {
            let end = start + arity as usize;
            let polygon: Vec<u32> = mesh.indices.get(start..end).unwrap_or(&[]).iter().map(|&i| base + i).collect();
            fan(&polygon, &mut soup.triangles);
            start = end;
        }
    }
    Ok(soup)
}
