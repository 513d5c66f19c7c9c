//! A file's winding numbers and signed distances ([`WindingNumbers`]).
//!
//! A point's winding number is counted along a ray where it can be: the sides of the ray's crossings of the
//! surface (`crate::tracer::crossings`, exact) and of the caps over the surface's holes (`crate::point::caps`),
//! less the caps' own winding number summed from their moments. For a closed mesh (no caps) that is exact; for
//! an open one only the caps' sum is approximate, and caps span holes, so the error is confined to points near
//! the holes. Where the count cannot be trusted (a point within `2^-18` of the scene's size of the surface or of
//! a cap, where the side of the point is left to rounding) the whole surface is summed from its moments instead
//! (`crate::point::winding`, Barill et al. 2018).

use std::collections::TryReserveError;
use std::sync::Arc;

use crate::point::ClosestPoint;
use crate::point::caps::Caps;
use crate::point::order::answer_in_order;
use crate::point::winding::{Map, MeshMoments, mesh_angle, mesh_moments};
use crate::ray::intersect::Ray;
use crate::ray::transform::{mirrors, object_ray};
use crate::source::identity::TriangleIdentities;
use crate::tracer::Tracer;
use crate::tracer::crossings::{Crossings, INSIDE_DIRECTION};

/// Within what distance of the surface, relative to the scene's size, a winding number is summed rather than
/// counted (`2^-18`: far above the rounding of a hit's `t`, which is relative to the triangle's own offset from
/// the point).
const COUNTED_BEYOND: f32 = 1.0 / 262_144.0;

/// What a file's winding numbers are computed from, once (O(records) time and memory): the moments of every mesh,
/// the caps over its holes, each instance's map. Owned and shareable between threads, so a binding can keep it
/// with the file and answer many calls from it ([`WindingNumbers::with_moments`]); it describes the bytes it was
/// computed from, so a refit, pose or instance move calls for a new one (`TracedFile` drops its own).
#[derive(Clone, Debug)]
pub struct WindingMoments {
    /// One a mesh: the file's tree (one level), or each mesh of a two-level file.
    meshes: Vec<MeshMoments>,
    /// Each mesh's caps; `None` for a closed mesh.
    caps: Vec<Option<Caps>>,
    /// Each instance's map in binary64 (`None`: not finite); empty for a one-level file.
    maps: Vec<Option<Map>>,
    /// Within what distance of the surface or a cap a point's winding number is summed, not counted.
    near: f32,
}

impl WindingMoments {
    /// The moments and caps of `tracer`'s file. Fails only when memory for them cannot be had.
    pub fn new(tracer: &Tracer<'_>) -> Result<WindingMoments, TryReserveError> {
        let mut meshes = Vec::new();
        let mut caps = Vec::new();
        let mut add = |nodes, triangles, ids| -> Result<(), TryReserveError> {
            let moments = mesh_moments(nodes, triangles, ids, tracer.split())?;
            caps.try_reserve(1)?;
            caps.push(Caps::of(triangles, moments.counted())?);
            meshes.try_reserve(1)?;
            meshes.push(moments);
            Ok(())
        };
        match tracer.instance_sections() {
            None => add(tracer.nodes(), tracer.triangles(), tracer.triangle_ids())?,
            Some(sections) => {
                for mesh in sections.meshes {
                    let (nodes, triangles, ids) = tracer.mesh_arrays(mesh).unwrap_or((&[], &[], None));
                    add(nodes, triangles, ids)?;
                }
            }
        }
        let mut maps = Vec::new();
        if let Some(sections) = tracer.instance_sections() {
            maps.try_reserve_exact(sections.instances.len())?;
            maps.extend(sections.instances.iter().map(Map::of));
        }
        Ok(WindingMoments { meshes, caps, maps, near: tracer.scene_extent() * COUNTED_BEYOND })
    }
}

/// A file's winding numbers and signed distances: its [`WindingMoments`] over a tracer that answers the closest
/// points and the crossings.
#[derive(Clone, Debug)]
pub struct WindingNumbers<'a> {
    tracer: Tracer<'a>,
    crossings: Crossings<'a>,
    moments: Arc<WindingMoments>,
}

impl<'a> WindingNumbers<'a> {
    /// The moments and caps of `tracer`'s file, computed here. Fails only when memory for them cannot be had.
    pub fn new(tracer: &Tracer<'a>) -> Result<WindingNumbers<'a>, TryReserveError> {
        Ok(WindingNumbers::with_moments(tracer, Arc::new(WindingMoments::new(tracer)?)))
    }

    /// Over `moments` computed earlier from `tracer`'s file as its bytes are now. Moments of other bytes give
    /// wrong numbers (never a panic: every index they hold is checked).
    pub fn with_moments(tracer: &Tracer<'a>, moments: Arc<WindingMoments>) -> WindingNumbers<'a> {
        let identities = TriangleIdentities::new(tracer.triangles(), tracer.triangle_ids(), tracer.split());
        let crossings = Crossings::new(*tracer, tracer.triangles(), identities);
        WindingNumbers { tracer: *tracer, crossings, moments }
    }

    /// The moments these numbers are computed from, to keep for later calls.
    pub fn moments(&self) -> &Arc<WindingMoments> {
        &self.moments
    }

    /// The winding number of the file's surface at `point`: 1 inside a closed mesh wound counter-clockwise seen
    /// from outside (-1 for the other winding), 0 outside, fractions near holes; NaN for a point that is not
    /// finite.
    pub fn winding_number(&self, point: [f32; 3]) -> f64 {
        if !point.iter().all(|c| c.is_finite()) {
            return f64::NAN;
        }
        let clear = self.tracer.closest_point(point, self.moments.near).is_none();
        clear.then(|| self.counted(point)).flatten().unwrap_or_else(|| self.summed(point))
    }

    /// The winding number at `point` counted along a ray (see the module doc), for a point farther than
    /// `near` from the surface; `None` when a cap lies that near.
    fn counted(&self, point: [f32; 3]) -> Option<f64> {
        let ray = Ray::new(point, INSIDE_DIRECTION);
        let p = point.map(f64::from);
        let mut crossings = self.crossings.winding_along(&ray);
        let mut angle = 0.0;
        match self.tracer.instance_sections() {
            None => {
                if let Some(Some(caps)) = self.moments.caps.first() {
                    crossings += caps.crossings(&ray, self.moments.near).ok()?;
                    angle += caps.angle(p, None);
                }
            }
            Some(sections) => {
                for (instance, map) in sections.instances.iter().zip(&self.moments.maps) {
                    let Some(Some(caps)) = self.moments.caps.get(instance.mesh_index as usize) else { continue };
                    let Some(map) = map else { continue };
                    let side = caps.crossings(&object_ray(instance, &ray), self.moments.near).ok()?;
                    crossings += if mirrors(instance) { -side } else { side };
                    angle += caps.angle(p, Some(map));
                }
            }
        }
        Some(crossings as f64 - angle / (4.0 * std::f64::consts::PI))
    }

    /// The winding number at `point` summed over the whole surface from its moments (Barill et al. 2018).
    fn summed(&self, point: [f32; 3]) -> f64 {
        let p = point.map(f64::from);
        let total = match self.tracer.instance_sections() {
            None => match self.moments.meshes.first() {
                Some(moments) => mesh_angle(self.tracer.nodes(), self.tracer.triangles(), moments, p, None),
                None => 0.0,
            },
            Some(sections) => {
                let mut total = 0.0;
                for (index, instance) in sections.instances.iter().enumerate() {
                    let Some((_, mesh)) = sections.placement(index as u32) else { continue };
                    let (Some(moments), Some(Some(map))) =
                        (self.moments.meshes.get(instance.mesh_index as usize), self.moments.maps.get(index))
                    else {
                        continue;
                    };
                    let (nodes, triangles, _) = self.tracer.mesh_arrays(mesh).unwrap_or((&[], &[], None));
                    total += mesh_angle(nodes, triangles, moments, p, Some(map));
                }
                total
            }
        };
        total / (4.0 * std::f64::consts::PI)
    }

    /// The signed distance from `point` to the surface: the closest point's distance, negative where the
    /// winding number's magnitude exceeds 1/2 (inside, whichever way the mesh is wound); 0 on the surface;
    /// `f32::INFINITY` for a file with no triangles; NaN for a point that is not finite.
    pub fn signed_distance(&self, point: [f32; 3]) -> f32 {
        self.signed_distance_near(point, &mut None)
    }

    /// [`WindingNumbers::signed_distance`], the closest point's walk bounded by `previous` (a nearby point's
    /// closest point, `crate::point::order`), which becomes this point's.
    fn signed_distance_near(&self, point: [f32; 3], previous: &mut Option<ClosestPoint>) -> f32 {
        if !point.iter().all(|c| c.is_finite()) {
            return f32::NAN;
        }
        let found = self.tracer.closest_point_near(point, f32::INFINITY, previous.as_ref(), None);
        *previous = found.or(*previous);
        let distance = found.map_or(f32::INFINITY, |found| found.distance);
        if distance == 0.0 || distance.is_infinite() {
            return distance;
        }
        let counted = if distance > self.moments.near { self.counted(point) } else { None };
        let winding = counted.unwrap_or_else(|| self.summed(point));
        if winding.abs() > 0.5 { -distance } else { distance }
    }

    /// [`WindingNumbers::winding_number`] of each of `points` into `out` (the same length; panics otherwise),
    /// on up to `threads` threads (0 counts as 1); the same values on any count, the points taken in a spatial
    /// order (`crate::point::order`).
    pub fn winding_numbers(&self, points: &[[f32; 3]], out: &mut [f64], threads: usize) {
        crate::ray::hit::same_length("winding_numbers", points.len(), out.len());
        answer_in_order(points, out, threads, |point, _: &mut ()| self.winding_number(point));
    }

    /// [`WindingNumbers::signed_distance`] of each of `points` into `out` (the same length; panics otherwise),
    /// on up to `threads` threads (0 counts as 1); the same values on any count, the points taken in a spatial
    /// order, each closest point's walk bounded by the previous one's (`crate::point::order`).
    pub fn signed_distances(&self, points: &[[f32; 3]], out: &mut [f32], threads: usize) {
        crate::ray::hit::same_length("signed_distances", points.len(), out.len());
        answer_in_order(points, out, threads, |point, previous| self.signed_distance_near(point, previous));
    }
}
