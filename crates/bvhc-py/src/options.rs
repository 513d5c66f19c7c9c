//! `convert` and `resolve`: keyword options, named as in the library's options table (the command line's flags
//! with `_` for `-`: `split_method`, `no_splits=True`; a `no_*` switch also by its positive name with a boolean,
//! `splits=False`), set through the library's [`Settings`], which parses and checks them exactly as it does the
//! command line's (the same refusals, the same messages), and then the same conversion (atomic output,
//! up-to-date skip).

use std::ops::ControlFlow;
use std::path::PathBuf;

use bvhc::Conversion;
use bvhc::convert::Event;
use bvhc::convert::metadata::BuildRecord;
use bvhc::options::{OptionValue, Settings};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict};

use crate::errors::OptionsError;

/// A Python value as an option's value: `bool`, `int`, `float`, `str` or a path (`os.PathLike`).
fn option_value(value: &Bound<'_, PyAny>) -> Option<OptionValue> {
    if let Ok(b) = value.cast::<PyBool>() {
        return Some(OptionValue::Bool(b.is_true()));
    }
    if let Ok(i) = value.extract::<i64>() {
        return Some(OptionValue::Int(i));
    }
    if let Ok(x) = value.extract::<f64>() {
        return Some(OptionValue::Number(x));
    }
    value.extract::<PathBuf>().ok().map(|p| OptionValue::Text(p.to_string_lossy().into_owned()))
}

/// `name=value: why`, the value as Python shows it.
fn refused(name: &str, value: &Bound<'_, PyAny>, error: bvhc::options::OptionsError) -> PyErr {
    let shown = value.repr().map_or_else(|_| "?".to_string(), |r| r.to_string());
    match error {
        bvhc::options::OptionsError::Invalid { why, .. } => OptionsError::new_err(format!("{name}={shown}: {why}")),
        other => OptionsError::new_err(other.to_string()),
    }
}

/// The settings of a preset and keyword options (the names of the options table, `bvhc.options_table()`); `None`
/// leaves the preset's choice, as a flag not given does. An unknown keyword or a value the option does not take
/// is refused, naming it.
pub(crate) fn settings(py: Python<'_>, preset: &str, options: Option<&Bound<'_, PyDict>>) -> PyResult<Settings> {
    let mut settings = Settings::default();
    let preset = preset.into_pyobject(py)?.into_any();
    let given = [(pyo3::types::PyString::new(py, "preset").into_any(), preset)];
    let keywords = options.into_iter().flat_map(|d| d.iter());
    for (key, value) in given.into_iter().chain(keywords) {
        let name: String = key.extract()?;
        if value.is_none() {
            continue;
        }
        let Some(given) = option_value(&value) else {
            let why = "expected a bool, a number, a string or a path".to_string();
            return Err(refused(&name, &value, bvhc::options::OptionsError::Invalid { setting: name.clone(), why }));
        };
        settings.set(&name, given).map_err(|e| refused(&name, &value, e))?;
    }
    Ok(settings)
}

/// The options table as JSON (`bvhc options --list --json`): each option's name (the keyword), flag, stage,
/// kind, choices, help, example value and what each preset sets.
#[pyfunction]
pub fn options_table() -> String {
    bvhc::options::listing::to_json().to_string()
}

/// The options a conversion would use, resolved and checked, as the JSON of the metadata's `build` object
/// (`bvhc options`).
#[pyfunction]
#[pyo3(signature = (preset, options=None))]
pub fn resolve(py: Python<'_>, preset: &str, options: Option<&Bound<'_, PyDict>>) -> PyResult<String> {
    let resolved = settings(py, preset, options)?.resolve().map_err(|e| OptionsError::new_err(e.to_string()))?;
    Ok(BuildRecord::of(&resolved).to_value().to_string())
}

/// Converts `src` into `dst`; returns the JSON of `bvhc --json`'s report (`up_to_date`, `files_read`,
/// `report`). `progress(stage, batch, cost, best_cost)` is called with the GIL held at each stage and optimizer
/// batch; an exception it raises cancels the optimization (the best tree so far is written) and is re-raised.
#[pyfunction]
#[allow(clippy::too_many_arguments)] // the Python signature's keywords
#[pyo3(signature = (src, dst, preset, options=None, force=false, threads=None, progress=None))]
pub fn convert(
    py: Python<'_>,
    src: PathBuf,
    dst: PathBuf,
    preset: &str,
    options: Option<&Bound<'_, PyDict>>,
    force: bool,
    threads: Option<usize>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<String> {
    let conversion = Conversion::new(&src, &dst).settings(settings(py, preset, options)?).force(force);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(crate::tracing::threads_keyword(threads)?.unwrap_or(0))
        .build()
        .map_err(|e| crate::errors::InternalError::new_err(format!("cannot start threads: {e}")))?;
    let callback: Option<Py<PyAny>> = progress.map(Bound::unbind);
    let mut raised: Option<PyErr> = None;
    // The conversion runs with the GIL released, on the pool; the callback takes the GIL for each event.
    let result = py.detach(|| {
        pool.install(|| match &callback {
            None => conversion.run(),
            Some(callback) => conversion.run_with_progress(&mut |event: Event<'_>| {
                if raised.is_some() {
                    return ControlFlow::Break(());
                }
                let call = Python::attach(|py| match event {
                    Event::Stage(stage) => {
                        let name = format!("{stage:?}").to_lowercase();
                        callback.call1(py, (name, py.None(), py.None(), py.None())).map(drop)
                    }
                    Event::Batch(p) => callback.call1(py, ("batch", p.batch, p.cost, p.best_cost)).map(drop),
                });
                match call {
                    Ok(()) => ControlFlow::Continue(()),
                    Err(error) => {
                        raised = Some(error);
                        ControlFlow::Break(())
                    }
                }
            }),
        })
    });
    if let Some(error) = raised {
        return Err(error);
    }
    let outcome = result.map_err(crate::errors::conversion)?;
    Ok(serde_json::json!({
        "output": dst,
        "up_to_date": outcome.up_to_date,
        "files_read": outcome.files_read,
        "report": outcome.report,
    })
    .to_string())
}
