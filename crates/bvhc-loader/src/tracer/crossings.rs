//! Every surface a ray crosses ([`Crossings::all_hits`]) and whether a point lies inside a closed mesh
//! ([`Crossings::contains`]), on any kernel, one- and two-level files.
//!
//! **All hits.** The kernel is run with a filter that records every candidate hit within `[t_min, t_max]` and
//! rejects it, so traversal goes on to the end of the interval; the records are then sorted by `t`, and a
//! triangle reported more than once (split references, or a record tested again) is one hit, the nearest.
//!
//! **Edges and vertices.** The watertight test counts a point on an edge as inside both triangles that share it, so
//! that no ray slips between them; a ray exactly through an edge or a vertex (an edge function exactly 0: a ray aimed
//! at a vertex meets it exactly, since the vertex's offset from the origin is the direction before rounding) therefore
//! hits every triangle around it. Here such a ray counts as if moved infinitesimally off it, to the same side for every
//! triangle (`crate::ray::moved`), in the spirit of Edelsbrunner and Muecke's Simulation of Simplicity (1990): in the
//! ray's sheared 2D space (where the test's edge function `E(p, q) = p_x q_y - p_y q_x` is evaluated at the origin) the
//! query point moves to `(e, e^2)` for an infinitesimal `e`, which changes an edge function of 0 to `e (p_y - q_y) +
//! e^2 (q_x - p_x)`: its sign is that of `p_y - q_y`, or if that is 0 of `q_x - p_x`. Both differences are of f32
//! values, so their signs are exact, and two triangles sharing an edge see it with opposite orientation and get
//! opposite signs: the moved point lies in exactly the triangles whose three signs then agree, which for triangles
//! around an edge or a vertex of a consistently oriented mesh is one crossing where the ray crosses the surface, and
//! none or a front and a back hit where it touches a ridge or a silhouette, however the fan around the vertex folds as
//! seen along the ray. So a ray from outside a closed mesh always has an even number of hits, and the sum of their
//! sides is zero.
//!
//! Ray casters built on a non-watertight test instead report such a crossing twice or not at all, and ones that
//! restart the ray past each hit can skip a surface within their offset.
//!
//! **Inside test.** A point is inside a closed mesh when the surfaces a ray from it crosses do not cancel: the
//! winding number along the ray, back-facing crossings minus front-facing ones (1 or -1 inside a closed,
//! consistently oriented mesh, whichever way it is wound; 0 outside). A point on the surface (a hit at
//! `t <= 2^-20` of the scene's size over the direction's length from it) counts as inside.

use crate::trace::Trace;
use std::cell::RefCell;

use crate::format::{PackedTriangle, TRIANGLE_NOT_OPAQUE};
use crate::open::view::BvhView;
use crate::ray::candidates::{Candidate, FilterScope, HitFilter};
use crate::ray::hit::{Hit, TriangleHit};
use crate::ray::intersect::{PreparedRay, Ray};
use crate::ray::moved::moved_side;
use crate::ray::transform::{mirrors, object_ray, world_normal};
use crate::source::identity::TriangleIdentities;
use crate::tracer::Tracer;

/// Within what `t`, relative to the scene's size, of a point a hit puts the point on the surface (`2^-20`).
const ON_SURFACE: f32 = 1.0 / 1_048_576.0;
/// The direction of an inside test's ray: along no axis or diagonal, so that axis-aligned models do not put it
/// through their edges more often than chance.
pub(crate) const INSIDE_DIRECTION: [f32; 3] = [0.577_350_3, 0.211_324_87, 0.788_675_1];

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
        let recorded = self.candidates(ray, filter, scope);
        self.crossings_of(ray, recorded, hits);
    }

    /// Whether `point` lies inside the closed meshes of this file (see the module doc): the winding number of
    /// the surfaces a ray from it crosses, or inside when the test hits a triangle at the point itself (before
    /// any perturbation: a point on an edge or at a vertex is on the surface too).
    pub fn contains(&self, point: [f32; 3]) -> bool {
        let ray = Ray::new(point, INSIDE_DIRECTION);
        let recorded = self.candidates(&ray, &everything, FilterScope::Every);
        if recorded.iter().any(|r| r.hit.t <= self.surface_distance()) {
            return true;
        }
        let mut hits = Vec::new();
        self.crossings_of(&ray, recorded, &mut hits);
        hits.iter().map(|h| if h.front_face { -1i32 } else { 1 }).sum::<i32>() != 0
    }

    /// The winding number at `ray`'s origin counted along it: the sides of its crossings within `[t_min,
    /// t_max]` summed, each triangle once ([`crate::ray::moved::moved_side`]: 1 passing from a back side to a
    /// front side, -1 the other way; in world space, so a mirroring instance's sides count turned). For a
    /// surface without boundary this is its winding number at the origin exactly, provided no triangle lies
    /// within the rounding of a hit's `t` of the origin (the caller's check).
    pub(crate) fn winding_along(&self, ray: &Ray) -> i64 {
        let recorded = self.candidates(ray, &everything, FilterScope::Every);
        let world = PreparedRay::new(ray);
        let mut sides: Vec<(u32, Option<u32>, i32)> = recorded
            .iter()
            .filter_map(|r| {
                let side = self.moved_side(ray, &world, r)?;
                (side != 0).then(|| (self.identities.get(r.record), r.instance, side))
            })
            .collect();
        // A line crosses a triangle once: its records (split references) and repeated tests are one crossing.
        sides.sort_unstable();
        sides.dedup_by_key(|&mut (identity, instance, _)| (identity, instance));
        sides.iter().map(|&(_, _, side)| i64::from(side)).sum()
    }

    /// Every candidate hit of `ray` within its interval that `filter` accepts (asked in `scope`).
    fn candidates<F: HitFilter + ?Sized>(&self, ray: &Ray, filter: &F, scope: FilterScope) -> Vec<Recorded> {
        let collector =
            Collector { filter, scope, flags: self.tracer.triangle_flags(), found: RefCell::new(Vec::new()) };
        // Everything rejected: the any-hit walk (no ordering work) visits every candidate in the interval.
        let _ = self.tracer.filtered(&collector, FilterScope::Every).any_hit(ray);
        collector.found.into_inner()
    }

    /// The crossings among `recorded` (the candidates of `ray`) into `hits`: those the moved ray still hits,
    /// sorted by `t` (ties by instance and triangle), each triangle once.
    fn crossings_of(&self, ray: &Ray, recorded: Vec<Recorded>, hits: &mut Vec<Hit>) {
        let world = PreparedRay::new(ray);
        let mut found: Vec<(Hit, u32)> = recorded
            .into_iter()
            .filter(|r| self.moved_side(ray, &world, r) != Some(0))
            .map(|r| (self.hit(ray, r), self.identities.get(r.record)))
            .collect();
        found.sort_by(|a, b| {
            a.0.t.total_cmp(&b.0.t).then(a.0.instance_index.cmp(&b.0.instance_index)).then(a.1.cmp(&b.1))
        });
        // One hit per triangle (the nearest).
        let mut seen = std::collections::HashSet::new();
        found.retain(|(hit, identity)| seen.insert((*identity, hit.instance_index)));
        hits.extend(found.into_iter().map(|(hit, _)| hit));
    }

    /// How the ray, moved infinitesimally off the edges and vertices it passes exactly through, crosses a recorded
    /// candidate's triangle (`crate::ray::moved::moved_side`; `world` is `ray` prepared): 0 when it misses it, 1
    /// or -1 by the side in world space (a mirroring instance turns its mesh's sides); decided by the test's edge
    /// functions, not by the hit's weights, which for an ill-conditioned hit are the exact ones. `None` for a
    /// record outside the triangles (only in a file that breaks verification).
    fn moved_side(&self, ray: &Ray, world: &PreparedRay, recorded: &Recorded) -> Option<i32> {
        let triangle = self.triangles.get(recorded.record as usize)?;
        Some(match recorded.instance.and_then(|i| self.tracer.instance_sections()?.placement(i)) {
            Some((instance, _)) => {
                let side = moved_side(&PreparedRay::new(&object_ray(instance, ray)), triangle);
                if mirrors(instance) { -side } else { side }
            }
            None => moved_side(world, triangle),
        })
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
}
