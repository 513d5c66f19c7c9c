//! Moving geometry from Python: a scene opened writable (`bvhc.open(path, writable=True)`: a private
//! copy-on-write map, or the file read into memory) refit in place to numpy positions read in place (per record,
//! or per source vertex of each source range), its instances moved, and written back with its costs
//! recomputed. The scene's numpy views of its sections see the new values (the same memory).

use bvhc::loader::format::Affine3x4;
use bvhc::loader::{BvhViewMut, RebuildPolicy, RefitPositions, RefitReport};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::{InvalidInputError, OptionsError, loader, posed};

/// The scene's bytes borrowed writable, opened; `what` names the call in errors.
fn with_view_mut<R: Send>(
    py: Python<'_>,
    bytes: &Py<PyArray1<u8>>,
    path: &str,
    what: &str,
    f: impl FnOnce(&mut BvhViewMut<'_>) -> Result<R, bvhc::loader::Error> + Send,
) -> PyResult<R> {
    let mut array = bytes.bind(py).try_readwrite().map_err(|_| {
        InvalidInputError::new_err(format!(
            "{path}: {what} changes the file's bytes: open it with bvhc.open(path, writable=True)"
        ))
    })?;
    let slice = array.as_slice_mut().map_err(|e| InvalidInputError::new_err(format!("{path}: {e}")))?;
    py.detach(|| {
        let mut view = BvhViewMut::open(slice)?;
        f(&mut view)
    })
    .map_err(|e| loader(&e, format!("{path}: {what}: {e}")))
}

/// A C-contiguous float32 array's values, in place; `name` names it in errors.
fn floats<'a>(array: &'a PyReadonlyArrayDyn<'_, f32>, name: &str, last: &[usize]) -> PyResult<&'a [f32]> {
    let shape = array.shape();
    if shape.len() < last.len() || shape[shape.len() - last.len()..] != *last {
        return Err(InvalidInputError::new_err(format!("{name}: shape {shape:?}, expected (n, {last:?})")));
    }
    array.as_slice().map_err(|_| InvalidInputError::new_err(format!("{name}: a C-contiguous float32 array")))
}

/// `max_cost_ratio` as a policy, refused as the command line refuses `--max-cost-ratio` (`OptionsError`).
fn rebuild_policy(max_cost_ratio: f64) -> PyResult<RebuildPolicy> {
    RebuildPolicy::new(max_cost_ratio).map_err(OptionsError::new_err)
}

/// The report as a dict: the four costs (`None` where the file states none), `cost_ratio`,
/// `planned_cost_ratio` (a tree chosen for an animation: the largest ratio its sampled poses reach, else `None`)
/// and `rebuild_recommended` by `policy` (its ratio times the planned ratio where there is one).
fn report_dict<'py>(py: Python<'py>, report: &RefitReport, policy: RebuildPolicy) -> PyResult<Bound<'py, PyDict>> {
    let dict = PyDict::new(py);
    dict.set_item("cost", report.cost)?;
    dict.set_item("file_cost", report.file_cost)?;
    dict.set_item("wide_cost", report.wide_cost)?;
    dict.set_item("file_wide_cost", report.file_wide_cost)?;
    dict.set_item("cost_ratio", report.cost_ratio())?;
    dict.set_item("planned_cost_ratio", report.planned_cost_ratio)?;
    dict.set_item("rebuild_recommended", policy.should_rebuild(report))?;
    Ok(dict)
}

/// `Scene.refit`: per record (`positions`, `(n, 3, 3)`) or per source range (`source_vertices`, a list of
/// `(m, 3)` arrays or `None`).
pub fn refit<'py>(
    py: Python<'py>,
    bytes: &Py<PyArray1<u8>>,
    path: &str,
    positions: Option<PyReadonlyArrayDyn<'py, f32>>,
    source_vertices: Option<Vec<Option<PyReadonlyArrayDyn<'py, f32>>>>,
    threads: usize,
    max_cost_ratio: f64,
) -> PyResult<Bound<'py, PyDict>> {
    let policy = rebuild_policy(max_cost_ratio)?;
    let report = match (&positions, &source_vertices) {
        (Some(positions), None) => {
            let values = floats(positions, "positions", &[3, 3])?;
            let triangles = values.as_chunks::<3>().0.as_chunks::<3>().0;
            with_view_mut(py, bytes, path, "refit", |view| view.refit(RefitPositions::Triangles(triangles), threads))?
        }
        (None, Some(ranges)) => {
            let mut slices: Vec<Option<&[[f32; 3]]>> = Vec::with_capacity(ranges.len());
            for (r, range) in ranges.iter().enumerate() {
                let slice = range.as_ref().map(|a| floats(a, &format!("source_vertices[{r}]"), &[3])).transpose()?;
                slices.push(slice.map(|values| values.as_chunks::<3>().0));
            }
            with_view_mut(py, bytes, path, "refit", |view| {
                view.refit(RefitPositions::SourceVertices(&slices), threads)
            })?
        }
        (None, None) => return Err(OptionsError::new_err("refit: give positions or source_vertices")),
        (Some(_), Some(_)) => {
            return Err(OptionsError::new_err("refit: give positions or source_vertices, not both"));
        }
    };
    report_dict(py, &report, policy)
}

/// `Scene.pose`: the scene's records and instances placed as `asset` places them in its default pose or at
/// `pose` (`CLIP@SECONDS`), imported as the conversion imported it (`bvhc::posed::placed_pose`), then applied in
/// place (`PlacedPose::apply_in_place`: the deforming geometry refit, the moving instances placed); the refit's
/// report with `instances_placed`, the files the asset's import read and the metadata `refit` record of the pose
/// (for `write`).
pub fn pose<'py>(
    py: Python<'py>,
    bytes: &Py<PyArray1<u8>>,
    path: &str,
    asset: std::path::PathBuf,
    pose: Option<String>,
    threads: usize,
    max_cost_ratio: f64,
) -> PyResult<(Bound<'py, PyDict>, Vec<std::path::PathBuf>, bvhc::posed::RefitRecord)> {
    let policy = rebuild_policy(max_cost_ratio)?;
    let pose: Option<bvhc::import::PoseSelector> = pose
        .map(|text| text.parse().map_err(|why: String| InvalidInputError::new_err(format!("pose: {why}"))))
        .transpose()?;
    let placed = {
        let array = bytes.bind(py).readonly();
        let slice = array.as_slice().map_err(|e| InvalidInputError::new_err(format!("{path}: {e}")))?;
        py.detach(|| {
            let view = bvhc::loader::BvhView::open(slice).map_err(|e| loader(&e, format!("{path}: {e}")))?;
            bvhc::posed::placed_pose(&view, &asset, &Default::default(), pose.as_ref())
                .map_err(|e| posed(&e, format!("{path}: pose from {}: {e}", asset.display())))
        })?
    };
    let report = with_view_mut(py, bytes, path, "pose", |view| placed.apply_in_place(view, threads))?;
    let dict = report_dict(py, &report, policy)?;
    dict.set_item("instances_placed", placed.instances.len())?;
    Ok((dict, placed.files_read, placed.record))
}

/// `Scene.refit_mesh`: mesh `mesh` of a two-level file refit to `positions` (`(n, 3, 3)`, its records in its own
/// space), the other meshes untouched.
pub fn refit_mesh(
    py: Python<'_>,
    bytes: &Py<PyArray1<u8>>,
    path: &str,
    mesh: u32,
    positions: PyReadonlyArrayDyn<'_, f32>,
    threads: usize,
) -> PyResult<()> {
    let values = floats(&positions, "positions", &[3, 3])?;
    let triangles = values.as_chunks::<3>().0.as_chunks::<3>().0;
    with_view_mut(py, bytes, path, "refit_mesh", |view| view.refit_mesh(mesh, triangles, threads))?;
    Ok(())
}

/// `Scene.move_instances` (`checksums`) and `Scene.move_instances_in_frame`: `instances` (uint32, `(k,)`) placed
/// by `transforms` (`(k, 3, 4)` float32 rows); `what` names the call in errors.
pub fn move_instances(
    py: Python<'_>,
    bytes: &Py<PyArray1<u8>>,
    path: &str,
    (instances, transforms): (Vec<u32>, PyReadonlyArrayDyn<'_, f32>),
    what: &str,
    checksums: bool,
) -> PyResult<()> {
    let values = floats(&transforms, "transforms", &[3, 4])?;
    let maps = values.as_chunks::<4>().0.as_chunks::<3>().0;
    if maps.len() != instances.len() {
        let (given, count) = (maps.len(), instances.len());
        return Err(InvalidInputError::new_err(format!("{what}: {given} transforms for {count} instances")));
    }
    let moves: Vec<(u32, Affine3x4)> = instances.into_iter().zip(maps.iter().copied()).collect();
    with_view_mut(py, bytes, path, what, |view| match checksums {
        true => view.move_instances(&moves),
        false => view.move_instances_in_frame(&moves),
    })
}

/// `Scene.write`: the file written atomically to `output` with its stated costs recomputed and, after a
/// `Scene.pose`, the pose recorded in its metadata (`RefitRecord::rewritten`, as `bvhc refit` records it).
pub fn write(
    py: Python<'_>,
    bytes: &Py<PyArray1<u8>>,
    path: &str,
    output: std::path::PathBuf,
    refit: Option<&bvhc::posed::RefitRecord>,
) -> PyResult<()> {
    let array = bytes.bind(py).readonly();
    let slice = array.as_slice().map_err(|e| InvalidInputError::new_err(format!("{path}: {e}")))?;
    py.detach(|| {
        let view = bvhc::loader::BvhView::open(slice)?;
        let shipped = match refit {
            Some(record) => record.rewritten(&view)?,
            None => view.rewritten()?,
        };
        bvhc::loader::write::write_atomic(&output, shipped.as_bytes())
    })
    .map_err(|e| loader(&e, format!("{}: {e}", output.display())))
}

/// `Scene.rebuilt_top_trees`: the bytes of the file with both top trees built anew over its instances as they
/// stand (`BvhView::rebuilt_top_trees`, verified), in a new array.
pub fn rebuilt_top_trees<'py>(
    py: Python<'py>,
    bytes: &Py<PyArray1<u8>>,
    path: &str,
) -> PyResult<Bound<'py, PyArray1<u8>>> {
    let array = bytes.bind(py).readonly();
    let slice = array.as_slice().map_err(|e| InvalidInputError::new_err(format!("{path}: {e}")))?;
    let rebuilt = py
        .detach(|| bvhc::loader::BvhView::open(slice)?.rebuilt_top_trees())
        .map_err(|e| loader(&e, format!("{path}: rebuilt_top_trees: {e}")))?;
    Ok(PyArray1::from_slice(py, rebuilt.as_bytes()))
}

/// `Scene.top_tree_cost`: a two-level file's binary top tree's SAH cost (`BvhView::top_tree_cost`), `None` for a
/// one-level file.
pub fn top_tree_cost(py: Python<'_>, bytes: &Py<PyArray1<u8>>, path: &str) -> PyResult<Option<f64>> {
    let array = bytes.bind(py).readonly();
    let slice = array.as_slice().map_err(|e| InvalidInputError::new_err(format!("{path}: {e}")))?;
    let view = bvhc::loader::BvhView::open(slice).map_err(|e| loader(&e, format!("{path}: {e}")))?;
    Ok(view.top_tree_cost())
}
