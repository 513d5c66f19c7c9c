//! `convert` and `resolve`: keyword options, named as the command line's flags (`--split-method` is
//! `split_method`; the `--no-*` switches are booleans: `splits=False`), into the library's [`Overrides`], which
//! the library's resolver checks exactly as it checks the command line's (the same refusals, the same
//! messages), and then the same conversion (atomic output, up-to-date skip).

use std::ops::ControlFlow;
use std::path::PathBuf;

use bvhc::Conversion;
use bvhc::animation::Animation;
use bvhc::builders::Builder;
use bvhc::convert::Event;
use bvhc::convert::metadata::BuildRecord;
use bvhc::import::memory::MemoryLimit;
use bvhc::import::{ImportLimits, Instancing, Opacity, SceneSelector};
use bvhc::optimize::Selection;
use bvhc::options::{OptimizeOver, Overrides, Preset, SplitMethod, SplitTriangles, resolve as resolve_options};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString};

use crate::errors::OptionsError;

/// One keyword option's value, named in errors as the keyword.
struct Value<'a, 'py> {
    name: &'a str,
    value: Bound<'py, PyAny>,
}

impl Value<'_, '_> {
    fn error(&self, expected: &str) -> PyErr {
        let shown = self.value.repr().map_or_else(|_| "?".to_string(), |r| r.to_string());
        OptionsError::new_err(format!("{}={shown}: expected {expected}", self.name))
    }

    fn boolean(&self) -> PyResult<bool> {
        self.value.extract::<bool>().map_err(|_| self.error("True or False"))
    }

    fn count(&self) -> PyResult<u64> {
        // Not a bool (which is an int in Python).
        if self.value.is_instance_of::<pyo3::types::PyBool>() {
            return Err(self.error("a whole number"));
        }
        self.value.extract::<u64>().map_err(|_| self.error("a whole number from 0"))
    }

    fn number(&self) -> PyResult<f64> {
        self.value.extract::<f64>().ok().filter(|v| v.is_finite()).ok_or_else(|| self.error("a finite number"))
    }

    fn text(&self) -> PyResult<String> {
        self.value.extract::<String>().map_err(|_| self.error("a string"))
    }

    /// One of `choices` by the command line's name (`pre-split`; `pre_split` is accepted too).
    fn choice<T: Copy>(&self, choices: &[(&str, T)]) -> PyResult<T> {
        let names: Vec<&str> = choices.iter().map(|(n, _)| *n).collect();
        let expected = format!("one of {}", names.join(", "));
        let text = self.text().map_err(|_| self.error(&expected))?.replace('_', "-");
        choices.iter().find(|(n, _)| *n == text).map(|(_, v)| *v).ok_or_else(|| self.error(&expected))
    }
}

/// The preset by name.
fn preset(name: &str) -> PyResult<Preset> {
    Preset::ALL
        .into_iter()
        .find(|p| p.name() == name.replace('_', "-"))
        .ok_or_else(|| OptionsError::new_err(format!("preset={name:?}: expected one of fast, balanced, max-quality")))
}

/// The keyword options as overrides of the preset; an unknown keyword is refused, naming it.
fn overrides(options: Option<&Bound<'_, PyDict>>) -> PyResult<Overrides> {
    let mut o = Overrides::default();
    let mut limits = ImportLimits::default();
    let mut limits_given = false;
    let mut animation_poses = None;
    let mut animation_window = None;
    for (key, value) in options.into_iter().flat_map(|d| d.iter()) {
        let name: String = key.extract()?;
        let v = Value { name: &name, value };
        if v.value.is_none() {
            continue; // None leaves the preset's choice, as a flag not given does.
        }
        match name.as_str() {
            "scene" => {
                o.scene = Some(match v.value.extract::<usize>() {
                    Ok(index) if !v.value.is_instance_of::<pyo3::types::PyBool>() => SceneSelector::Index(index),
                    _ => SceneSelector::Name(v.text().map_err(|_| v.error("a scene index or name"))?),
                })
            }
            "pose" => {
                let text = match v.value.extract::<f64>() {
                    Ok(code) if !v.value.is_instance_of::<pyo3::types::PyBool>() => code.to_string(),
                    _ => v.text().map_err(|_| v.error("a pose 'CLIP@SECONDS' or a USD time code"))?,
                };
                let why = |why: String| v.error(&format!("a pose 'CLIP@SECONDS' or a USD time code ({why})"));
                o.pose = Some(text.parse().map_err(why)?)
            }
            "purposes" => {
                let text = v.text().map_err(|_| v.error("USD purposes 'render,proxy,guide'"))?;
                o.purposes = Some(text.parse().map_err(|why: String| v.error(&format!("USD purposes ({why})")))?)
            }
            "animation" => {
                let clips = if v.value.is_instance_of::<pyo3::types::PyBool>() {
                    v.boolean()?.then(Vec::new)
                } else {
                    let text = v.text().map_err(|_| v.error("True or clips 'CLIP,CLIP'"))?;
                    Some(Animation::parse_clips(&text).map_err(|why| v.error(&format!("clips 'CLIP,CLIP' ({why})")))?)
                };
                o.animation = clips.map(|clips| Animation { clips, ..Animation::default() });
            }
            "animation_poses" => {
                let poses = v.count()?;
                animation_poses = Some(u32::try_from(poses).map_err(|_| v.error("a count from 1 to 64"))?);
            }
            "animation_window" => {
                let text = v.text().map_err(|_| v.error("a window 'START..END' in seconds"))?;
                let window = text.parse().map_err(|why: String| v.error(&format!("a window 'START..END' ({why})")))?;
                animation_window = Some(window);
            }
            "keep_degenerate" => o.keep_degenerate = Some(v.boolean()?),
            "allow_outside_buffers" => o.allow_buffers_outside_input_folder = Some(v.boolean()?),
            "max_input_bytes" => (limits.max_input_bytes, limits_given) = (v.count()?, true),
            "max_triangles" => (limits.max_triangles, limits_given) = (v.count()?, true),
            "max_decoded_values" => (limits.max_decoded_values, limits_given) = (v.count()?, true),
            "max_placements" => (limits.max_placements, limits_given) = (v.count()?, true),
            "max_polygon_vertices" => (limits.max_polygon_vertices, limits_given) = (v.count()?, true),
            "max_memory" => {
                limits.max_memory = if v.value.is_instance_of::<PyString>() {
                    bvhc::import::memory::parse_size(&v.text()?).map_err(|e| v.error(&e))?
                } else {
                    MemoryLimit::Bytes(v.count()?)
                };
                limits_given = true;
            }
            "instancing" => {
                o.instancing = Some(v.choice(&[
                    ("auto", Instancing::Auto),
                    ("always", Instancing::Always),
                    ("never", Instancing::Never),
                ])?)
            }
            "opacity" => {
                o.opacity = Some(v.choice(&[
                    ("materials", Opacity::Materials),
                    ("opaque", Opacity::Opaque),
                    ("filtered", Opacity::Filtered),
                ])?)
            }
            "builder" => {
                o.builder =
                    Some(v.choice(&[("binned-sah", Builder::BinnedSah), ("spatial-median", Builder::SpatialMedian)])?)
            }
            "splits" => o.splits = Some(v.boolean()?),
            "splits_deforming" => o.splits_deforming = Some(v.boolean()?),
            "split_budget" => {
                let budget = v.number()?;
                if !(0.0..=bvhc::builders::MAX_BUDGET).contains(&budget) {
                    return Err(v.error("a fraction from 0 to 4 (at most five references a triangle)"));
                }
                o.split_budget = Some(budget);
            }
            "split_method" => {
                o.split_method = Some(v.choice(&[("sbvh", SplitMethod::Sbvh), ("pre-split", SplitMethod::PreSplit)])?)
            }
            "split_triangles" => {
                o.split_triangles = Some(v.choice(&[
                    ("wasteful", SplitTriangles::Wasteful),
                    ("any", SplitTriangles::Any),
                    ("choose", SplitTriangles::Choose),
                ])?)
            }
            "optimize" => o.optimize = Some(v.boolean()?),
            "selection" => {
                let choices: Vec<(&str, Selection)> = Selection::ALL.iter().map(|s| (s.name(), *s)).collect();
                o.selection = Some(v.choice(&choices)?);
            }
            "time_budget" => {
                let seconds = v.number()?;
                if !(0.0..=365.0 * 24.0 * 3600.0).contains(&seconds) {
                    return Err(v.error("seconds from 0 to a year"));
                }
                o.time_budget = Some(std::time::Duration::from_secs_f64(seconds));
            }
            "optimize_over" => {
                o.optimize_over = Some(v.choice(&[
                    ("references", OptimizeOver::References),
                    ("clusters", OptimizeOver::Clusters),
                    ("choose", OptimizeOver::Choose),
                ])?)
            }
            "merge_leaves" => o.merge_leaves = Some(v.boolean()?),
            "max_leaf_size" => o.max_leaf_size = Some(v.count()? as usize),
            "wide" => o.wide = Some(v.boolean()?),
            "gpu_layout" => o.gpu_layout = Some(v.boolean()?),
            "tune_rays" => o.tune_rays = Some(v.count()? as usize),
            "train_rays" => {
                let path: PathBuf = v.value.extract().map_err(|_| v.error("a path to a ray file"))?;
                o.train_rays = Some(bvhc::sampling::TrainingRays::read(&path).map_err(OptionsError::new_err)?);
            }
            "ids" => o.write_ids = Some(v.boolean()?),
            "source_vertices" => o.write_source_vertices = Some(v.boolean()?),
            other => {
                return Err(OptionsError::new_err(format!(
                    "{other}: not an option of bvhc.convert (the command line's flags with underscores; the --no-* \
                     switches as booleans: splits, optimize, merge_leaves, wide, ids, source_vertices)"
                )));
            }
        }
    }
    if limits_given {
        o.limits = Some(limits);
    }
    match (&mut o.animation, animation_poses) {
        (Some(animation), Some(poses)) => animation.poses_per_clip = poses,
        (None, Some(_)) => {
            return Err(OptionsError::new_err("animation_poses: needs animation=True or animation='CLIPS'"));
        }
        _ => {}
    }
    match (&mut o.animation, animation_window) {
        (Some(animation), Some(window)) => animation.window = Some(window),
        (None, Some(_)) => {
            return Err(OptionsError::new_err("animation_window: needs animation=True or animation='CLIPS'"));
        }
        _ => {}
    }
    Ok(o)
}

/// The options a conversion would use, resolved and checked, as the JSON of the metadata's `build` object
/// (`bvhc options`).
#[pyfunction]
#[pyo3(signature = (preset, options=None))]
pub fn resolve(preset: &str, options: Option<&Bound<'_, PyDict>>) -> PyResult<String> {
    let resolved = resolve_options(self::preset(preset)?, &overrides(options)?)
        .map_err(|e| OptionsError::new_err(e.to_string()))?;
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
    let conversion =
        Conversion::new(&src, &dst).preset(self::preset(preset)?).overrides(overrides(options)?).force(force);
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
