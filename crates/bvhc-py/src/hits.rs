//! Hit records into numpy columns: closest hits (a row a ray, misses as in `format-spec/rays-and-hits.md`) and
//! all hits (a row a hit, with its ray's index), traced chunk by chunk on the pool, or in order on the calling
//! thread when a Python callback filters them.

use bvhc::loader::{BatchRayError, Hit, Ray};
use numpy::IntoPyArray;
use numpy::ndarray::Array2;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;

use crate::rays::RayArrays;

/// Rays traced a task.
pub const CHUNK: usize = 1024;

/// Misses and absent values in hit arrays.
pub const NONE: u32 = u32::MAX;

/// A batch tracing call: `trace(rays, hits)` writes each ray's closest hit into the slot of the same index.
pub type BatchTrace<'t> = dyn Fn(&[Ray], &mut [Option<Hit>]) + Sync + 't;

/// A placeholder in ray buffers (overwritten before use).
pub const EMPTY_RAY: Ray = Ray { origin: [0.0; 3], direction: [1.0, 0.0, 0.0], t_min: 0.0, t_max: 0.0 };

/// Hits as columns, a row a hit (or a miss).
#[derive(Default)]
pub struct HitColumns {
    t: Vec<f32>,
    triangle: Vec<u32>,
    source_id: Vec<u32>,
    u: Vec<f32>,
    v: Vec<f32>,
    normal: Vec<f32>,
    front_face: Vec<bool>,
    instance: Vec<u32>,
}

/// One row's slots in the columns.
struct Row<'a> {
    t: &'a mut f32,
    triangle: &'a mut u32,
    source_id: &'a mut u32,
    u: &'a mut f32,
    v: &'a mut f32,
    normal: &'a mut [f32],
    front_face: &'a mut bool,
    instance: &'a mut u32,
}

impl Row<'_> {
    fn write(self, hit: Option<&Hit>) {
        let Some(hit) = hit else {
            (*self.t, *self.triangle, *self.source_id, *self.instance) = (f32::INFINITY, NONE, NONE, NONE);
            return;
        };
        *self.t = hit.t;
        *self.triangle = hit.triangle_index;
        *self.source_id = hit.source_triangle_id.unwrap_or(NONE);
        *self.u = hit.u;
        *self.v = hit.v;
        self.normal.copy_from_slice(&hit.normal);
        *self.front_face = hit.front_face;
        *self.instance = hit.instance_index.unwrap_or(NONE);
    }
}

impl HitColumns {
    /// `n` zeroed rows (calloc'd: every entry is written by the thread that traces its ray).
    fn zeroed(n: usize) -> HitColumns {
        HitColumns {
            t: vec![0.0; n],
            triangle: vec![0; n],
            source_id: vec![0; n],
            u: vec![0.0; n],
            v: vec![0.0; n],
            normal: vec![0.0; 3 * n],
            front_face: vec![false; n],
            instance: vec![0; n],
        }
    }

    fn row(&mut self, i: usize) -> Row<'_> {
        Row {
            t: &mut self.t[i],
            triangle: &mut self.triangle[i],
            source_id: &mut self.source_id[i],
            u: &mut self.u[i],
            v: &mut self.v[i],
            normal: &mut self.normal[3 * i..3 * i + 3],
            front_face: &mut self.front_face[i],
            instance: &mut self.instance[i],
        }
    }

    /// Appends a hit's row.
    fn push(&mut self, hit: &Hit) {
        self.t.push(hit.t);
        self.triangle.push(hit.triangle_index);
        self.source_id.push(hit.source_triangle_id.unwrap_or(NONE));
        self.u.push(hit.u);
        self.v.push(hit.v);
        self.normal.extend_from_slice(&hit.normal);
        self.front_face.push(hit.front_face);
        self.instance.push(hit.instance_index.unwrap_or(NONE));
    }

    /// The closest hits of `rays`, each chunk of rays read, checked and traced (by `trace`) by one task; the
    /// first ray that breaks the contract is the error (the hits are then dropped).
    pub fn traced(rays: RayArrays<'_>, trace: &BatchTrace<'_>) -> Result<HitColumns, BatchRayError> {
        let n = rays.len();
        let mut c = HitColumns::zeroed(n);
        let first_bad = (0..n.div_ceil(CHUNK))
            .into_par_iter()
            .zip(c.t.par_chunks_mut(CHUNK))
            .zip(c.triangle.par_chunks_mut(CHUNK))
            .zip(c.source_id.par_chunks_mut(CHUNK))
            .zip(c.u.par_chunks_mut(CHUNK))
            .zip(c.v.par_chunks_mut(CHUNK))
            .zip(c.normal.par_chunks_mut(3 * CHUNK))
            .zip(c.front_face.par_chunks_mut(CHUNK))
            .zip(c.instance.par_chunks_mut(CHUNK))
            .filter_map(|((((((((chunk, t), triangle), source_id), u), v), normal), front_face), instance)| {
                let mut buffer = [EMPTY_RAY; CHUNK];
                let chunk_rays = &mut buffer[..t.len()];
                if let Err(e) = rays.chunk(chunk * CHUNK, chunk_rays) {
                    return Some(e);
                }
                let mut hits = [None; CHUNK];
                let hits = &mut hits[..t.len()];
                trace(chunk_rays, hits);
                for (i, hit) in hits.iter().enumerate() {
                    let row = Row {
                        t: &mut t[i],
                        triangle: &mut triangle[i],
                        source_id: &mut source_id[i],
                        u: &mut u[i],
                        v: &mut v[i],
                        normal: &mut normal[3 * i..3 * i + 3],
                        front_face: &mut front_face[i],
                        instance: &mut instance[i],
                    };
                    row.write(hit.as_ref());
                }
                None
            })
            .min_by_key(|e| e.index);
        match first_bad {
            Some(e) => Err(e),
            None => Ok(c),
        }
    }

    /// The closest hits of `rays` in order on this thread, `trace(i, ray)` tracing ray `i` (for a Python
    /// callback, which needs the GIL). The rays are checked first, chunk by chunk.
    pub fn traced_in_order(
        rays: RayArrays<'_>,
        mut trace: impl FnMut(usize, &Ray) -> Option<Hit>,
    ) -> Result<HitColumns, BatchRayError> {
        let n = rays.len();
        let mut c = HitColumns::zeroed(n);
        let mut buffer = [EMPTY_RAY; CHUNK];
        for start in (0..n).step_by(CHUNK) {
            let chunk = &mut buffer[..CHUNK.min(n - start)];
            rays.chunk(start, chunk)?;
            for (k, ray) in chunk.iter().enumerate() {
                let hit = trace(start + k, ray);
                c.row(start + k).write(hit.as_ref());
            }
        }
        Ok(c)
    }

    /// The columns into `d`.
    fn fill<'py>(self, d: &Bound<'py, PyDict>) -> PyResult<()> {
        let py = d.py();
        let n = self.t.len();
        d.set_item("t", self.t.into_pyarray(py))?;
        d.set_item("triangle", self.triangle.into_pyarray(py))?;
        d.set_item("source_id", self.source_id.into_pyarray(py))?;
        d.set_item("u", self.u.into_pyarray(py))?;
        d.set_item("v", self.v.into_pyarray(py))?;
        let normal = Array2::from_shape_vec((n, 3), self.normal)
            .map_err(|e| crate::errors::InternalError::new_err(e.to_string()))?;
        d.set_item("normal", normal.into_pyarray(py))?;
        d.set_item("front_face", self.front_face.into_pyarray(py))?;
        d.set_item("instance", self.instance.into_pyarray(py))?;
        Ok(())
    }

    /// The columns as a dict of arrays.
    pub fn into_dict<'py>(self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        self.fill(&d)?;
        Ok(d)
    }
}

/// Every hit of a chunk of rays: for each ray, its hits (nearest first, at most the cap) and how many it has.
pub struct RayHits {
    /// Index of the first ray of the chunk.
    pub first_ray: usize,
    /// `(ray's offset in the chunk, hit)`, in order.
    pub hits: Vec<(u32, Hit)>,
    /// Hits each ray has, before the cap.
    pub found: Vec<u32>,
}

/// All hits of many rays as columns: a row a hit, `ray` naming its ray; `count` (kept) and `found` (before the
/// cap) a ray.
pub struct AllHitColumns {
    ray: Vec<u32>,
    columns: HitColumns,
    count: Vec<u32>,
    found: Vec<u32>,
}

impl AllHitColumns {
    /// The columns of `chunks` (in ray order) for `n` rays.
    pub fn from_chunks(chunks: Vec<RayHits>, n: usize) -> AllHitColumns {
        let total: usize = chunks.iter().map(|c| c.hits.len()).sum();
        let mut all = AllHitColumns {
            ray: Vec::with_capacity(total),
            columns: HitColumns::default(),
            count: vec![0; n],
            found: vec![0; n],
        };
        for chunk in chunks {
            for (k, found) in chunk.found.iter().enumerate() {
                all.found[chunk.first_ray + k] = *found;
            }
            for (offset, hit) in &chunk.hits {
                let ray = chunk.first_ray + *offset as usize;
                all.ray.push(ray as u32);
                all.count[ray] += 1;
                all.columns.push(hit);
            }
        }
        all
    }

    /// The columns as a dict of arrays.
    pub fn into_dict<'py>(self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("ray", self.ray.into_pyarray(py))?;
        self.columns.fill(&d)?;
        d.set_item("count", self.count.into_pyarray(py))?;
        d.set_item("found", self.found.into_pyarray(py))?;
        Ok(d)
    }
}
