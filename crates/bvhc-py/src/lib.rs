//! The Python package's native module, `bvhc._native`: conversions through the library's option resolver, and
//! scenes traced from numpy arrays with the loader's kernels on all cores, the GIL released. The pure-Python
//! package in `python/bvhc` wraps it (numpy views of a file's sections, keyword options, progress).

mod batch;
mod core_hits;
mod errors;
mod filters;
mod hits;
mod options;
mod points;
mod rays;
mod refit;
mod scene;
mod tracing;
mod verify;

use pyo3::prelude::*;

/// `bvhc._native`.
#[pymodule]
#[pyo3(name = "_native")]
fn native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    errors::register(m)?;
    m.add_function(wrap_pyfunction!(options::convert, m)?)?;
    m.add_function(wrap_pyfunction!(options::resolve, m)?)?;
    m.add_function(wrap_pyfunction!(options::options_table, m)?)?;
    m.add_function(wrap_pyfunction!(batch::run_job, m)?)?;
    m.add_function(wrap_pyfunction!(verify::verify, m)?)?;
    m.add_class::<scene::Scene>()?;
    m.add(
        "FORMAT_VERSION",
        format!("{}.{}", bvhc::loader::format::VERSION_MAJOR, bvhc::loader::format::VERSION_MINOR),
    )?;
    m.add("RULE_COUNT", bvhc::loader::Rule::ALL.len())?;
    Ok(())
}
