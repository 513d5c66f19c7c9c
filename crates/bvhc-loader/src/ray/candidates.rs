//! The candidate hits a filter sees ([`Candidate`]), the filters ([`HitFilter`], [`FilterScope`]), and how the
//! kernels ask about each candidate: generic over `Candidates`, with `Unfiltered` (whose test compiles away)
//! for the plain calls and `Filtering` for [`crate::FilteredTracer`]'s. The kernels import this module; the
//! filtered tracer (`filter.rs`) sits above them.

use crate::format::TRIANGLE_NOT_OPAQUE;
use crate::ray::hit::{Hit, TriangleHit};
use crate::ray::intersect::Ray;

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
/// must be synchronized (or made per thread, with one [`crate::FilteredTracer`] each).
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
    /// Whether a hit on record `record` (an index into the tracer's own triangles: a mesh's, in a two-level
    /// file) is put to the filter at all; a hit that is not is accepted.
    fn asks(&self, record: u32) -> bool;
    /// Whether the hit on record `record` is accepted.
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
    fn asks(&self, _: u32) -> bool {
        false
    }

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
    fn asks(&self, record: u32) -> bool {
        let record = record.wrapping_add(self.first_record);
        self.scope == FilterScope::Every
            || self.flags.and_then(|f| f.get(record as usize)).is_some_and(|&f| f & TRIANGLE_NOT_OPAQUE != 0)
    }

    #[inline]
    fn accept(&self, record: u32, hit: &TriangleHit) -> bool {
        if !self.asks(record) {
            return true;
        }
        let record = record.wrapping_add(self.first_record);
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
