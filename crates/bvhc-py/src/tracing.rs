//! The tracing calls' work, on the view of a scene's bytes: closest hits, any hits and all hits of rays (with or
//! without a filter, `filters.rs`), and inside tests of points. Without a Python callback they run on the pool
//! with the GIL released; with one, in order on the calling thread (the callback needs the GIL).

use bvhc::loader::Trace;
use std::cell::{Cell, RefCell};

use bvhc::loader::{BatchRayError, BvhView, Crossings, Hit, Order, Ray, Tracer};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;

use crate::core_hits::CoreColumns;
use crate::errors::{InvalidInputError, OptionsError};
use crate::filters::{FilterArgs, WithCallback};
use crate::hits::{AllHitColumns, CHUNK, EMPTY_RAY, HitColumns, RayHits};
use crate::rays::{RayArrays, Vectors};

/// The most threads a call takes, as the command line's `--threads` (1 to 1024).
const MAX_THREADS: usize = 1024;

/// A `threads` keyword checked as the command line checks `--threads` (1 to 1024; `OptionsError`, a usage
/// error, otherwise), `None` when not given.
pub fn threads_keyword(threads: Option<usize>) -> PyResult<Option<usize>> {
    match threads {
        Some(n) if !(1..=MAX_THREADS).contains(&n) => {
            Err(OptionsError::new_err(format!("threads {n}: expected 1 to {MAX_THREADS}, as --threads")))
        }
        other => Ok(other),
    }
}

/// A `threads` keyword checked ([`threads_keyword`]), or all cores when not given.
pub fn threads_or_all(threads: Option<usize>) -> PyResult<usize> {
    Ok(threads_keyword(threads)?.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, usize::from)))
}

/// A pool of `threads` threads ([`threads_keyword`]), or `None` for rayon's global pool (all cores).
pub fn pool(threads: Option<usize>) -> PyResult<Option<rayon::ThreadPool>> {
    threads_keyword(threads)?
        .map(|n| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| crate::errors::InternalError::new_err(format!("cannot start {n} threads: {e}")))
        })
        .transpose()
}

pub fn on_pool<R: Send>(pool: &Option<rayon::ThreadPool>, f: impl FnOnce() -> R + Send) -> R {
    match pool {
        Some(pool) => pool.install(f),
        None => f(),
    }
}

/// A callback filter over `view` for `args`, and the error it raised, if any, once `work` has run with it.
fn with_callback<'py, R>(
    view: &BvhView<'_>,
    args: &FilterArgs<'py>,
    callback: &Bound<'py, PyAny>,
    work: impl FnOnce(&WithCallback<'_, 'py>) -> R,
) -> PyResult<R> {
    let cutouts = args.cutouts(view)?;
    let filter = WithCallback { cutouts: &cutouts, callback, ray: Cell::new(0), error: RefCell::new(None) };
    let result = work(&filter);
    match filter.error.into_inner() {
        Some(error) => Err(error),
        None => Ok(result),
    }
}

/// The closest hits of `rays`, as columns; traced in packets of 8 consecutive rays when `order` is
/// [`Order::Coherent`] (the same hits; a callable filter traces one ray at a time either way).
pub fn closest(
    py: Python<'_>,
    view: &BvhView<'_>,
    rays: RayArrays<'_>,
    filter: Option<&FilterArgs<'_>>,
    (pool, order): (&Option<rayon::ThreadPool>, Order),
) -> PyResult<HitColumns> {
    let tracer = view.tracer().trusting_rays();
    let traced = match filter {
        None => py.detach(|| on_pool(pool, || HitColumns::traced(rays, &|r, h| closest_hits(&tracer, r, h, order)))),
        Some(args) => match &args.callback {
            None => {
                let cutouts = args.cutouts(view)?;
                let filtered = tracer.filtered(&cutouts, args.scope);
                py.detach(|| on_pool(pool, || HitColumns::traced(rays, &|r, h| closest_hits(&filtered, r, h, order))))
            }
            Some(callback) => with_callback(view, args, callback, |filter| {
                let filtered = tracer.filtered(filter, args.scope);
                HitColumns::traced_in_order(rays, |i, ray| {
                    filter.ray.set(i);
                    filtered.closest_hit(ray)
                })
            })?,
        },
    };
    traced.map_err(|e| rays.error(&e))
}

/// [`closest`] handed off lean: each ray's `t`, record, `u`, `v`, instance ([`CoreColumns`]), without a normal,
/// side or source id computed where the tracer can skip them (no callable filter). With a callable filter the
/// full hits are traced in order and these columns kept.
pub fn closest_lean<'py>(
    py: Python<'py>,
    view: &BvhView<'_>,
    rays: RayArrays<'_>,
    filter: Option<&FilterArgs<'_>>,
    (pool, order): (&Option<rayon::ThreadPool>, Order),
) -> PyResult<Bound<'py, PyDict>> {
    let tracer = view.tracer().trusting_rays();
    let traced = match filter {
        None => py.detach(|| on_pool(pool, || CoreColumns::traced(rays, &tracer, order))),
        Some(args) if args.callback.is_none() => {
            let cutouts = args.cutouts(view)?;
            let filtered = tracer.filtered(&cutouts, args.scope);
            py.detach(|| on_pool(pool, || CoreColumns::traced(rays, &filtered, order)))
        }
        Some(_) => {
            let full = closest(py, view, rays, filter, (pool, order))?.into_dict(py)?;
            let lean = PyDict::new(py);
            for key in ["t", "triangle", "u", "v", "instance"] {
                lean.set_item(key, full.get_item(key)?)?;
            }
            return Ok(lean);
        }
    };
    traced.map_err(|e| rays.error(&e))?.into_dict(py)
}

/// Whether each ray of `rays` hits anything (that the filter accepts); `order` as for [`closest`].
pub fn any(
    py: Python<'_>,
    view: &BvhView<'_>,
    rays: RayArrays<'_>,
    filter: Option<&FilterArgs<'_>>,
    (pool, order): (&Option<rayon::ThreadPool>, Order),
) -> PyResult<Vec<bool>> {
    let tracer = view.tracer().trusting_rays();
    let traced = match filter {
        None => py.detach(|| on_pool(pool, || any_in_chunks(rays, &|r, o| any_hits(&tracer, r, o, order)))),
        Some(args) => match &args.callback {
            None => {
                let cutouts = args.cutouts(view)?;
                let filtered = tracer.filtered(&cutouts, args.scope);
                py.detach(|| on_pool(pool, || any_in_chunks(rays, &|r, o| any_hits(&filtered, r, o, order))))
            }
            Some(callback) => with_callback(view, args, callback, |filter| {
                let filtered = tracer.filtered(filter, args.scope);
                in_order(rays, |i, ray| {
                    filter.ray.set(i);
                    filtered.any_hit(ray)
                })
            })?,
        },
    };
    traced.map_err(|e| rays.error(&e))
}

/// `tracer`'s closest hits of a chunk, as a stream or in coherent packets.
fn closest_hits(tracer: &impl Trace, rays: &[Ray], hits: &mut [Option<Hit>], order: Order) {
    match order {
        Order::Coherent => tracer.closest_hits_coherent(rays, hits),
        Order::Stream => tracer.closest_hits(rays, hits),
    }
}

/// `tracer`'s any-hit answers of a chunk, as a stream or in coherent packets.
fn any_hits(tracer: &impl Trace, rays: &[Ray], occluded: &mut [bool], order: Order) {
    match order {
        Order::Coherent => tracer.any_hits_coherent(rays, occluded),
        Order::Stream => tracer.any_hits(rays, occluded),
    }
}

/// `trace` over chunks of `rays` on the pool, into one flag a ray.
fn any_in_chunks(
    rays: RayArrays<'_>,
    trace: &(dyn Fn(&[Ray], &mut [bool]) + Sync),
) -> Result<Vec<bool>, BatchRayError> {
    let mut occluded = vec![false; rays.len()];
    let first_bad = occluded
        .par_chunks_mut(CHUNK)
        .enumerate()
        .filter_map(|(chunk, occluded)| {
            let mut buffer = [EMPTY_RAY; CHUNK];
            let chunk_rays = &mut buffer[..occluded.len()];
            if let Err(e) = rays.chunk(chunk * CHUNK, chunk_rays) {
                return Some(e);
            }
            trace(chunk_rays, occluded);
            None
        })
        .min_by_key(|e| e.index);
    match first_bad {
        Some(e) => Err(e),
        None => Ok(occluded),
    }
}

/// `trace(i, ray)` of every ray in order on this thread, the rays checked chunk by chunk.
fn in_order<T>(rays: RayArrays<'_>, mut trace: impl FnMut(usize, &Ray) -> T) -> Result<Vec<T>, BatchRayError> {
    let mut out = Vec::with_capacity(rays.len());
    let mut buffer = [EMPTY_RAY; CHUNK];
    for start in (0..rays.len()).step_by(CHUNK) {
        let chunk = &mut buffer[..CHUNK.min(rays.len() - start)];
        rays.chunk(start, chunk)?;
        for (k, ray) in chunk.iter().enumerate() {
            out.push(trace(start + k, ray));
        }
    }
    Ok(out)
}

/// The crossings of a view, its rays trusted (the calls check them first).
fn crossings<'a>(view: &BvhView<'a>) -> Crossings<'a> {
    let tracer: Tracer<'a> = view.tracer().trusting_rays();
    Crossings::new(tracer, view.triangles(), view.triangle_identities())
}

/// Every hit of each ray (the nearest `max_hits`), as columns.
pub fn all(
    py: Python<'_>,
    view: &BvhView<'_>,
    rays: RayArrays<'_>,
    filter: Option<&FilterArgs<'_>>,
    max_hits: usize,
    pool: &Option<rayon::ThreadPool>,
) -> PyResult<AllHitColumns> {
    if max_hits == 0 {
        return Err(InvalidInputError::new_err("max_hits: expected at least 1"));
    }
    let crossings = crossings(view);
    let n = rays.len();
    let chunks = match filter {
        None => py.detach(|| on_pool(pool, || all_in_chunks(rays, max_hits, &|ray, out| crossings.all_hits(ray, out)))),
        Some(args) => match &args.callback {
            None => {
                let (cutouts, scope) = (args.cutouts(view)?, args.scope);
                let each = |ray: &Ray, out: &mut Vec<Hit>| crossings.all_hits_filtered(ray, &cutouts, scope, out);
                py.detach(|| on_pool(pool, || all_in_chunks(rays, max_hits, &each)))
            }
            Some(callback) => with_callback(view, args, callback, |filter| {
                let mut hits = Vec::new();
                let per_ray = in_order(rays, |i, ray| {
                    filter.ray.set(i);
                    crossings.all_hits_filtered(ray, filter, args.scope, &mut hits);
                    let found = hits.len() as u32;
                    (found, hits.drain(..).take(max_hits).collect::<Vec<_>>())
                });
                per_ray.map(|per_ray| {
                    let mut chunk = RayHits { first_ray: 0, hits: Vec::new(), found: Vec::with_capacity(n) };
                    for (i, (found, hits)) in per_ray.into_iter().enumerate() {
                        chunk.found.push(found);
                        chunk.hits.extend(hits.into_iter().map(|h| (i as u32, h)));
                    }
                    vec![chunk]
                })
            })?,
        },
    };
    let chunks = chunks.map_err(|e| rays.error(&e))?;
    Ok(AllHitColumns::from_chunks(chunks, n))
}

/// Every hit of chunks of rays on the pool, `each(ray, out)` finding a ray's.
fn all_in_chunks(
    rays: RayArrays<'_>,
    max_hits: usize,
    each: &(dyn Fn(&Ray, &mut Vec<Hit>) + Sync),
) -> Result<Vec<RayHits>, BatchRayError> {
    (0..rays.len().div_ceil(CHUNK))
        .into_par_iter()
        .map(|chunk| {
            let first_ray = chunk * CHUNK;
            let mut buffer = [EMPTY_RAY; CHUNK];
            let chunk_rays = &mut buffer[..CHUNK.min(rays.len() - first_ray)];
            rays.chunk(first_ray, chunk_rays)?;
            let mut result = RayHits { first_ray, hits: Vec::new(), found: Vec::with_capacity(chunk_rays.len()) };
            let mut hits = Vec::new();
            for (k, ray) in chunk_rays.iter().enumerate() {
                each(ray, &mut hits);
                result.found.push(hits.len() as u32);
                result.hits.extend(hits.drain(..).take(max_hits).map(|h| (k as u32, h)));
            }
            Ok(result)
        })
        .collect()
}

/// Whether each point lies inside the scene's closed meshes.
pub fn contains(
    py: Python<'_>,
    view: &BvhView<'_>,
    points: &Vectors<'_>,
    pool: &Option<rayon::ThreadPool>,
) -> PyResult<Vec<bool>> {
    let points = points.rows(py)?;
    if let Some(bad) = points.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        return Err(InvalidInputError::new_err(format!("points: point {bad} {:?} is not finite", points[bad])));
    }
    let crossings = crossings(view);
    Ok(py.detach(|| on_pool(pool, || points.par_iter().map(|p| crossings.contains(*p)).collect())))
}
