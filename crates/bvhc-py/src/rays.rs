//! Rays from numpy arrays and hits into numpy arrays. Origins and directions are `(n, 3)` arrays of float32 or
//! float64, C-ordered or strided (read in place; float64 is rounded to float32, the precision the kernels trace
//! in); `t_min` and `t_max` a number or an `(n,)` array. Rays are checked as `bvhc trace` checks them, and the
//! first that breaks the contract is named.

use bvhc::loader::{BatchRayError, Ray, check_rays};
use numpy::ndarray::{ArrayView1, ArrayView2};
use numpy::{PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

use crate::errors::InvalidInputError;

/// Rays gathered and checked a task.
const CHECK_CHUNK: usize = 16 * 1024;

/// An `(n, 3)` array argument, borrowed read-only.
pub enum Vectors<'py> {
    F32(PyReadonlyArray2<'py, f32>),
    F64(PyReadonlyArray2<'py, f64>),
}

/// A per-ray bound: one number, or an `(n,)` array.
pub enum Bound1<'py> {
    Scalar(f32),
    F32(PyReadonlyArray1<'py, f32>),
    F64(PyReadonlyArray1<'py, f64>),
}

/// The borrowed arrays' views (`Send`, for tracing with the GIL released).
#[derive(Clone, Copy)]
enum VectorsView<'a> {
    /// C-ordered float32: the rows read straight from the buffer.
    Flat(&'a [f32]),
    F32(ArrayView2<'a, f32>),
    F64(ArrayView2<'a, f64>),
}

#[derive(Clone, Copy)]
enum BoundView<'a> {
    Scalar(f32),
    F32(ArrayView1<'a, f32>),
    F64(ArrayView1<'a, f64>),
}

impl<'py> Vectors<'py> {
    /// `value` as an `(n, 3)` float array named `name` in errors.
    pub fn extract(name: &str, value: &pyo3::Bound<'py, PyAny>) -> PyResult<Vectors<'py>> {
        let vectors = if let Ok(a) = value.extract::<PyReadonlyArray2<'py, f32>>() {
            Vectors::F32(a)
        } else if let Ok(a) = value.extract::<PyReadonlyArray2<'py, f64>>() {
            Vectors::F64(a)
        } else {
            return Err(InvalidInputError::new_err(format!(
                "{name}: expected a numpy array of shape (n, 3) and dtype float32 or float64"
            )));
        };
        let shape = match &vectors {
            Vectors::F32(a) => a.shape().to_vec(),
            Vectors::F64(a) => a.shape().to_vec(),
        };
        if shape[1] != 3 {
            return Err(InvalidInputError::new_err(format!("{name}: shape {shape:?}, expected (n, 3)")));
        }
        Ok(vectors)
    }

    /// Every row, as float32 (float64 rounded once).
    pub fn rows(&self, _py: Python<'_>) -> PyResult<Vec<[f32; 3]>> {
        let view = self.view();
        Ok((0..self.len()).map(|i| view.row(i)).collect())
    }

    /// Rows.
    pub fn len(&self) -> usize {
        match self {
            Vectors::F32(a) => a.shape()[0],
            Vectors::F64(a) => a.shape()[0],
        }
    }

    fn view(&self) -> VectorsView<'_> {
        match self {
            Vectors::F32(a) => match a.as_slice() {
                Ok(flat) => VectorsView::Flat(flat),
                Err(_) => VectorsView::F32(a.as_array()),
            },
            Vectors::F64(a) => VectorsView::F64(a.as_array()),
        }
    }
}

impl VectorsView<'_> {
    fn row(&self, i: usize) -> [f32; 3] {
        match self {
            VectorsView::Flat(flat) => {
                let row = &flat[3 * i..3 * i + 3];
                [row[0], row[1], row[2]]
            }
            VectorsView::F32(a) => [a[[i, 0]], a[[i, 1]], a[[i, 2]]],
            VectorsView::F64(a) => [a[[i, 0]] as f32, a[[i, 1]] as f32, a[[i, 2]] as f32],
        }
    }
}

impl<'py> Bound1<'py> {
    /// `value` as a number or an `(n,)` float array, named `name` in errors.
    pub fn extract(name: &str, value: &pyo3::Bound<'py, PyAny>, n: usize) -> PyResult<Bound1<'py>> {
        let bound = if let Ok(a) = value.extract::<PyReadonlyArray1<'py, f32>>() {
            Bound1::F32(a)
        } else if let Ok(a) = value.extract::<PyReadonlyArray1<'py, f64>>() {
            Bound1::F64(a)
        } else if let Ok(x) = value.extract::<f64>() {
            Bound1::Scalar(x as f32)
        } else {
            return Err(InvalidInputError::new_err(format!(
                "{name}: expected a number or a numpy array of shape (n,) and dtype float32 or float64"
            )));
        };
        let len = match &bound {
            Bound1::Scalar(_) => n,
            Bound1::F32(a) => a.len(),
            Bound1::F64(a) => a.len(),
        };
        if len != n {
            return Err(InvalidInputError::new_err(format!("{name}: {len} values for {n} rays")));
        }
        Ok(bound)
    }

    fn view(&self) -> BoundView<'_> {
        match self {
            Bound1::Scalar(x) => BoundView::Scalar(*x),
            Bound1::F32(a) => BoundView::F32(a.as_array()),
            Bound1::F64(a) => BoundView::F64(a.as_array()),
        }
    }
}

impl BoundView<'_> {
    fn at(&self, i: usize) -> f32 {
        match self {
            BoundView::Scalar(x) => *x,
            BoundView::F32(a) => a[i],
            BoundView::F64(a) => a[i] as f32,
        }
    }
}

/// The four ray arguments of a tracing call (`origins`, `directions`, `t_min`, `t_max`), borrowed read-only.
pub struct RayArguments<'py> {
    origins: Vectors<'py>,
    directions: Vectors<'py>,
    t_min: Bound1<'py>,
    t_max: Bound1<'py>,
}

impl<'py> RayArguments<'py> {
    /// The arguments as arrays and bounds, named in errors as the Python parameters.
    pub fn extract(
        origins: &pyo3::Bound<'py, PyAny>,
        directions: &pyo3::Bound<'py, PyAny>,
        t_min: &pyo3::Bound<'py, PyAny>,
        t_max: &pyo3::Bound<'py, PyAny>,
    ) -> PyResult<RayArguments<'py>> {
        let origins = Vectors::extract("origins", origins)?;
        let directions = Vectors::extract("directions", directions)?;
        let t_min = Bound1::extract("t_min", t_min, origins.len())?;
        let t_max = Bound1::extract("t_max", t_max, origins.len())?;
        Ok(RayArguments { origins, directions, t_min, t_max })
    }

    /// The rays they describe.
    pub fn rays(&self) -> PyResult<RayArrays<'_>> {
        RayArrays::new(&self.origins, &self.directions, &self.t_min, &self.t_max)
    }
}

/// The rays the arrays describe, read where they are traced, a chunk at a time (no copy of the whole set).
#[derive(Clone, Copy)]
pub struct RayArrays<'a> {
    origins: VectorsView<'a>,
    directions: VectorsView<'a>,
    t_min: BoundView<'a>,
    t_max: BoundView<'a>,
    len: usize,
}

impl<'a> RayArrays<'a> {
    /// The rays of the arrays, which must have a row each.
    pub fn new(
        origins: &'a Vectors<'_>,
        directions: &'a Vectors<'_>,
        t_min: &'a Bound1<'_>,
        t_max: &'a Bound1<'_>,
    ) -> PyResult<RayArrays<'a>> {
        let len = origins.len();
        if directions.len() != len {
            return Err(InvalidInputError::new_err(format!("{len} origins but {} directions", directions.len())));
        }
        Ok(RayArrays {
            origins: origins.view(),
            directions: directions.view(),
            t_min: t_min.view(),
            t_max: t_max.view(),
            len,
        })
    }

    /// Rays.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Ray `i`, as given (unchecked).
    pub fn ray(&self, i: usize) -> Ray {
        Ray {
            origin: self.origins.row(i),
            direction: self.directions.row(i),
            t_min: self.t_min.at(i),
            t_max: self.t_max.at(i),
        }
    }

    /// Rays `start ..` into `out`, checked: the first that breaks the contract is the error.
    pub fn chunk(&self, start: usize, out: &mut [Ray]) -> Result<(), BatchRayError> {
        for (k, ray) in out.iter_mut().enumerate() {
            *ray = self.ray(start + k);
        }
        check_rays(out).map_err(|e| BatchRayError { index: start + e.index, error: e.error })
    }

    /// The exception for a ray that breaks the contract, naming it and its values.
    pub fn error(&self, e: &BatchRayError) -> PyErr {
        let ray = self.ray(e.index);
        InvalidInputError::new_err(format!(
            "ray {}: {} (origin {:?}, direction {:?}, t_min {}, t_max {}); rays need a finite origin and direction, \
             the direction's largest component at least 2^-64 in magnitude, and 0 <= t_min <= t_max",
            e.index, e.error, ray.origin, ray.direction, ray.t_min, ray.t_max
        ))
    }

    /// Every ray, checked (the GIL released while they are gathered and checked, in parallel).
    pub fn gather(&self, py: Python<'_>) -> PyResult<Vec<Ray>> {
        use rayon::prelude::*;
        let zero = Ray { origin: [0.0; 3], direction: [1.0, 0.0, 0.0], t_min: 0.0, t_max: 0.0 };
        let mut rays = vec![zero; self.len];
        let first_bad = py.detach(|| {
            rays.par_chunks_mut(CHECK_CHUNK)
                .enumerate()
                .filter_map(|(c, chunk)| self.chunk(c * CHECK_CHUNK, chunk).err())
                .min_by_key(|e| e.index)
        });
        match first_bad {
            Some(e) => Err(self.error(&e)),
            None => Ok(rays),
        }
    }
}
