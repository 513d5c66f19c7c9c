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
//! **Tracing without a filter costs what it did.** The kernels are generic over [`Candidates`]; the unfiltered
//! calls pass [`Unfiltered`], whose test compiles away, so they run the same instructions as before filters
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
//! use bvhc_loader::{BvhFile, FilterScope, Ray};
//!
//! let file = BvhFile::from_bytes(include_bytes!("../tests/data/quad-v1.1.bvh"))?;
//! let tracer = file.view().tracer();
//! let ray = Ray::new([0.25, 0.75, 1.0], [0.0, 0.0, -1.0]);
//! let hit = tracer.closest_hit(&ray).expect("the quad is below");
//! // A cut-out where v > u (a renderer samples its texture's alpha at the hit's texture coordinates instead).
//! let cut_out = |candidate: &bvhc_loader::Candidate<'_>| candidate.v <= candidate.u;
//! let filtered = tracer.filtered(&cut_out, FilterScope::Every);
//! assert_eq!(filtered.closest_hit(&ray).is_some(), hit.v <= hit.u);
//! assert_eq!(filtered.any_hit(&ray), hit.v <= hit.u);
//! // By default only triangles the file marks not opaque are asked: this file has no flags, so none is cut.
//! assert_eq!(tracer.filtered(&cut_out, FilterScope::NotOpaque).closest_hit(&ray), Some(hit));
//! # Ok::<(), bvhc_loader::Error>(())
//! ```

use crate::format::TRIANGLE_NOT_OPAQUE;
use crate::hit::Hit;
use crate::intersect::{Ray, TriangleHit};
use crate::traverse::Tracer;

/// A hit the kernel found, before it is accepted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate<'r> {
    /// The ray as given to the tracer (in world space, also in a two-level file).
    pub ray: &'r Ray,
    /// Distance along the ray.
    pub t: f32,
    /// Barycentric weight of the record's `v1` (as [`Hit::u`]).
    pub u: f32,
    /// Barycentric weight of the record's `v2`.
    pub v: f32,
    /// The triangle record (in the file's triangles section).
    pub triangle_index: u32,
    /// Its source id, when the file has ids: with [`crate::BvhView::source_range_of`] the glTF mesh and
    /// primitive (and so the material), and with [`crate::BvhView::source_corners`] the texture coordinates.
    pub source_triangle_id: Option<u32>,
    /// In a two-level file, the instance whose mesh holds the triangle.
    pub instance_index: Option<u32>,
}

impl Candidate<'_> {
    /// The candidate as the hit record a tracer would return for it (for [`crate::BvhView::source_corners`]),
    /// without its normal and front-face flag, which a filter rarely needs (zero and `false`).
    pub fn as_hit(&self) -> Hit {
        Hit {
            t: self.t,
            triangle_index: self.triangle_index,
            source_triangle_id: self.source_triangle_id,
            u: self.u,
            v: self.v,
            normal: [0.0; 3],
            front_face: false,
            instance_index: self.instance_index,
        }
    }
}

/// Decides whether a candidate hit counts: `true` accepts it, `false` rejects it and traversal goes on. Any
/// `Fn(&Candidate) -> bool` is one. Shared by every thread that traces with it (`&self`), so state it keeps
/// must be synchronized (or made per thread, with one [`FilteredTracer`] each).
pub trait HitFilter {
    /// Whether `candidate` is accepted.
    fn accept(&self, candidate: &Candidate<'_>) -> bool;
}

impl<F: Fn(&Candidate<'_>) -> bool> HitFilter for F {
    fn accept(&self, candidate: &Candidate<'_>) -> bool {
        self(candidate)
    }
}

/// Which candidates a filter sees.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FilterScope {
    /// Only hits on triangles the file marks not opaque ([`crate::format::TRIANGLE_NOT_OPAQUE`]); every other
    /// hit is accepted without a call. A file without the `triangle_flags` section is all opaque.
    NotOpaque,
    /// Every candidate hit.
    Every,
}

/// What the kernels ask of each candidate hit: the unfiltered calls pass [`Unfiltered`] (`ACTIVE` false, so the
/// test compiles away), the filtered ones a [`Filtering`].
pub(crate) trait Candidates: Copy {
    /// Whether the kernel asks at all.
    const ACTIVE: bool;
    /// Whether the hit on record `record` (an index into the tracer's own triangles: a mesh's, in a two-level
    /// file) is accepted.
    fn accept(&self, record: u32, hit: &TriangleHit) -> bool;
    /// These candidates in the mesh whose records start at `first_record`, placed by `instance`.
    fn in_mesh(&self, first_record: u32, instance: u32) -> Self;
}

/// Every candidate accepted, with no test: tracing as without filters.
#[derive(Clone, Copy)]
pub(crate) struct Unfiltered;

impl Candidates for Unfiltered {
    const ACTIVE: bool = false;

    #[inline(always)]
    fn accept(&self, _: u32, _: &TriangleHit) -> bool {
        true
    }

    #[inline(always)]
    fn in_mesh(&self, _: u32, _: u32) -> Self {
        Unfiltered
    }
}

/// A filter applied to the candidates of one ray (in a two-level file: of one instance's mesh).
pub(crate) struct Filtering<'f, F: ?Sized> {
    pub filter: &'f F,
    pub scope: FilterScope,
    /// The ray as the caller gave it.
    pub ray: &'f Ray,
    /// The file's triangle flags and ids (whole sections).
    pub flags: Option<&'f [u8]>,
    pub ids: Option<&'f [u32]>,
    /// Added to a kernel's record index to make it the file's (a mesh's first triangle).
    pub first_record: u32,
    pub instance: Option<u32>,
}

impl<F: HitFilter + ?Sized> Candidates for Filtering<'_, F> {
    const ACTIVE: bool = true;

    fn in_mesh(&self, first_record: u32, instance: u32) -> Self {
        Filtering { first_record, instance: Some(instance), ..*self }
    }

    #[inline]
    fn accept(&self, record: u32, hit: &TriangleHit) -> bool {
        let record = record.wrapping_add(self.first_record);
        if self.scope == FilterScope::NotOpaque
            && self.flags.and_then(|f| f.get(record as usize)).is_none_or(|&f| f & TRIANGLE_NOT_OPAQUE == 0)
        {
            return true;
        }
        self.filter.accept(&Candidate {
            ray: self.ray,
            t: hit.t,
            u: hit.u,
            v: hit.v,
            triangle_index: record,
            source_triangle_id: self.ids.and_then(|ids| ids.get(record as usize).copied()),
            instance_index: self.instance,
        })
    }
}

impl<F: ?Sized> Clone for Filtering<'_, F> {
    fn clone(&self) -> Self {
        *self
    }
}

impl<F: ?Sized> Copy for Filtering<'_, F> {}

/// A tracer that runs a [`HitFilter`] on candidate hits ([`Tracer::filtered`]): the same calls as [`Tracer`],
/// checking rays as it does. Batch calls trace one ray after the other with the single-ray kernel (no stream
/// interleaving, no coherent packets).
pub struct FilteredTracer<'a, 'f, F: ?Sized> {
    tracer: Tracer<'a>,
    filter: &'f F,
    scope: FilterScope,
}

impl<'a> Tracer<'a> {
    /// This tracer with `filter` deciding the candidate hits `scope` names (see the module doc of
    /// [`crate::filter`]).
    pub fn filtered<'f, F: HitFilter + ?Sized>(&self, filter: &'f F, scope: FilterScope) -> FilteredTracer<'a, 'f, F> {
        FilteredTracer { tracer: *self, filter, scope }
    }
}

impl<F: HitFilter + ?Sized> FilteredTracer<'_, '_, F> {
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

    /// The closest accepted hit with `t_min <= t <= t_max`.
    ///
    /// # Panics
    ///
    /// As [`Tracer::closest_hit`].
    #[track_caller]
    pub fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        self.tracer.check("closest_hit", ray);
        self.tracer.closest_hit_inner(ray, &mut (), &self.filtering(ray))
    }

    /// Whether an accepted hit lies within `[t_min, t_max]`; stops at the first.
    ///
    /// # Panics
    ///
    /// As [`Tracer::closest_hit`].
    #[track_caller]
    pub fn any_hit(&self, ray: &Ray) -> bool {
        self.tracer.check("any_hit", ray);
        self.tracer.any_hit_inner(ray, &mut (), &self.filtering(ray))
    }

    /// [`FilteredTracer::closest_hit`] of each ray into the `hits` slot of the same index.
    ///
    /// # Panics
    ///
    /// When `hits` is not as long as `rays`, or (for a tracer that checks rays) a ray breaks the contract, before
    /// any ray is traced.
    #[track_caller]
    pub fn closest_hits(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        crate::hit::same_length("closest_hits", rays.len(), hits.len());
        self.tracer.check_batch("closest_hits", rays);
        for (ray, hit) in rays.iter().zip(hits) {
            *hit = self.tracer.closest_hit_inner(ray, &mut (), &self.filtering(ray));
        }
    }

    /// [`FilteredTracer::any_hit`] of each ray into the `occluded` slot of the same index.
    ///
    /// # Panics
    ///
    /// As [`FilteredTracer::closest_hits`].
    #[track_caller]
    pub fn any_hits(&self, rays: &[Ray], occluded: &mut [bool]) {
        crate::hit::same_length("any_hits", rays.len(), occluded.len());
        self.tracer.check_batch("any_hits", rays);
        for (ray, hit) in rays.iter().zip(occluded) {
            *hit = self.tracer.any_hit_inner(ray, &mut (), &self.filtering(ray));
        }
    }
}
