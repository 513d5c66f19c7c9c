//! The tracer's point queries (`crate::point`): the closest point of the surface to a position and its
//! distance, one point or a batch on threads, through a two-level file's instances as well.

use crate::format::{InstanceRecord, MeshRecord, PackedNode, PackedTriangle};
use crate::open::sections::TwoLevelSections;
use crate::point::nearest::{Candidate, Nearest};
use crate::point::order::answer_in_order;
use crate::point::records::{PacketRecords, Placement, PointLeaves, TriangleRecords};
use crate::point::space::Space;
use crate::point::walk::walk_points;
use crate::point::wide::walk_wide_points;
use crate::point::{ClosestPoint, Point3, PointFilter, closest_on_triangle};
use crate::ray::query::TieOrder;
use crate::ray::transform::world_point;
use crate::tracer::Tracer;
use crate::tracer::winding::WindingNumbers;

/// A mesh's binary nodes, triangle records and source ids.
pub(crate) type MeshArrays<'a> = (&'a [PackedNode], &'a [PackedTriangle], Option<&'a [u32]>);

impl<'a> Tracer<'a> {
    /// The closest point of the file's surface to `point` within `max_distance` (inclusive; `f32::INFINITY`
    /// for no bound): the triangle record, the point on it, its distance and barycentrics, as
    /// `format-spec/point-queries.md` defines them (ties: lowest instance, then lowest record). `None` when no
    /// triangle is that near, the file has none, or the query is not one: a coordinate of `point` not finite,
    /// `max_distance` negative or NaN. Safe on any file; on one that fails verification the answer is
    /// unspecified.
    pub fn closest_point(&self, point: [f32; 3], max_distance: f32) -> Option<ClosestPoint> {
        self.closest_point_near(point, max_distance, None, None)
    }

    /// [`Tracer::closest_point`] among the triangles `filter` keeps ([`PointFilter`]): as if the others were
    /// absent.
    pub fn closest_point_filtered(
        &self,
        point: [f32; 3],
        max_distance: f32,
        filter: &dyn PointFilter,
    ) -> Option<ClosestPoint> {
        self.closest_point_near(point, max_distance, None, Some(filter))
    }

    /// [`Tracer::closest_point`] (among the triangles `filter` keeps), the walk bounded first by the distance from
    /// `point` of `hint`'s triangle (the answer of a nearby point under the same filter, `crate::point::order`):
    /// the same answer, found sooner when the hint is near.
    pub(crate) fn closest_point_near(
        &self,
        point: [f32; 3],
        max_distance: f32,
        hint: Option<&ClosestPoint>,
        filter: Option<&dyn PointFilter>,
    ) -> Option<ClosestPoint> {
        if !point.iter().all(|c| c.is_finite()) || max_distance.is_nan() || max_distance < 0.0 {
            return None;
        }
        let root = match &self.instances {
            Some(sections) => sections.top_nodes.first(),
            None => self.nodes.first(),
        }?;
        let nearest = Nearest::new(point, max_distance, (root.min, root.max));
        if let Some(d2) = hint.and_then(|hint| self.hint_d2(nearest.point, hint)) {
            let mut bounded = nearest;
            bounded.bound_by(d2);
            let found = self.walk_nearest(bounded, filter);
            // The hint's triangle is in the tree, so the bounded walk finds it or a nearer one; were the file
            // to break that (a record outside every leaf), the query is answered unbounded.
            if found.is_some() {
                return found;
            }
        }
        self.walk_nearest(nearest, filter)
    }

    /// The squared distance from `point` of the triangle of `hint`, computed as a walk computes it.
    fn hint_d2(&self, point: Point3, hint: &ClosestPoint) -> Option<f64> {
        let vertices = self.triangles.get(hint.triangle_index as usize)?.vertices;
        let placed = match (&self.instances, hint.instance_index) {
            (None, None) => vertices.map(|v| v.map(f64::from)),
            (Some(sections), Some(index)) => {
                let instance = sections.instances.get(index as usize)?;
                vertices.map(|v| world_point(instance, v))
            }
            _ => return None,
        };
        placed.iter().flatten().all(|c| c.is_finite()).then(|| closest_on_triangle(point, placed).d2)
    }

    /// Walks the file for `nearest` (offering only what `filter` keeps): the top tree's instances, else the wide
    /// tree or the binary one.
    fn walk_nearest(&self, mut nearest: Nearest, filter: Option<&dyn PointFilter>) -> Option<ClosestPoint> {
        let world = Space::world(nearest.point);
        match &self.instances {
            Some(sections) => {
                let mut leaves = InstanceLeaves { tracer: self, sections, filter };
                walk_points(sections.top_nodes, &world, &mut nearest, &mut leaves);
            }
            None => {
                let placement = Placement {
                    first_record: 0,
                    instance: None,
                    tie: TieOrder::new(self.split_references, self.triangle_ids),
                    ids: self.triangle_ids,
                    filter,
                };
                match &self.wide {
                    Some(wide) => {
                        let leaves = PacketRecords { packets: wide.sections().packets, placement, avx2: wide.avx2() };
                        walk_wide_points(wide.sections(), &world, &mut nearest, &leaves);
                    }
                    None => {
                        let mut leaves = TriangleRecords { triangles: self.triangles, placement };
                        walk_points(self.nodes, &world, &mut nearest, &mut leaves);
                    }
                }
            }
        }
        nearest.best.map(|best| self.closest_point_of(&best))
    }

    /// The distance from `point` to the file's surface ([`Tracer::closest_point`] with no bound):
    /// `f32::INFINITY` for a file with no triangles or a point that is not finite.
    pub fn distance(&self, point: [f32; 3]) -> f32 {
        self.closest_point(point, f32::INFINITY).map_or(f32::INFINITY, |found| found.distance)
    }

    /// [`Tracer::closest_point`] of each of `points` into `out` (the same length; panics otherwise, naming the
    /// call), on up to `threads` threads (the caller's included; 0 counts as 1). The same answers whatever the
    /// thread count; the points are walked in a spatial order (`crate::point::order`), each bounded by its
    /// predecessor's answer, which is faster than one call a point.
    pub fn closest_points(
        &self,
        points: &[[f32; 3]],
        max_distance: f32,
        out: &mut [Option<ClosestPoint>],
        threads: usize,
    ) {
        crate::ray::hit::same_length("closest_points", points.len(), out.len());
        self.closest_points_near(points, max_distance, None, out, threads);
    }

    /// [`Tracer::closest_points`] among the triangles `filter` keeps ([`Tracer::closest_point_filtered`]).
    pub fn closest_points_filtered(
        &self,
        points: &[[f32; 3]],
        max_distance: f32,
        filter: &dyn PointFilter,
        out: &mut [Option<ClosestPoint>],
        threads: usize,
    ) {
        crate::ray::hit::same_length("closest_points_filtered", points.len(), out.len());
        self.closest_points_near(points, max_distance, Some(filter), out, threads);
    }

    /// The batch calls' work: the points in a spatial order, each walk bounded by its predecessor's answer.
    fn closest_points_near(
        &self,
        points: &[[f32; 3]],
        max_distance: f32,
        filter: Option<&dyn PointFilter>,
        out: &mut [Option<ClosestPoint>],
        threads: usize,
    ) {
        answer_in_order(points, out, threads, |point, previous: &mut Option<ClosestPoint>| {
            let found = self.closest_point_near(point, max_distance, previous.as_ref(), filter);
            *previous = found.or(*previous);
            found
        });
    }

    /// The public answer for the best candidate.
    fn closest_point_of(&self, best: &Candidate) -> ClosestPoint {
        let found = &best.found;
        ClosestPoint {
            point: found.point.map(|c| c as f32),
            distance: found.d2.sqrt() as f32,
            triangle_index: best.record,
            source_triangle_id: self.triangle_ids.and_then(|ids| ids.get(best.record as usize).copied()),
            u: found.u as f32,
            v: found.v as f32,
            instance_index: best.instance,
        }
    }

    /// The winding numbers and signed distances of this tracer's file ([`WindingNumbers`]): their moments,
    /// computed here in O(records). Fails only when memory for them cannot be had.
    pub fn winding_numbers(&self) -> Result<WindingNumbers<'a>, std::collections::TryReserveError> {
        WindingNumbers::new(self)
    }

    /// The binary nodes this tracer walks (a one-level file's tree; in a two-level file, every mesh's).
    pub(crate) fn nodes(&self) -> &'a [PackedNode] {
        self.nodes
    }

    /// The triangle records.
    pub(crate) fn triangles(&self) -> &'a [PackedTriangle] {
        self.triangles
    }

    /// Whether the file has split references.
    pub(crate) fn split(&self) -> bool {
        self.split_references
    }

    /// `mesh`'s ranges of the nodes, records and source ids; `None` when they lie outside the arrays (V41).
    pub(crate) fn mesh_arrays(&self, mesh: &MeshRecord) -> Option<MeshArrays<'a>> {
        let range = |first: u32, count: u32| first as usize..(first as usize).saturating_add(count as usize);
        let nodes = self.nodes.get(range(mesh.first_node, mesh.node_count))?;
        let triangle_range = range(mesh.first_triangle, mesh.triangle_count);
        let triangles = self.triangles.get(triangle_range.clone())?;
        Some((nodes, triangles, self.triangle_ids.and_then(|ids| ids.get(triangle_range))))
    }

    /// Walks `mesh` (placed by instance `index`, `instance`) for `nearest`: its wide tree where this tracer has
    /// the wide kernel, else its binary tree. Nothing when its ranges lie outside the arrays (a file that breaks
    /// V41) or the instance's map is singular (V42).
    fn walk_mesh(
        &self,
        (mesh, index, instance): (&MeshRecord, u32, &'a InstanceRecord),
        nearest: &mut Nearest,
        filter: Option<&dyn PointFilter>,
    ) {
        let (Some((nodes, triangles, ids)), Some(space)) =
            (self.mesh_arrays(mesh), Space::instance(instance, nearest.point))
        else {
            return;
        };
        let tie = TieOrder::new(self.split_references, ids);
        let placement =
            Placement { first_record: mesh.first_triangle, instance: Some((index, instance)), tie, ids, filter };
        let root = nodes.first().map(|root| (root.min, root.max));
        match self.wide.zip(root).and_then(|(wide, root)| wide.mesh(mesh, root, ids)) {
            Some(wide) => {
                let leaves = PacketRecords { packets: wide.sections().packets, placement, avx2: wide.avx2() };
                walk_wide_points(wide.sections(), &space, nearest, &leaves);
            }
            None => walk_points(nodes, &space, nearest, &mut TriangleRecords { triangles, placement }),
        }
    }
}

/// The leaves of a top tree: instances, each walked in its mesh's tree in object space.
struct InstanceLeaves<'t, 'a> {
    tracer: &'t Tracer<'a>,
    sections: &'t TwoLevelSections<'a>,
    filter: Option<&'t dyn PointFilter>,
}

impl PointLeaves for InstanceLeaves<'_, '_> {
    fn test_leaf(&mut self, node: &PackedNode, nearest: &mut Nearest) {
        for index in node.index..node.index.saturating_add(node.count) {
            if let Some((instance, mesh)) = self.sections.placement(index) {
                self.tracer.walk_mesh((mesh, index, instance), nearest, self.filter);
            }
        }
    }
}
