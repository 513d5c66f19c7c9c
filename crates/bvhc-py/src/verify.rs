//! `bvhc.verify(path)`: a file checked against every validity rule, from its path.

use pyo3::prelude::*;

use crate::errors::{InvalidFileError, loader};

/// Reads and verifies the file at `path`: every rule; raises naming the file and the first broken rule.
#[pyfunction]
pub fn verify(py: Python<'_>, path: std::path::PathBuf) -> PyResult<String> {
    let name = path.display().to_string();
    let file = py.detach(|| bvhc::loader::BvhFile::read(&path)).map_err(|e| loader(&e, e.for_file(&path)))?;
    let view = file.view();
    py.detach(|| view.verify()).map_err(|v| InvalidFileError::new_err(format!("{name}: invalid .bvh file: {v}")))?;
    let (major, minor) = view.version();
    Ok(format!(
        "{name}: valid .bvh {major}.{minor} ({} nodes, {} triangles, every rule V1-V{} holds)",
        view.nodes().len(),
        view.triangles().len(),
        bvhc::loader::Rule::ALL.len()
    ))
}
