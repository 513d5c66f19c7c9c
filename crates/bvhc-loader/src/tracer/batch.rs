//! The batch calls of [`Tracer`] ([`crate::Trace`]'s `closest_hits_with` and `any_hits_with`, on which the slice calls
//! stand): closest and any hits of many rays, as a stream (rays interleaved over large
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
use crate::ray::hit::{Hit, HitCore};
use crate::ray::intersect::Ray;
use crate::trace::Order;
use crate::tracer::Tracer;

/// Rays a batch call checks at a time before tracing them (32 KiB of rays, which stay in the core's caches
/// between the check and the tracing). A multiple of 8, so that coherent packets keep their groups.
pub const CHECKED_CHUNK: usize = 1024;
const _: () = assert!(CHECKED_CHUNK.is_multiple_of(8));

impl Tracer<'_> {
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
    pub(crate) fn closest_hits_each(
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
                Some(wide) => wide.closest_hits_each(chunk, order, each),
                None => chunk.iter().enumerate().for_each(|(i, ray)| each(i, self.closest_hit_trusted(ray, &mut ()))),
            }
        }
        Ok(())
    }

    /// Each ray's closest hit to `each`, handed off lean ([`HitCore`]): in a one-level file the wide kernel then
    /// computes no normal, side or source id; as [`Tracer::closest_hits_each`] otherwise.
    pub(crate) fn closest_hit_cores_each(
        &self,
        rays: &[Ray],
        order: Order,
        each: &mut impl FnMut(usize, Option<HitCore>),
    ) -> Result<(), BatchRayError> {
        let Some(wide) = self.one_level_wide() else {
            return self.closest_hits_each(rays, order, &mut |i, hit| each(i, hit.map(|hit| hit.core())));
        };
        for (c, chunk) in rays.chunks(CHECKED_CHUNK).enumerate() {
            let first = c * CHECKED_CHUNK;
            self.check_chunk(chunk, first)?;
            wide.closest_hit_cores_each(chunk, order, &mut |i: usize, hit| each(first + i, hit));
        }
        Ok(())
    }

    /// Each ray's any-hit answer to `each`, as [`Tracer::closest_hits_each`].
    pub(crate) fn any_hits_each(
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
                Some(wide) => wide.any_hits_each(chunk, order, each),
                None => chunk.iter().enumerate().for_each(|(i, ray)| each(i, self.any_hit_trusted(ray, &mut ()))),
            }
        }
        Ok(())
    }
}
