//! An opened `.bvh` file over a numpy `uint8` array of its bytes (a read-only memory map, or the file read into
//! memory), and the tracing calls (`tracing.rs` does their work). Each call opens a view over the array (the
//! structural checks, O(sections)) and traces on all cores with the GIL released; the array is borrowed
//! read-only meanwhile.

use bvhc::loader::Trace;
use bvhc::loader::{BvhView, Hit, Ray};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArrayMethods, PyReadonlyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;

use crate::errors::{InternalError, InvalidFileError, InvalidInputError, loader};
use crate::filters::{FilterArgs, source_id_count};
use crate::hits::{CHUNK, NONE};
use crate::rays::{Bound1, RayArguments, RayArrays, Vectors};
use crate::tracing::{on_pool, pool};

/// A `.bvh` file opened over a numpy array of its bytes.
#[pyclass(frozen, module = "bvhc._native")]
pub struct Scene {
    bytes: Py<PyArray1<u8>>,
    path: String,
    /// What `pose` left for `write`.
    posed: std::sync::Mutex<Posed>,
    /// The winding moments of the bytes as they were when last asked for (`crate::points::KeptMoments`).
    winding: crate::points::KeptMoments,
}

/// What `Scene.pose` leaves for `Scene.write`.
#[derive(Default)]
struct Posed {
    /// The files `pose` has read (each asset and its buffers), which `write` refuses to overwrite.
    files_read: Vec<std::path::PathBuf>,
    /// The last pose's metadata `refit` record, while the records and instances are that pose's: a refit or
    /// move from the program's own values drops it.
    record: Option<bvhc::posed::RefitRecord>,
}

impl Scene {
    /// The state `pose` left, locked.
    fn posed(&self) -> PyResult<std::sync::MutexGuard<'_, Posed>> {
        self.posed.lock().map_err(|_| InternalError::new_err("a poisoned lock"))
    }
}

/// Runs `f` on the file's view, the array borrowed read-only.
fn with_view<R>(
    py: Python<'_>,
    bytes: &Py<PyArray1<u8>>,
    path: &str,
    f: impl FnOnce(&BvhView<'_>) -> PyResult<R>,
) -> PyResult<R> {
    let array: PyReadonlyArray1<'_, u8> = bytes.bind(py).readonly();
    let slice = array.as_slice().map_err(|e| InvalidInputError::new_err(format!("{path}: {e}")))?;
    let view = BvhView::open(slice).map_err(|e| loader(&e, format!("{path}: {e}")))?;
    f(&view)
}

#[pymethods]
impl Scene {
    /// Opens the file whose bytes `data` holds (`path` names it in errors); `verify` checks every rule.
    #[new]
    #[pyo3(signature = (data, path, verify=true))]
    fn new(py: Python<'_>, data: Bound<'_, PyArray1<u8>>, path: String, verify: bool) -> PyResult<Scene> {
        let bytes = data.unbind();
        with_view(py, &bytes, &path, |view| {
            if verify {
                let view = *view;
                py.detach(|| view.verify())
                    .map_err(|v| InvalidFileError::new_err(format!("{path}: invalid .bvh file: {v}")))?;
            }
            Ok(())
        })?;
        Ok(Scene { bytes, path, posed: Default::default(), winding: Default::default() })
    }

    /// The file's path as given.
    #[getter]
    fn path(&self) -> &str {
        &self.path
    }

    /// The file's bytes (the array this scene was opened over).
    #[getter]
    fn data<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<u8>> {
        self.bytes.bind(py).clone()
    }

    /// The scene's bounding box `((min x, y, z), (max x, y, z))`, or `None` for an empty scene.
    #[getter]
    fn bounds(&self, py: Python<'_>) -> PyResult<Option<([f32; 3], [f32; 3])>> {
        with_view(py, &self.bytes, &self.path, |view| Ok(view.scene_box()))
    }

    /// The `bvhc info --json` report, as JSON.
    fn info_json(&self, py: Python<'_>) -> PyResult<String> {
        with_view(py, &self.bytes, &self.path, |view| {
            Ok(bvhc::inspect::inspect(view).to_json(std::path::Path::new(&self.path), view).to_string())
        })
    }

    /// Every validity rule; raises `InvalidFileError` naming the first broken one.
    fn verify(&self, py: Python<'_>) -> PyResult<()> {
        with_view(py, &self.bytes, &self.path, |view| {
            let view = *view;
            py.detach(|| view.verify())
                .map_err(|v| InvalidFileError::new_err(format!("{}: invalid .bvh file: {v}", self.path)))
        })
    }

    /// Source ids of the file (the length of a `cutout` mask): the end of its last source range.
    #[getter]
    fn source_id_count(&self, py: Python<'_>) -> PyResult<usize> {
        with_view(py, &self.bytes, &self.path, |view| Ok(source_id_count(view)))
    }

    /// Closest hits of the rays, as a dict of arrays (see the package's docs).
    #[allow(clippy::too_many_arguments)] // the rays, then the filter's four
    #[pyo3(signature = (origins, directions, t_min, t_max, threads=None, cutout=None, cutout_primitives=None,
        filter=None, filter_scope="every", coherent=false, lean=false))]
    fn closest_hits<'py>(
        &self,
        py: Python<'py>,
        origins: Bound<'py, PyAny>,
        directions: Bound<'py, PyAny>,
        t_min: Bound<'py, PyAny>,
        t_max: Bound<'py, PyAny>,
        threads: Option<usize>,
        cutout: Option<Bound<'py, PyAny>>,
        cutout_primitives: Option<Bound<'py, PyAny>>,
        filter: Option<Bound<'py, PyAny>>,
        filter_scope: &str,
        coherent: bool,
        lean: bool,
    ) -> PyResult<Bound<'py, PyDict>> {
        let arguments = RayArguments::extract(&origins, &directions, &t_min, &t_max)?;
        let rays = arguments.rays()?;
        let filter = FilterArgs::extract(cutout, cutout_primitives, filter, filter_scope)?;
        let pool = pool(threads)?;
        if lean {
            return with_view(py, &self.bytes, &self.path, |view| {
                crate::tracing::closest_lean(py, view, rays, filter.as_ref(), (&pool, order(coherent)))
            });
        }
        let columns = with_view(py, &self.bytes, &self.path, |view| {
            crate::tracing::closest(py, view, rays, filter.as_ref(), (&pool, order(coherent)))
        })?;
        columns.into_dict(py)
    }

    /// Whether each ray hits anything within its interval, as a bool array.
    #[allow(clippy::too_many_arguments)] // the rays, then the filter's four
    #[pyo3(signature = (origins, directions, t_min, t_max, threads=None, cutout=None, cutout_primitives=None,
        filter=None, filter_scope="every", coherent=false))]
    fn any_hits<'py>(
        &self,
        py: Python<'py>,
        origins: Bound<'py, PyAny>,
        directions: Bound<'py, PyAny>,
        t_min: Bound<'py, PyAny>,
        t_max: Bound<'py, PyAny>,
        threads: Option<usize>,
        cutout: Option<Bound<'py, PyAny>>,
        cutout_primitives: Option<Bound<'py, PyAny>>,
        filter: Option<Bound<'py, PyAny>>,
        filter_scope: &str,
        coherent: bool,
    ) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let arguments = RayArguments::extract(&origins, &directions, &t_min, &t_max)?;
        let rays = arguments.rays()?;
        let filter = FilterArgs::extract(cutout, cutout_primitives, filter, filter_scope)?;
        let pool = pool(threads)?;
        let occluded = with_view(py, &self.bytes, &self.path, |view| {
            crate::tracing::any(py, view, rays, filter.as_ref(), (&pool, order(coherent)))
        })?;
        Ok(occluded.into_pyarray(py))
    }

    /// Every hit of each ray (the nearest `max_hits`), as a dict of arrays a row a hit.
    #[allow(clippy::too_many_arguments)] // the rays and the cap, then the filter's four
    #[pyo3(signature = (origins, directions, t_min, t_max, max_hits=64, threads=None, cutout=None,
        cutout_primitives=None, filter=None, filter_scope="every"))]
    fn all_hits<'py>(
        &self,
        py: Python<'py>,
        origins: Bound<'py, PyAny>,
        directions: Bound<'py, PyAny>,
        t_min: Bound<'py, PyAny>,
        t_max: Bound<'py, PyAny>,
        max_hits: usize,
        threads: Option<usize>,
        cutout: Option<Bound<'py, PyAny>>,
        cutout_primitives: Option<Bound<'py, PyAny>>,
        filter: Option<Bound<'py, PyAny>>,
        filter_scope: &str,
    ) -> PyResult<Bound<'py, PyDict>> {
        let arguments = RayArguments::extract(&origins, &directions, &t_min, &t_max)?;
        let rays = arguments.rays()?;
        let filter = FilterArgs::extract(cutout, cutout_primitives, filter, filter_scope)?;
        let pool = pool(threads)?;
        let columns = with_view(py, &self.bytes, &self.path, |view| {
            crate::tracing::all(py, view, rays, filter.as_ref(), max_hits, &pool)
        })?;
        columns.into_dict(py)
    }

    /// Whether each point (an `(n, 3)` array) lies inside the scene's closed meshes, as a bool array.
    #[pyo3(signature = (points, threads=None))]
    fn contains<'py>(
        &self,
        py: Python<'py>,
        points: Bound<'py, PyAny>,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let points = Vectors::extract("points", &points)?;
        let pool = pool(threads)?;
        let inside = with_view(py, &self.bytes, &self.path, |view| crate::tracing::contains(py, view, &points, &pool))?;
        Ok(inside.into_pyarray(py))
    }

    /// The closest point of the surface to each point, as a dict of arrays, among the triangles the cut-out
    /// masks keep (see the package's docs).
    #[pyo3(signature = (points, max_distance=None, threads=None, cutout=None, cutout_primitives=None))]
    fn closest_points<'py>(
        &self,
        py: Python<'py>,
        points: Bound<'py, PyAny>,
        max_distance: Option<f64>,
        threads: Option<usize>,
        cutout: Option<Bound<'py, PyAny>>,
        cutout_primitives: Option<Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let points = Vectors::extract("points", &points)?;
        let max_distance = crate::points::max_distance_keyword(max_distance)?;
        let masks = FilterArgs::extract(cutout, cutout_primitives, None, "every")?;
        let pool = pool(threads)?;
        with_view(py, &self.bytes, &self.path, |view| {
            let cutouts = masks.as_ref().map(|masks| masks.cutouts(view)).transpose()?;
            crate::points::closest_points(py, view, &points, max_distance, cutouts.as_ref(), &pool)
        })
    }

    /// Each point's signed distance (`signed`: float32, negative inside) or generalized winding number
    /// (float64), as an array.
    #[pyo3(signature = (points, signed, threads=None))]
    fn winding<'py>(
        &self,
        py: Python<'py>,
        points: Bound<'py, PyAny>,
        signed: bool,
        threads: Option<usize>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let points = Vectors::extract("points", &points)?;
        let pool = pool(threads)?;
        with_view(py, &self.bytes, &self.path, |view| {
            crate::points::winding(py, view, &points, signed, &pool, &self.winding)
        })
    }

    /// Seconds the loader's batch call takes for these rays as a Rust program makes it: `Tracer::closest_hits` in
    /// chunks of 1024 on the pool, into an array of hit records (the rays gathered and checked, and the array
    /// allocated and written once, beforehand: not timed). What the benchmark compares `closest_hits`, the
    /// whole Python call, with.
    #[pyo3(signature = (origins, directions, threads=None))]
    fn rust_batch_seconds<'py>(
        &self,
        py: Python<'py>,
        origins: Bound<'py, PyAny>,
        directions: Bound<'py, PyAny>,
        threads: Option<usize>,
    ) -> PyResult<f64> {
        let origins = Vectors::extract("origins", &origins)?;
        let directions = Vectors::extract("directions", &directions)?;
        let (lo, hi) = (Bound1::Scalar(0.0), Bound1::Scalar(f32::INFINITY));
        let rays = RayArrays::new(&origins, &directions, &lo, &hi)?.gather(py)?;
        let pool = pool(threads)?;
        with_view(py, &self.bytes, &self.path, |view| {
            let tracer = view.tracer().trusting_rays();
            Ok(py.detach(|| {
                on_pool(&pool, || {
                    let mut found: Vec<Option<Hit>> = vec![None; rays.len()];
                    let start = std::time::Instant::now();
                    rays.par_chunks(CHUNK)
                        .zip(found.par_chunks_mut(CHUNK))
                        .for_each(|(rays, found)| tracer.closest_hits(rays, found));
                    std::hint::black_box(&found);
                    start.elapsed().as_secs_f64()
                })
            }))
        })
    }

    /// Secondary rays leaving the hits (the columns `closest_hits` returns) in `directions`, without an epsilon:
    /// `(origins, directions, t_min, t_max)` arrays. Every hit must be one (no miss) of this file.
    #[allow(clippy::too_many_arguments)]
    #[pyo3(signature = (t, triangle, u, v, normal, front_face, instance, source_id, directions))]
    fn spawn<'py>(
        &self,
        py: Python<'py>,
        t: PyReadonlyArray1<'py, f32>,
        triangle: PyReadonlyArray1<'py, u32>,
        u: PyReadonlyArray1<'py, f32>,
        v: PyReadonlyArray1<'py, f32>,
        normal: Bound<'py, PyAny>,
        front_face: PyReadonlyArray1<'py, bool>,
        instance: PyReadonlyArray1<'py, u32>,
        source_id: PyReadonlyArray1<'py, u32>,
        directions: Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, pyo3::types::PyTuple>> {
        let normal = Vectors::extract("normal", &normal)?;
        let directions = Vectors::extract("directions", &directions)?;
        let n = directions.len();
        let (t, triangle, u, v) = (t.as_array(), triangle.as_array(), u.as_array(), v.as_array());
        let (front_face, instance, source_id) = (front_face.as_array(), instance.as_array(), source_id.as_array());
        for (name, len) in [
            ("t", t.len()),
            ("triangle", triangle.len()),
            ("u", u.len()),
            ("v", v.len()),
            ("normal", normal.len()),
            ("front_face", front_face.len()),
            ("instance", instance.len()),
            ("source_id", source_id.len()),
        ] {
            if len != n {
                return Err(InvalidInputError::new_err(format!("spawn: {len} values of {name} for {n} directions")));
            }
        }
        let zero = Bound1::Scalar(0.0);
        let rows = RayArrays::new(&normal, &directions, &zero, &zero)?
            .gather(py)
            .map_err(|e| InvalidInputError::new_err(format!("spawn: normals and directions: {}", e.value(py))))?;
        let rays = with_view(py, &self.bytes, &self.path, |view| {
            let tracer = view.tracer();
            rows.iter()
                .enumerate()
                .map(|(i, row)| {
                    if triangle[i] == NONE {
                        return Err(InvalidInputError::new_err(format!(
                            "spawn: hit {i} is a miss (triangle 0xFFFFFFFF); select the hits first"
                        )));
                    }
                    let hit = Hit {
                        t: t[i],
                        triangle_index: triangle[i],
                        source_triangle_id: (source_id[i] != NONE).then_some(source_id[i]),
                        u: u[i],
                        v: v[i],
                        normal: row.origin,
                        front_face: front_face[i],
                        instance_index: (instance[i] != NONE).then_some(instance[i]),
                    };
                    let surface =
                        tracer.surface(&hit).map_err(|e| InvalidInputError::new_err(format!("spawn: hit {i}: {e}")))?;
                    surface.spawn(row.direction).map_err(|e| {
                        InvalidInputError::new_err(format!("spawn: direction {i} {:?}: {e}", row.direction))
                    })
                })
                .collect::<PyResult<Vec<Ray>>>()
        })?;
        let origins: Vec<f32> = rays.iter().flat_map(|r| r.origin).collect();
        let directions: Vec<f32> = rays.iter().flat_map(|r| r.direction).collect();
        let t_min: Vec<f32> = rays.iter().map(|r| r.t_min).collect();
        let t_max: Vec<f32> = rays.iter().map(|r| r.t_max).collect();
        let shape = |v: Vec<f32>| {
            Array2::from_shape_vec((n, 3), v).map_err(|e| crate::errors::InternalError::new_err(e.to_string()))
        };
        pyo3::types::PyTuple::new(
            py,
            [
                shape(origins)?.into_pyarray(py).into_any(),
                shape(directions)?.into_pyarray(py).into_any(),
                t_min.into_pyarray(py).into_any(),
                t_max.into_pyarray(py).into_any(),
            ],
        )
    }

    /// Refits the file in place (opened writable) to `positions` (`(n, 3, 3)` float32, a record each) or
    /// `source_vertices` (per source range, an `(m, 3)` float32 array or `None`), on `threads` threads; returns
    /// the refit tree's costs beside the file's, the cost ratio and whether it passes `max_cost_ratio`.
    #[pyo3(signature = (positions=None, source_vertices=None, threads=None, max_cost_ratio=1.2))]
    fn refit<'py>(
        &self,
        py: Python<'py>,
        positions: Option<numpy::PyReadonlyArrayDyn<'py, f32>>,
        source_vertices: Option<Vec<Option<numpy::PyReadonlyArrayDyn<'py, f32>>>>,
        threads: Option<usize>,
        max_cost_ratio: f64,
    ) -> PyResult<Bound<'py, PyDict>> {
        let threads = crate::tracing::threads_or_all(threads)?;
        let report =
            crate::refit::refit(py, &self.bytes, &self.path, positions, source_vertices, threads, max_cost_ratio)?;
        self.posed()?.record = None;
        Ok(report)
    }

    /// Poses the file (opened writable) as the asset it was converted from stands in its default pose or at
    /// `pose` (`"CLIP@SECONDS"`, a clip by index or name): every record given its triangle's positions there and
    /// every instance a glTF node places the node's transform; the deforming geometry refit, the instanced
    /// meshes left as they are unless their positions differ, the instances moved. Returns `refit`'s dict with
    /// `instances_placed`.
    #[pyo3(signature = (asset, pose=None, threads=None, max_cost_ratio=1.2))]
    fn pose<'py>(
        &self,
        py: Python<'py>,
        asset: std::path::PathBuf,
        pose: Option<String>,
        threads: Option<usize>,
        max_cost_ratio: f64,
    ) -> PyResult<Bound<'py, PyDict>> {
        let threads = crate::tracing::threads_or_all(threads)?;
        let (report, files_read, record) =
            crate::refit::pose(py, &self.bytes, &self.path, asset, pose, threads, max_cost_ratio)?;
        let mut posed = self.posed()?;
        posed.files_read.extend(files_read);
        posed.record = Some(record);
        Ok(report)
    }

    /// Refits mesh `mesh` of a two-level file (opened writable) to `positions` (`(n, 3, 3)` float32, its
    /// records in its own space), its instances' boxes and the top trees; the other meshes are left untouched.
    #[pyo3(signature = (mesh, positions, threads=None))]
    fn refit_mesh(
        &self,
        py: Python<'_>,
        mesh: u32,
        positions: numpy::PyReadonlyArrayDyn<'_, f32>,
        threads: Option<usize>,
    ) -> PyResult<()> {
        let threads = crate::tracing::threads_or_all(threads)?;
        crate::refit::refit_mesh(py, &self.bytes, &self.path, mesh, positions, threads)?;
        self.posed()?.record = None;
        Ok(())
    }

    /// Places `instances` (a two-level file's, opened writable) by `transforms` (`(k, 3, 4)` float32 rows).
    fn move_instances(
        &self,
        py: Python<'_>,
        instances: Vec<u32>,
        transforms: numpy::PyReadonlyArrayDyn<'_, f32>,
    ) -> PyResult<()> {
        let moves = (instances, transforms);
        crate::refit::move_instances(py, &self.bytes, &self.path, moves, "move_instances", true)?;
        self.posed()?.record = None;
        Ok(())
    }

    /// `move_instances` without recomputing the checksums (`write` does), for a frame.
    fn move_instances_in_frame(
        &self,
        py: Python<'_>,
        instances: Vec<u32>,
        transforms: numpy::PyReadonlyArrayDyn<'_, f32>,
    ) -> PyResult<()> {
        let moves = (instances, transforms);
        crate::refit::move_instances(py, &self.bytes, &self.path, moves, "move_instances_in_frame", false)?;
        self.posed()?.record = None;
        Ok(())
    }

    /// The file with its top trees built anew over its instances as they stand, as a new byte array.
    fn rebuilt_top_trees<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, numpy::PyArray1<u8>>> {
        crate::refit::rebuilt_top_trees(py, &self.bytes, &self.path)
    }

    /// A two-level file's top tree cost (`None` for a one-level file).
    #[getter]
    fn top_tree_cost(&self, py: Python<'_>) -> PyResult<Option<f64>> {
        crate::refit::top_tree_cost(py, &self.bytes, &self.path)
    }

    /// Writes the file to `output` atomically, its stated costs recomputed (so a refit file verifies) and, when
    /// its records and instances are still the last `pose`'s, that pose recorded as the metadata key `refit`.
    fn write(&self, py: Python<'_>, output: std::path::PathBuf) -> PyResult<()> {
        let (files_read, record) = {
            let posed = self.posed()?;
            (posed.files_read.clone(), posed.record.clone())
        };
        bvhc::convert::files::refuse_output_among(&output, &files_read).map_err(crate::errors::conversion)?;
        crate::refit::write(py, &self.bytes, &self.path, output, record.as_ref())
    }
}

/// The batch order a `coherent` keyword asks for.
fn order(coherent: bool) -> bvhc::loader::Order {
    if coherent { bvhc::loader::Order::Coherent } else { bvhc::loader::Order::Stream }
}
