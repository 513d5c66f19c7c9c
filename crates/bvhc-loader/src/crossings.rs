//! Every surface a ray crosses ([`Crossings::all_hits`]) and whether a point lies inside a closed mesh
//! ([`Crossings::contains`]), on any kernel, one- and two-level files.
//!
//! **All hits.** The kernel is run with a filter that records every candidate hit within `[t_min, t_max]` and
//! rejects it, so traversal goes on to the end of the interval; the records are then sorted by `t` and reduced
//! to one hit per surface crossing:
//! * a triangle reported more than once (split references, or a record tested again) is one hit, the nearest;
//! * a ray through an edge or vertex that triangles share hits each of them at that point (the watertight test
//!   counts an edge as inside both of its triangles, so no ray slips between them), and a ray passing within
//!   rounding of a vertex hits several of the triangles around it: hits on the same side (`front_face`), in the
//!   same instance, one of them at an edge or vertex of its triangle (its other weights within `2^-10` of 0)
//!   that the other's triangle has too, and at about the same `t` (within `2^-12` of it: at a grazing angle the
//!   triangles around a vertex lie at depths that differ by their slope) are one crossing, whose hit is the one
//!   farther inside its triangle. Hits on opposite sides there are kept: the ray touches a ridge or a
//!   silhouette without crossing it, and the two cancel in the inside test.
//!
//! Ray casters built on a non-watertight test instead report such a crossing twice or not at all, and ones that
//! restart the ray past each hit can skip a surface within their offset.
//!
//! **Inside test.** A point is inside a closed mesh when the surfaces a ray from it crosses do not cancel: the
//! winding number along the ray, back-facing crossings minus front-facing ones (1 or -1 inside a closed,
//! consistently oriented mesh, whichever way it is wound; 0 outside). A ray that meets some triangle within
//! `2^-16` of its boundary could count an edge crossing ambiguously, so the test then tries the next of a few
//! fixed directions; only when every direction grazes an edge does it take the majority. A point on the surface
//! (a hit at `t <= 2^-20` of the scene's size over the direction's length from it) counts as inside.

use std::cell::RefCell;

use crate::candidates::{Candidate, FilterScope, HitFilter};
use crate::format::{PackedTriangle, TRIANGLE_NOT_OPAQUE};
use crate::hit::Hit;
use crate::identity::TriangleIdentities;
use crate::instance_transform::{object_ray, world_normal};
use crate::intersect::{Ray, TriangleHit};
use crate::traverse::Tracer;
use crate::view::BvhView;

/// Within what `t`, relative to the scene's size, of a point a hit puts the point on the surface (`2^-20`).
const ON_SURFACE: f32 = 1.0 / 1_048_576.0;
/// How close to an edge a hit makes an inside test try another direction (`2^-16`).
const NEAR_EDGE: f32 = 1.0 / 65_536.0;
/// How small a weight puts a hit at an edge or vertex for merging crossings (`2^-10`: a ray passing within
/// rounding of a vertex at a grazing angle meets the triangles around it up to this far from the vertex).
const AT_ELEMENT: f32 = 1.0 / 1024.0;
/// Relative depth within which hits on one edge or vertex are one crossing (`2^-12`).
const SAME_DEPTH: f32 = 1.0 / 4096.0;
/// Directions an inside test tries in turn: spread over the sphere, none along an axis or a diagonal.
const DIRECTIONS: [[f32; 3]; 6] = [
    [0.577_350_3, 0.211_324_87, 0.788_675_1],
    [-0.301_511_35, 0.904_534_06, 0.301_511_35],
    [0.229_415_73, -0.688_247_2, 0.688_247_2],
    [-0.801_783_7, -0.267_261_24, -0.534_522_5],
    [0.872_871_6, -0.436_435_8, 0.218_217_9],
    [-0.408_248_3, 0.408_248_3, -0.816_496_6],
];

/// All hits and inside tests over a file: see the module doc. Made once per file ([`BvhView::crossings`]); cheap
/// to copy around threads by reference (`Sync`).
#[derive(Clone, Debug)]
pub struct Crossings<'a> {
    tracer: Tracer<'a>,
    triangles: &'a [PackedTriangle],
    identities: TriangleIdentities<'a>,
}

impl<'a> BvhView<'a> {
    /// [`Crossings`] over this file with its fastest tracer.
    pub fn crossings(&self) -> Crossings<'a> {
        Crossings { tracer: self.tracer(), triangles: self.triangles(), identities: self.triangle_identities() }
    }
}

/// What the collecting filter keeps of a candidate.
#[derive(Clone, Copy)]
struct Recorded {
    record: u32,
    instance: Option<u32>,
    hit: TriangleHit,
}

/// Records every candidate the caller's filter accepts (asking it only in its scope), and rejects all.
struct Collector<'f, F: ?Sized> {
    filter: &'f F,
    scope: FilterScope,
    flags: Option<&'f [u8]>,
    found: RefCell<Vec<Recorded>>,
}

impl<F: HitFilter + ?Sized> HitFilter for Collector<'_, F> {
    fn accept(&self, candidate: &Candidate<'_>) -> bool {
        let asked = self.scope == FilterScope::Every
            || self
                .flags
                .and_then(|f| f.get(candidate.triangle_index as usize))
                .is_some_and(|&f| f & TRIANGLE_NOT_OPAQUE != 0);
        if !asked || self.filter.accept(candidate) {
            let hit = TriangleHit { t: candidate.t, u: candidate.u, v: candidate.v };
            let recorded = Recorded { record: candidate.triangle_index, instance: candidate.instance_index, hit };
            self.found.borrow_mut().push(recorded);
        }
        false
    }
}

/// A filter that accepts everything.
fn everything(_: &Candidate<'_>) -> bool {
    true
}

impl<'a> Crossings<'a> {
    /// Crossings over `tracer`, whose records are `triangles`, one triangle per identity of `identities`.
    pub fn new(tracer: Tracer<'a>, triangles: &'a [PackedTriangle], identities: TriangleIdentities<'a>) -> Self {
        Crossings { tracer, triangles, identities }
    }

    /// Every surface crossing of `ray` within `[t_min, t_max]`, nearest first (ties by record), into `hits`
    /// (cleared first): each triangle once, and a crossing through an edge or vertex once (see the module doc).
    ///
    /// # Panics
    ///
    /// When the ray breaks the ray contract and the tracer checks rays, as [`Tracer::closest_hit`].
    #[track_caller]
    pub fn all_hits(&self, ray: &Ray, hits: &mut Vec<Hit>) {
        self.all_hits_filtered(ray, &everything, FilterScope::Every, hits);
    }

    /// [`Crossings::all_hits`] of the candidates `filter` accepts (asked in `scope`, as [`Tracer::filtered`]
    /// asks): the surfaces a ray crosses where a cut-out leaves them.
    ///
    /// # Panics
    ///
    /// As [`Crossings::all_hits`].
    #[track_caller]
    pub fn all_hits_filtered<F: HitFilter + ?Sized>(
        &self,
        ray: &Ray,
        filter: &F,
        scope: FilterScope,
        hits: &mut Vec<Hit>,
    ) {
        hits.clear();
        let collector =
            Collector { filter, scope, flags: self.tracer.triangle_flags(), found: RefCell::new(Vec::new()) };
        // Everything rejected: the any-hit walk (no ordering work) visits every candidate in the interval.
        let _ = self.tracer.filtered(&collector, FilterScope::Every).any_hit(ray);
        let mut found: Vec<(Hit, u32)> = collector
            .found
            .into_inner()
            .into_iter()
            .map(|r| (self.hit(ray, r), self.identities.get(r.record)))
            .collect();
        found.sort_by(|a, b| {
            a.0.t.total_cmp(&b.0.t).then(a.0.instance_index.cmp(&b.0.instance_index)).then(a.1.cmp(&b.1))
        });
        // One hit per triangle (the nearest), then one per crossing.
        let mut seen = std::collections::HashSet::new();
        found.retain(|(hit, identity)| seen.insert((*identity, hit.instance_index)));
        for (hit, _) in found {
            let nearby = hits.iter().rposition(|kept| !close_in_t(kept.t, hit.t)).map_or(0, |at| at + 1);
            match (nearby..hits.len()).find(|&k| self.same_crossing(&hits[k], &hit)) {
                // One crossing: keep the hit farther inside its triangle.
                Some(k) if inset(&hit) > inset(&hits[k]) => hits[k] = hit,
                Some(_) => {}
                None => hits.push(hit),
            }
        }
    }

    /// Whether `point` lies inside the closed meshes of this file (see the module doc): the winding number of
    /// the surfaces a ray from it crosses, on a direction that meets no triangle near an edge.
    pub fn contains(&self, point: [f32; 3]) -> bool {
        let mut hits = Vec::new();
        let mut votes = 0i32;
        for direction in DIRECTIONS {
            let ray = Ray::new(point, direction);
            self.all_hits(&ray, &mut hits);
            if hits.first().is_some_and(|h| h.t <= self.surface_distance()) {
                return true;
            }
            let winding: i32 = hits.iter().map(|h| if h.front_face { -1 } else { 1 }).sum();
            if !hits.iter().any(|h| near_edge(h.u, h.v)) {
                return winding != 0;
            }
            votes += if winding != 0 { 1 } else { -1 };
        }
        votes > 0
    }

    /// Within what `t` (along a unit direction) of a point a hit puts the point on the surface: `2^-20` of the
    /// scene's size.
    fn surface_distance(&self) -> f32 {
        let extent = self.tracer.scene_extent();
        extent * ON_SURFACE
    }

    /// The hit record of a recorded candidate, as the kernel makes it: the normal and side in the record's own
    /// space, through an instance mapped to world space.
    fn hit(&self, ray: &Ray, recorded: Recorded) -> Hit {
        let ids = self.tracer.triangle_ids();
        let placement = recorded.instance.and_then(|i| self.tracer.instance_sections()?.placement(i));
        match placement {
            Some((instance, _)) => {
                let object = object_ray(instance, ray);
                let mut hit = Hit::new(recorded.record, recorded.hit, self.triangles, ids, &object.direction);
                hit.instance_index = recorded.instance;
                hit.normal = world_normal(instance, hit.normal);
                hit
            }
            None => Hit::new(recorded.record, recorded.hit, self.triangles, ids, &ray.direction),
        }
    }

    /// Whether two hits at about the same `t` are one crossing through an edge or vertex their triangles share:
    /// the same side, the same instance, and one of them at an edge or vertex of its triangle (its other weights
    /// within `2^-10` of 0) that the other triangle has too (the same coordinates): there the test, within
    /// rounding, reports the neighbours of the triangle crossed as well.
    fn same_crossing(&self, a: &Hit, b: &Hit) -> bool {
        if a.front_face != b.front_face || a.instance_index != b.instance_index {
            return false;
        }
        let (Some(ta), Some(tb)) =
            (self.triangles.get(a.triangle_index as usize), self.triangles.get(b.triangle_index as usize))
        else {
            return false;
        };
        on_shared_element(a, ta, tb) || on_shared_element(b, tb, ta)
    }
}

/// Whether `hit` lies at an edge or vertex of `triangle` (its weights of the other vertices within `2^-10` of
/// 0) whose vertices `other` has too.
fn on_shared_element(hit: &Hit, triangle: &PackedTriangle, other: &PackedTriangle) -> bool {
    let weights = [1.0 - hit.u - hit.v, hit.u, hit.v];
    if !weights.iter().any(|&w| w <= AT_ELEMENT) {
        return false;
    }
    let bits = |v: &[f32; 3]| v.map(f32::to_bits);
    let shared = |i: usize| other.vertices.iter().any(|q| bits(q) == bits(&triangle.vertices[i]));
    (0..3).filter(|&i| weights[i] > AT_ELEMENT).all(shared)
}

/// Whether `t` and `s` are within `2^-12` of the larger (a ray passing within rounding of a vertex at a grazing
/// angle meets the triangles around it at depths that differ by their slope).
fn close_in_t(t: f32, s: f32) -> bool {
    (t - s).abs() <= SAME_DEPTH * t.abs().max(s.abs())
}

/// How far inside its triangle a hit lies: its smallest weight `(1 - u - v, u, v)`.
fn inset(hit: &Hit) -> f32 {
    hit.u.min(hit.v).min(1.0 - hit.u - hit.v)
}

/// Whether the weights put a point near an edge (for the inside test's choice of direction).
fn near_edge(u: f32, v: f32) -> bool {
    u.min(v).min(1.0 - u - v) <= NEAR_EDGE
}
