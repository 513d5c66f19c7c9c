//! `_native.run_job`: one job of `bvhc.convert_many` (a dict shaped as a `bvhc batch` manifest line, as JSON),
//! converted as `bvhc batch` converts each of its jobs (`bvhc::batch::run_one`), with the GIL released; its
//! report as JSON. A job that cannot be read (an unknown option, a bad value) is a failed report, not an
//! exception, so that one bad job never stops the others.

use std::path::Path;

use bvhc::batch::{JobReport, job_of_line, run_one};
use bvhc::options::Settings;
use pyo3::prelude::*;

/// Converts `job` (JSON: `{"input", "output", "options"}`, relative paths against the working directory); the
/// report's JSON.
#[pyfunction]
#[pyo3(signature = (job, force=false, threads=None))]
pub fn run_job(py: Python<'_>, job: &str, force: bool, threads: Option<usize>) -> PyResult<String> {
    let threads = crate::tracing::threads_keyword(threads)?.unwrap_or(0);
    let report = match job_of_line(job, Path::new(""), &Settings::default(), "job".to_string()) {
        Ok(job) => py.detach(|| run_one(&job, force, threads)),
        Err(bad) => JobReport::of_bad_job(&bad),
    };
    serde_json::to_string(&report).map_err(|e| crate::errors::InternalError::new_err(e.to_string()))
}
