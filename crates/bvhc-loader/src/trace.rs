//! [`Trace`]: the calls every CPU tracer answers (beneath the tracers, so that each layout's tracer implements it
//! without importing upward) ([`crate::Tracer`], [`crate::WideTracer`],
//! [`crate::FilteredTracer`], [`crate::gpu::GpuLayoutTracer`]). A tracer writes the two single-ray queries; the
//! batch calls are provided on top of them, and a tracer with a faster way (streams of interleaved rays, coherent
//! packets, rays checked chunk by chunk) writes its own `closest_hits_with` and `any_hits_with`.

use crate::ray::check::BatchRayError;
use crate::ray::hit::{Hit, HitCore, TraversalCounter, same_length, slot_writer};
use crate::ray::intersect::Ray;

/// How a batch call traces its rays; the results are the same either way (ties are decided by spec 11.1), but
/// for which record of a split triangle a hit names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Order {
    /// Ray by ray (interleaved over large files by the wide kernel), except that the wide kernel traces each
    /// group of 8 consecutive rays whose origins are equal bit for bit (a pinhole camera's, a point light's, one
    /// hit's ambient-occlusion rays), or close together with directions in one octant, as a packet: the same
    /// hits either way.
    Stream,
    /// Each 8 consecutive rays together (camera rays of neighbouring pixels), where the tracer can; ray by ray
    /// otherwise.
    Coherent,
}

/// What a `_with` batch call returns: `Err` with the first ray that breaks the contract, for a tracer that checks.
pub type BatchResult = Result<(), BatchRayError>;

/// Closest-hit and any-hit queries, one ray or many. Tracing takes `&self` and allocates nothing.
///
/// Rays: a tracer that checks rays (a [`crate::Tracer`] unless made with `trusting_rays`) panics on a ray that
/// breaks the contract ([`Ray::check`]), naming the call and the rule; the `_with` calls return the first such
/// ray as an error instead.
pub trait Trace {
    /// The closest hit with `t_min <= t <= t_max`, counting node visits and triangle tests into `counter`.
    fn closest_hit_counted(&self, ray: &Ray, counter: &mut impl TraversalCounter) -> Option<Hit>;

    /// Whether anything is hit with `t_min <= t <= t_max` (stops at the first hit found), counting as
    /// [`Trace::closest_hit_counted`] does.
    fn any_hit_counted(&self, ray: &Ray, counter: &mut impl TraversalCounter) -> bool;

    /// The closest hit with `t_min <= t <= t_max`.
    #[track_caller]
    fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        self.closest_hit_counted(ray, &mut ())
    }

    /// Whether anything is hit with `t_min <= t <= t_max` (occlusion).
    #[track_caller]
    fn any_hit(&self, ray: &Ray) -> bool {
        self.any_hit_counted(ray, &mut ())
    }

    /// Each ray's closest hit passed to `each(i, hit)`, once per ray, in no particular order (for results kept
    /// in the caller's own layout, written where they belong without a copy). A ray that breaks the contract
    /// (for a tracer that checks rays) is the error; `each` has then been called for some rays before it only.
    #[track_caller]
    fn closest_hits_with(&self, rays: &[Ray], order: Order, mut each: impl FnMut(usize, Option<Hit>)) -> BatchResult {
        let _ = order;
        rays.iter().enumerate().for_each(|(i, ray)| each(i, self.closest_hit_counted(ray, &mut ())));
        Ok(())
    }

    /// [`Trace::closest_hits_with`] handing off each hit lean, as its [`HitCore`] (`t`, record, `u`, `v`,
    /// instance: the same values as the full hit's), for callers that keep those in their own arrays and need
    /// no normal, side or source id, or only for some hits. Where a tracer computes those apart from the walk
    /// (a one-level file's wide kernel, [`crate::Tracer`]) they are then not computed; elsewhere this maps the
    /// full hits.
    #[track_caller]
    fn closest_hit_cores_with(
        &self,
        rays: &[Ray],
        order: Order,
        mut each: impl FnMut(usize, Option<HitCore>),
    ) -> BatchResult {
        self.closest_hits_with(rays, order, |i, hit| each(i, hit.map(|hit| hit.core())))
    }

    /// Whether each ray hits anything, passed to `each(i, occluded)`, as [`Trace::closest_hits_with`].
    #[track_caller]
    fn any_hits_with(&self, rays: &[Ray], order: Order, mut each: impl FnMut(usize, bool)) -> BatchResult {
        let _ = order;
        rays.iter().enumerate().for_each(|(i, ray)| each(i, self.any_hit_counted(ray, &mut ())));
        Ok(())
    }

    /// The closest hit of each ray into the `hits` slot of the same index.
    ///
    /// # Panics
    ///
    /// When `hits` is not as long as `rays` (before tracing), or (for a tracer that checks rays) a ray breaks the
    /// contract: the message names the first such ray.
    #[track_caller]
    fn closest_hits(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        into_slots("closest_hits", rays, hits, |each| self.closest_hits_with(rays, Order::Stream, each));
    }

    /// Whether each ray hits anything, into the `occluded` slot of the same index.
    ///
    /// # Panics
    ///
    /// As [`Trace::closest_hits`].
    #[track_caller]
    fn any_hits(&self, rays: &[Ray], occluded: &mut [bool]) {
        into_slots("any_hits", rays, occluded, |each| self.any_hits_with(rays, Order::Stream, each));
    }

    /// [`Trace::closest_hits`] for coherent rays ([`Order::Coherent`]): the same hit for each ray as one at a time,
    /// ties decided as spec 11.1 says (with split references, possibly another record of the same triangle). A
    /// camera's rays laid out in blocks of 4 pixels by 2 rows (each 8 consecutive rays a block) run 5-12% faster
    /// than rows (`docs/kernel-peer.md`).
    ///
    /// # Panics
    ///
    /// As [`Trace::closest_hits`].
    #[track_caller]
    fn closest_hits_coherent(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        into_slots("closest_hits_coherent", rays, hits, |each| self.closest_hits_with(rays, Order::Coherent, each));
    }

    /// [`Trace::any_hits`] for coherent rays ([`Order::Coherent`]); the same answers.
    ///
    /// # Panics
    ///
    /// As [`Trace::closest_hits`].
    #[track_caller]
    fn any_hits_coherent(&self, rays: &[Ray], occluded: &mut [bool]) {
        into_slots("any_hits_coherent", rays, occluded, |each| self.any_hits_with(rays, Order::Coherent, each));
    }
}

/// A slice call (`call`) through its `_with` call `trace`: each result into the slot of its ray's index; a
/// panic naming the call when the lengths differ or a ray breaks the contract.
#[track_caller]
fn into_slots<T>(
    call: &str,
    rays: &[Ray],
    slots: &mut [T],
    trace: impl FnOnce(&mut dyn FnMut(usize, T)) -> BatchResult,
) {
    same_length(call, rays.len(), slots.len());
    if let Err(error) = trace(&mut slot_writer(slots)) {
        refused(call, &error);
    }
}

/// The panic of a checked call on a ray that breaks the contract.
#[cold]
#[inline(never)]
#[track_caller]
pub(crate) fn refused(call: &str, error: &dyn std::fmt::Display) -> ! {
    panic!(
        "Tracer::{call}: the ray breaks the ray contract: {error} (check rays with Ray::check, or use \
         Tracer::trusting_rays to trace them unchecked)"
    )
}
