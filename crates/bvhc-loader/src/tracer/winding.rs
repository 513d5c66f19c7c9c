//! A file's winding numbers and signed distances ([`WindingNumbers`]): the winding moments of each of its meshes
//! (`crate::point::winding`, computed once) with the tracer whose closest points give the distances.

use std::collections::TryReserveError;

use crate::point::winding::{Map, MeshMoments, mesh_angle, mesh_moments};
use crate::tracer::Tracer;

/// A file's winding numbers and signed distances: the moments of every mesh, computed once (O(records) time,
/// 136 bytes a binary node), over a tracer that answers the closest points.
#[derive(Clone, Debug)]
pub struct WindingNumbers<'a> {
    tracer: Tracer<'a>,
    /// One a mesh: the file's tree (one level), or each mesh of a two-level file.
    meshes: Vec<MeshMoments>,
}

impl<'a> WindingNumbers<'a> {
    /// The moments of `tracer`'s file. Fails only when memory for them cannot be had.
    pub fn new(tracer: &Tracer<'a>) -> Result<WindingNumbers<'a>, TryReserveError> {
        let mut meshes = Vec::new();
        match tracer.instance_sections() {
            None => {
                meshes.try_reserve_exact(1)?;
                meshes.push(mesh_moments(tracer.nodes(), tracer.triangles(), tracer.triangle_ids(), tracer.split())?);
            }
            Some(sections) => {
                meshes.try_reserve_exact(sections.meshes.len())?;
                for mesh in sections.meshes {
                    let (nodes, triangles, ids) = tracer.mesh_arrays(mesh).unwrap_or((&[], &[], None));
                    meshes.push(mesh_moments(nodes, triangles, ids, tracer.split())?);
                }
            }
        }
        Ok(WindingNumbers { tracer: *tracer, meshes })
    }

    /// The winding number of the file's surface at `point`: 1 inside a closed mesh wound counter-clockwise seen
    /// from outside (-1 for the other winding), 0 outside, fractions near holes; NaN for a point that is not
    /// finite.
    pub fn winding_number(&self, point: [f32; 3]) -> f64 {
        if !point.iter().all(|c| c.is_finite()) {
            return f64::NAN;
        }
        let p = point.map(f64::from);
        let total = match self.tracer.instance_sections() {
            None => match self.meshes.first() {
                Some(moments) => mesh_angle(self.tracer.nodes(), self.tracer.triangles(), moments, p, None),
                None => 0.0,
            },
            Some(sections) => {
                let mut total = 0.0;
                for (index, instance) in sections.instances.iter().enumerate() {
                    let Some((_, mesh)) = sections.placement(index as u32) else { continue };
                    let (Some(moments), Some(map)) = (self.meshes.get(instance.mesh_index as usize), Map::of(instance))
                    else {
                        continue;
                    };
                    let (nodes, triangles, _) = self.tracer.mesh_arrays(mesh).unwrap_or((&[], &[], None));
                    total += mesh_angle(nodes, triangles, moments, p, Some(&map));
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
        if !point.iter().all(|c| c.is_finite()) {
            return f32::NAN;
        }
        let distance = self.tracer.distance(point);
        if distance == 0.0 || distance.is_infinite() {
            return distance;
        }
        if self.winding_number(point).abs() > 0.5 { -distance } else { distance }
    }

    /// [`WindingNumbers::winding_number`] of each of `points` into `out` (the same length; panics otherwise),
    /// on up to `threads` threads (0 counts as 1); the same values on any count.
    pub fn winding_numbers(&self, points: &[[f32; 3]], out: &mut [f64], threads: usize) {
        crate::ray::hit::same_length("winding_numbers", points.len(), out.len());
        crate::parallel::Workers::new(threads).for_chunks(out, 256, |first, chunk| {
            for (slot, &point) in chunk.iter_mut().zip(&points[first..]) {
                *slot = self.winding_number(point);
            }
        });
    }

    /// [`WindingNumbers::signed_distance`] of each of `points` into `out` (the same length; panics otherwise),
    /// on up to `threads` threads (0 counts as 1); the same values on any count.
    pub fn signed_distances(&self, points: &[[f32; 3]], out: &mut [f32], threads: usize) {
        crate::ray::hit::same_length("signed_distances", points.len(), out.len());
        crate::parallel::Workers::new(threads).for_chunks(out, 256, |first, chunk| {
            for (slot, &point) in chunk.iter_mut().zip(&points[first..]) {
                *slot = self.signed_distance(point);
            }
        });
    }
}
