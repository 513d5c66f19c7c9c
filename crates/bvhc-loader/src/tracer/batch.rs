//! The batch calls of [`Tracer`]: closest and any hits of many rays, as a stream (rays interleaved over large
//! files) or in coherent packets of 8, into slices of results or, for bindings that keep results in their own
//! layout (the C API, an array library), to a callback that receives each ray's result once, with no
//! intermediate buffer.
//!
//! Unless the tracer trusts its rays, each call checks its rays against the ray contract chunk by chunk
//! ([`CHECKED_CHUNK`] rays), each chunk just before tracing it, so the rays are read a second time from the
//! caches rather than from memory: checking a whole 100,000-ray batch first measured 5-15% of the tracing
//! time, for the memory traffic alone. A ray that breaks the contract stops the call there: the slice calls
//! panic naming it, the `_with` calls return it as an error; results of the chunks before it have been written.

use crate::ray::check::BatchRayError;
use crate::ray::hit::{Hit, slot_writer};
use crate::ray::intersect::Ray;
use crate::tracer::{Tracer, refused};

/// Rays a batch call checks at a time before tracing them (32 KiB of rays, which stay in the core's caches
/// between the check and the tracing). A multiple of 8, so that coherent packets keep their groups.
pub const CHECKED_CHUNK: usize = 1024;
const _: () = assert!(CHECKED_CHUNK.is_multiple_of(8));

/// How a batch call traces its rays.
#[derive(Clone, Copy)]
enum Order {
    /// One ray at a time (interleaved over large files).
    Stream,
    /// Each 8 consecutive rays together.
    Coherent,
}

impl Tracer<'_> {
    /// The closest hit of each ray into the `hits` slot of the same index: [`Tracer::closest_hit`] of each ray,
    /// with the wide kernel's stream when the tracer runs it ([`crate::WideTracer::closest_hits`]: rays
    /// interleaved over large files).
    ///
    /// # Panics
    ///
    /// When `hits` is not as long as `rays` (before tracing), or (for a tracer that checks rays) a ray breaks
    /// the contract: the message names the first such ray (see the module doc).
    #[track_caller]
    pub fn closest_hits(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        crate::ray::hit::same_length("closest_hits", rays.len(), hits.len());
        let traced = self.closest_hits_each(rays, Order::Stream, &mut slot_writer(hits));
        if let Err(error) = traced {
            refused("closest_hits", &error);
        }
    }

    /// [`Tracer::closest_hits`] with each ray's hit passed to `each(i, hit)` (once per ray, in no particular
    /// order) instead of stored: for results kept in another layout, written where they belong without a copy.
    /// A ray that breaks the contract (for a tracer that checks rays) is returned as an error, and `each` has
    /// then been called for the rays of the chunks before it only.
    pub fn closest_hits_with(
        &self,
        rays: &[Ray],
        mut each: impl FnMut(usize, Option<Hit>),
    ) -> Result<(), BatchRayError> {
        self.closest_hits_each(rays, Order::Stream, &mut each)
    }

    /// Whether each ray hits anything, into the `occluded` slot of the same index, as [`Tracer::closest_hits`]
    /// does for closest hits.
    ///
    /// # Panics
    ///
    /// As [`Tracer::closest_hits`].
    #[track_caller]
    pub fn any_hits(&self, rays: &[Ray], occluded: &mut [bool]) {
        crate::ray::hit::same_length("any_hits", rays.len(), occluded.len());
        let traced = self.any_hits_each(rays, Order::Stream, &mut slot_writer(occluded));
        if let Err(error) = traced {
            refused("any_hits", &error);
        }
    }

    /// [`Tracer::any_hits`] with each ray's answer passed to `each(i, occluded)`, as
    /// [`Tracer::closest_hits_with`].
    pub fn any_hits_with(&self, rays: &[Ray], mut each: impl FnMut(usize, bool)) -> Result<(), BatchRayError> {
        self.any_hits_each(rays, Order::Stream, &mut each)
    }

    /// [`Tracer::closest_hits`] for coherent rays (camera rays of neighbouring pixels): with the wide kernel,
    /// 8 consecutive rays share a traversal ([`crate::WideTracer::closest_hits_coherent`]: the same `t` for each
    /// ray, on a tie possibly another triangle at it); with the binary kernel, one ray after the other.
    ///
    /// # Panics
    ///
    /// As [`Tracer::closest_hits`].
    #[track_caller]
    pub fn closest_hits_coherent(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        crate::ray::hit::same_length("closest_hits_coherent", rays.len(), hits.len());
        let traced = self.closest_hits_each(rays, Order::Coherent, &mut slot_writer(hits));
        if let Err(error) = traced {
            refused("closest_hits_coherent", &error);
        }
    }

    /// [`Tracer::closest_hits_coherent`] with each ray's hit passed to `each(i, hit)`, as
    /// [`Tracer::closest_hits_with`].
    pub fn closest_hits_coherent_with(
        &self,
        rays: &[Ray],
        mut each: impl FnMut(usize, Option<Hit>),
    ) -> Result<(), BatchRayError> {
        self.closest_hits_each(rays, Order::Coherent, &mut each)
    }

    /// [`Tracer::any_hits`] for coherent rays, as [`Tracer::closest_hits_coherent`].
    ///
    /// # Panics
    ///
    /// As [`Tracer::closest_hits`].
    #[track_caller]
    pub fn any_hits_coherent(&self, rays: &[Ray], occluded: &mut [bool]) {
        crate::ray::hit::same_length("any_hits_coherent", rays.len(), occluded.len());
        let traced = self.any_hits_each(rays, Order::Coherent, &mut slot_writer(occluded));
        if let Err(error) = traced {
            refused("any_hits_coherent", &error);
        }
    }

    /// [`Tracer::any_hits_coherent`] with each ray's answer passed to `each(i, occluded)`, as
    /// [`Tracer::closest_hits_with`].
    pub fn any_hits_coherent_with(&self, rays: &[Ray], mut each: impl FnMut(usize, bool)) -> Result<(), BatchRayError> {
        self.any_hits_each(rays, Order::Coherent, &mut each)
    }

    /// `chunk` (rays `first..` of a batch) checked against the contract, unless this tracer trusts its rays.
    #[inline(always)]
    fn check_chunk(&self, chunk: &[Ray], first: usize) -> Result<(), BatchRayError> {
        match self.checks_rays() {
            true => crate::ray::check::check_rays(chunk).map_err(|e| BatchRayError { index: first + e.index, ..e }),
            false => Ok(()),
        }
    }

    /// Each ray's closest hit to `each`: the wide kernel's stream or packets in a one-level file, one ray after
    /// the other otherwise; chunk by chunk, each checked first.
    fn closest_hits_each(
        &self,
        rays: &[Ray],
        order: Order,
        each: &mut impl FnMut(usize, Option<Hit>),
    ) -> Result<(), BatchRayError> {
        for (c, chunk) in rays.chunks(CHECKED_CHUNK).enumerate() {
            let first = c * CHECKED_CHUNK;
            self.check_chunk(chunk, first)?;
            let each = &mut |i: usize, hit: Option<Hit>| each(first + i, hit);
            match self.one_level_wide() {
                Some(wide) => wide.closest_hits_with(chunk, matches!(order, Order::Coherent), each),
                None => chunk.iter().enumerate().for_each(|(i, ray)| each(i, self.closest_hit_trusted(ray, &mut ()))),
            }
        }
        Ok(())
    }

    /// Each ray's any-hit answer to `each`, as [`Tracer::closest_hits_each`].
    fn any_hits_each(
        &self,
        rays: &[Ray],
        order: Order,
        each: &mut impl FnMut(usize, bool),
    ) -> Result<(), BatchRayError> {
        for (c, chunk) in rays.chunks(CHECKED_CHUNK).enumerate() {
            let first = c * CHECKED_CHUNK;
            self.check_chunk(chunk, first)?;
            let each = &mut |i: usize, occluded: bool| each(first + i, occluded);
            match self.one_level_wide() {
                Some(wide) => wide.any_hits_with(chunk, matches!(order, Order::Coherent), each),
                None => chunk.iter().enumerate().for_each(|(i, ray)| each(i, self.any_hit_trusted(ray, &mut ()))),
            }
        }
        Ok(())
    }
}
