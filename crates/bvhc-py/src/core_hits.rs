//! Closest hits handed off lean (`closest_hits(..., lean=True)`): each ray's `t`, record, `u`, `v` and instance
//! as numpy columns, through the loader's `Trace::closest_hit_cores_with`, which in a one-level file computes no
//! normal, side or source id.

use bvhc::loader::{BatchRayError, HitCore, Order, Trace};
use numpy::IntoPyArray;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;

use crate::hits::{CHUNK, EMPTY_RAY, NONE};
use crate::rays::RayArrays;

/// The lean columns, a row a ray.
pub struct CoreColumns {
    t: Vec<f32>,
    triangle: Vec<u32>,
    u: Vec<f32>,
    v: Vec<f32>,
    instance: Vec<u32>,
}

impl CoreColumns {
    /// The closest hits of `rays` by `tracer` in `order`, each chunk of rays read, checked and traced by one task
    /// of the current pool; the first ray that breaks the contract is the error.
    pub fn traced(
        rays: RayArrays<'_>,
        tracer: &(impl Trace + Sync),
        order: Order,
    ) -> Result<CoreColumns, BatchRayError> {
        let n = rays.len();
        let mut c = CoreColumns {
            t: vec![0.0; n],
            triangle: vec![0; n],
            u: vec![0.0; n],
            v: vec![0.0; n],
            instance: vec![0; n],
        };
        let first_bad = (0..n.div_ceil(CHUNK))
            .into_par_iter()
            .zip(c.t.par_chunks_mut(CHUNK))
            .zip(c.triangle.par_chunks_mut(CHUNK))
            .zip(c.u.par_chunks_mut(CHUNK))
            .zip(c.v.par_chunks_mut(CHUNK))
            .zip(c.instance.par_chunks_mut(CHUNK))
            .filter_map(|(((((chunk, t), triangle), u), v), instance)| {
                let mut buffer = [EMPTY_RAY; CHUNK];
                let chunk_rays = &mut buffer[..t.len()];
                if let Err(e) = rays.chunk(chunk * CHUNK, chunk_rays) {
                    return Some(e);
                }
                let traced = tracer.closest_hit_cores_with(chunk_rays, order, |i, core: Option<HitCore>| {
                    let miss = HitCore { t: f32::INFINITY, triangle_index: NONE, u: 0.0, v: 0.0, instance_index: None };
                    let core = core.unwrap_or(miss);
                    (t[i], triangle[i], u[i], v[i]) = (core.t, core.triangle_index, core.u, core.v);
                    instance[i] = core.instance_index.unwrap_or(NONE);
                });
                traced.err().map(|e| BatchRayError { index: chunk * CHUNK + e.index, ..e })
            })
            .min_by_key(|e| e.index);
        match first_bad {
            Some(e) => Err(e),
            None => Ok(c),
        }
    }

    /// The columns as a dict of arrays: `t`, `triangle`, `u`, `v`, `instance`.
    pub fn into_dict<'py>(self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("t", self.t.into_pyarray(py))?;
        d.set_item("triangle", self.triangle.into_pyarray(py))?;
        d.set_item("u", self.u.into_pyarray(py))?;
        d.set_item("v", self.v.into_pyarray(py))?;
        d.set_item("instance", self.instance.into_pyarray(py))?;
        Ok(d)
    }
}
