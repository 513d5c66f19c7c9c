//! Hit filters: a callback that sees each candidate hit before the kernel accepts it, and may reject it, after
//! which traversal goes on as if the triangle were not hit (Embree's intersection and occlusion filter
//! functions, a DXR any-hit shader). Renderers use it for alpha-tested geometry: foliage, fences and chains cut
//! out by a texture's alpha (glTF `alphaMode` `MASK`).
//!
//! **Opaque triangles pay nothing.** The converter records in the file which triangles come from materials that
//! may cut them out (the `triangle_flags` section of format 1.5, [`crate::format::TRIANGLE_NOT_OPAQUE`]), and
//! with [`FilterScope::NotOpaque`] the kernel accepts a hit on any other triangle at once, without calling the
//! filter (DXR's per-geometry opaque flag, decided at build time). A file without the section is all opaque;
//! [`FilterScope::Every`] calls the filter for every candidate (filters that are not about materials: skipping
//! a light's own triangles, per-ray visibility masks).
//!
//! **Tracing without a filter costs what it did.** The kernels are generic over `Candidates`; the unfiltered
//! calls pass `Unfiltered`, whose test compiles away, so they run the same instructions as before filters
//! existed (measured with callgrind, `docs/kernel-peer.md`).
//!
//! What a filter sees ([`Candidate`]): the ray as given, the candidate's `t`, `u` and `v`, the triangle record,
//! its source id and, in a two-level file, the instance. For a closest-hit query the filter may see candidates
//! farther than the hit finally returned (the kernel does not sort a leaf's triangles before asking), and may
//! see a triangle more than once (split references, or a triangle tested again after a rejection elsewhere);
//! an any-hit query stops at the first accepted candidate. A filter must answer the same for the same
//! candidate: the kernels find the closest accepted hit only if it does.
//!
//! ```
//! use bvhc_loader::{BvhFile, Ray, Trace, filter::FilterScope};
//!
//! let file = BvhFile::from_bytes(include_bytes!("../../tests/data/quad-v1.1.bvh"))?;
//! let tracer = file.view().tracer();
//! let ray = Ray::new([0.25, 0.75, 1.0], [0.0, 0.0, -1.0]);
//! let hit = tracer.closest_hit(&ray).expect("the quad is below");
//! // A cut-out where v > u (a renderer samples its texture's alpha at the hit's texture coordinates instead).
//! let cut_out = |candidate: &bvhc_loader::filter::Candidate<'_>| candidate.v <= candidate.u;
//! let filtered = tracer.filtered(&cut_out, FilterScope::Every);
//! assert_eq!(filtered.closest_hit(&ray).is_some(), hit.v <= hit.u);
//! assert_eq!(filtered.any_hit(&ray), hit.v <= hit.u);
//! // By default only triangles the file marks not opaque are asked: this file has no flags, so none is cut.
//! assert_eq!(tracer.filtered(&cut_out, FilterScope::NotOpaque).closest_hit(&ray), Some(hit));
//! # Ok::<(), bvhc_loader::Error>(())
//! ```

pub use crate::ray::candidates::{Candidate, FilterScope, HitFilter};

use crate::ray::candidates::Filtering;
use crate::ray::hit::{Hit, TraversalCounter};
use crate::ray::intersect::Ray;
use crate::trace::{BatchResult, Order, Trace};
use crate::tracer::Tracer;

/// A tracer that runs a [`HitFilter`] on candidate hits ([`Tracer::filtered`]): the same calls as [`Tracer`],
/// checking rays as it does. Batch calls trace one ray after the other with the single-ray kernel (no stream
/// interleaving, no coherent packets). With [`FilterScope::NotOpaque`] on a file without the `triangle_flags`
/// section (all opaque: the filter would never be asked) every call is the plain tracer's.
pub struct FilteredTracer<'a, 'f, F: ?Sized> {
    tracer: Tracer<'a>,
    filter: &'f F,
    scope: FilterScope,
}

impl<'a> Tracer<'a> {
    /// This tracer with `filter` deciding the candidate hits `scope` names (see the module doc of
    /// [`crate::tracer::filter`]).
    pub fn filtered<'f, F: HitFilter + ?Sized>(&self, filter: &'f F, scope: FilterScope) -> FilteredTracer<'a, 'f, F> {
        FilteredTracer { tracer: *self, filter, scope }
    }
}

impl<F: HitFilter + ?Sized> FilteredTracer<'_, '_, F> {
    /// Whether the filter would never be asked: only not-opaque triangles are, and the file has none marked.
    fn all_opaque(&self) -> bool {
        self.scope == FilterScope::NotOpaque && self.tracer.triangle_flags().is_none()
    }

    fn filtering<'r>(&'r self, ray: &'r Ray) -> Filtering<'r, F> {
        Filtering {
            filter: self.filter,
            scope: self.scope,
            ray,
            flags: self.tracer.triangle_flags(),
            ids: self.tracer.triangle_ids(),
            first_record: 0,
            instance: None,
        }
    }
}

/// The filtered calls: a tracer with every triangle opaque (or no filter to ask) runs the plain ones.
impl<F: HitFilter + ?Sized> Trace for FilteredTracer<'_, '_, F> {
    /// The closest accepted hit with `t_min <= t <= t_max`, counting into `counter`.
    ///
    /// # Panics
    ///
    /// As [`Trace::closest_hit`] for the tracer filtered.
    #[track_caller]
    fn closest_hit_counted(&self, ray: &Ray, counter: &mut impl TraversalCounter) -> Option<Hit> {
        if self.all_opaque() {
            return self.tracer.closest_hit_counted(ray, counter);
        }
        self.tracer.check("closest_hit", ray);
        self.tracer.closest_hit_inner(ray, counter, &self.filtering(ray))
    }

    /// Whether an accepted hit lies within `[t_min, t_max]`; stops at the first.
    ///
    /// # Panics
    ///
    /// As [`Trace::closest_hit`] for the tracer filtered.
    #[track_caller]
    fn any_hit_counted(&self, ray: &Ray, counter: &mut impl TraversalCounter) -> bool {
        if self.all_opaque() {
            return self.tracer.any_hit_counted(ray, counter);
        }
        self.tracer.check("any_hit", ray);
        self.tracer.any_hit_inner(ray, counter, &self.filtering(ray))
    }

    /// Each ray's closest accepted hit to `each`; the rays (for a tracer that checks them) all checked before
    /// any is traced.
    fn closest_hits_with(&self, rays: &[Ray], order: Order, mut each: impl FnMut(usize, Option<Hit>)) -> BatchResult {
        if self.all_opaque() {
            return self.tracer.closest_hits_with(rays, order, each);
        }
        self.tracer.check_all(rays)?;
        rays.iter()
            .enumerate()
            .for_each(|(i, ray)| each(i, self.tracer.closest_hit_inner(ray, &mut (), &self.filtering(ray))));
        Ok(())
    }

    /// Whether each ray has an accepted hit, to `each`, as [`Trace::closest_hits_with`] for this tracer.
    fn any_hits_with(&self, rays: &[Ray], order: Order, mut each: impl FnMut(usize, bool)) -> BatchResult {
        if self.all_opaque() {
            return self.tracer.any_hits_with(rays, order, each);
        }
        self.tracer.check_all(rays)?;
        rays.iter()
            .enumerate()
            .for_each(|(i, ray)| each(i, self.tracer.any_hit_inner(ray, &mut (), &self.filtering(ray))));
        Ok(())
    }
}
