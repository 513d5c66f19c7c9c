//! Point queries from numpy arrays (`Scene.closest_points`, `Scene.distance`, `Scene.signed_distance`,
//! `Scene.winding_number`): the loader's batch calls (which answer the points in a spatial order) on the pool's
//! thread count with the GIL released, answers into numpy columns. Points are `(n, 3)` float32 or float64
//! arrays (float64 rounded to float32, the precision the file's triangles and the spec's queries take); a point
//! that is not finite raises, naming it.

use std::sync::{Arc, Mutex, PoisonError};

use bvhc::loader::{BvhView, ClosestPoint, WindingMoments, WindingNumbers};
use numpy::IntoPyArray;
use numpy::ndarray::Array2;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::InvalidInputError;
use crate::filters::Cutouts;
use crate::hits::NONE;
use crate::rays::Vectors;
use crate::tracing::on_pool;

/// The points as rows, each finite (else the error names the first that is not).
fn finite_rows(py: Python<'_>, points: &Vectors<'_>) -> PyResult<Vec<[f32; 3]>> {
    let rows = points.rows(py)?;
    if let Some(bad) = rows.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(InvalidInputError::new_err(format!("points: point {bad} {:?} is not finite", rows[bad])));
    }
    Ok(rows)
}

/// `max_distance` as the loader takes it: `None` for no bound; a negative or NaN bound raises.
pub fn max_distance_keyword(max_distance: Option<f64>) -> PyResult<f32> {
    match max_distance {
        None => Ok(f32::INFINITY),
        Some(d) if d >= 0.0 => Ok(d as f32),
        Some(d) => Err(InvalidInputError::new_err(format!("max_distance: {d}, expected a number >= 0 or None"))),
    }
}

/// The threads a call on `pool` may use (the pool's, else every core's).
fn pool_threads(pool: &Option<rayon::ThreadPool>) -> usize {
    on_pool(pool, rayon::current_num_threads)
}

/// Each point's closest point within `max_distance` among the triangles `cutouts` keep: the loader's batch call
/// (points in a spatial order, each walk bounded by its neighbour's answer) on `pool`'s thread count, with the
/// GIL released.
fn answers(
    py: Python<'_>,
    view: &BvhView<'_>,
    rows: &[[f32; 3]],
    max_distance: f32,
    cutouts: Option<&Cutouts<'_>>,
    pool: &Option<rayon::ThreadPool>,
) -> Vec<Option<ClosestPoint>> {
    let tracer = view.tracer();
    let mut out = vec![None; rows.len()];
    let threads = pool_threads(pool);
    py.detach(|| match cutouts {
        Some(cutouts) => tracer.closest_points_filtered(rows, max_distance, cutouts, &mut out, threads),
        None => tracer.closest_points(rows, max_distance, &mut out, threads),
    });
    out
}

/// `Scene.closest_points`: a dict of columns, a row a point: `point` ((n, 3) float32), `distance` (float32,
/// `inf` when nothing is within `max_distance`), `triangle`, `source_id`, `instance` (uint32, the miss marker
/// where there is none), `u`, `v` (float32, 0 where there is none).
pub fn closest_points<'py>(
    py: Python<'py>,
    view: &BvhView<'_>,
    points: &Vectors<'_>,
    max_distance: f32,
    cutouts: Option<&Cutouts<'_>>,
    pool: &Option<rayon::ThreadPool>,
) -> PyResult<Bound<'py, PyDict>> {
    let rows = finite_rows(py, points)?;
    let found = answers(py, view, &rows, max_distance, cutouts, pool);
    let n = found.len();
    let mut point = Array2::<f32>::from_elem((n, 3), f32::NAN);
    let (mut distance, mut triangle, mut source_id) = (vec![f32::INFINITY; n], vec![NONE; n], vec![NONE; n]);
    let (mut u, mut v, mut instance) = (vec![0f32; n], vec![0f32; n], vec![NONE; n]);
    for (i, answer) in found.iter().enumerate() {
        let Some(c) = answer else { continue };
        for (a, &x) in c.point.iter().enumerate() {
            point[[i, a]] = x;
        }
        (distance[i], triangle[i], u[i], v[i]) = (c.distance, c.triangle_index, c.u, c.v);
        source_id[i] = c.source_triangle_id.unwrap_or(NONE);
        instance[i] = c.instance_index.unwrap_or(NONE);
    }
    let d = PyDict::new(py);
    d.set_item("point", point.into_pyarray(py))?;
    d.set_item("distance", distance.into_pyarray(py))?;
    d.set_item("triangle", triangle.into_pyarray(py))?;
    d.set_item("source_id", source_id.into_pyarray(py))?;
    d.set_item("u", u.into_pyarray(py))?;
    d.set_item("v", v.into_pyarray(py))?;
    d.set_item("instance", instance.into_pyarray(py))?;
    Ok(d)
}

/// A scene's winding moments and the hash (xxh3) and length of the bytes they were computed from: a call whose
/// bytes hash the same takes them, any other computes them again, so a refit, a pose, an instance move or a
/// write into the array by any means leaves no stale moments (hashing costs about a tenth of computing them).
#[derive(Default)]
pub struct KeptMoments(Mutex<Option<(u64, usize, Arc<WindingMoments>)>>);

impl KeptMoments {
    /// The moments of `view`'s bytes: the kept ones if they are of the same bytes, else computed and kept.
    fn of(&self, view: &BvhView<'_>) -> PyResult<Arc<WindingMoments>> {
        let bytes = view.bytes();
        let key = (xxhash_rust::xxh3::xxh3_64(bytes), bytes.len());
        let mut kept = self.0.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some((hash, len, moments)) = &*kept
            && (*hash, *len) == key
        {
            return Ok(Arc::clone(moments));
        }
        let moments = WindingMoments::new(&view.tracer()).map_err(|e| {
            pyo3::exceptions::PyMemoryError::new_err(format!(
                "the winding moments of {} triangles: {e}",
                view.triangles().len()
            ))
        })?;
        let moments = Arc::new(moments);
        *kept = Some((key.0, key.1, Arc::clone(&moments)));
        Ok(moments)
    }
}

/// `Scene.signed_distance` (`signed`) or `Scene.winding_number`: each point's signed distance (float32, negative
/// inside) or winding number (float64), from the file's winding moments (`kept`'s, when of the same bytes).
pub fn winding<'py>(
    py: Python<'py>,
    view: &BvhView<'_>,
    points: &Vectors<'_>,
    signed: bool,
    pool: &Option<rayon::ThreadPool>,
    kept: &KeptMoments,
) -> PyResult<Bound<'py, PyAny>> {
    let rows = finite_rows(py, points)?;
    let tracer = view.tracer();
    let moments = py.detach(|| kept.of(view))?;
    let numbers = WindingNumbers::with_moments(&tracer, moments);
    let threads = pool_threads(pool);
    if signed {
        let mut out = vec![0f32; rows.len()];
        py.detach(|| numbers.signed_distances(&rows, &mut out, threads));
        return Ok(out.into_pyarray(py).into_any());
    }
    let mut out = vec![0f64; rows.len()];
    py.detach(|| numbers.winding_numbers(&rows, &mut out, threads));
    Ok(out.into_pyarray(py).into_any())
}
