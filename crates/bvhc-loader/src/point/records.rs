//! What a point walk's leaves hold, offered to the query: triangle records from a binary tree's leaves
//! ([`TriangleRecords`]) or from a wide tree's packets ([`PacketRecords`]), in world space or placed by an
//! instance ([`Placement`]). Both read the same vertices (a packet's lane repeats its record bit for bit), so the
//! two layouts offer the same candidates.

use crate::format::{InstanceRecord, PackedNode, PackedTriangle, TrianglePacket4, UNUSED_LANE, WideNode8};
use crate::point::nearest::Nearest;
use crate::point::triangle::{PlaneValues, closest_from_plane};
use crate::point::{PointCandidate, PointFilter, TrianglePoint, closest_on_triangle};
use crate::ray::query::{TieKey, TieOrder};
use crate::ray::transform::world_point;
use crate::simd::Avx2;

/// Where a mesh's records are: the first's absolute index, the instance placing them (`None`: world space), the
/// mesh's tie order and its range of the source ids, and the query's filter, if any.
#[derive(Clone, Copy)]
pub(crate) struct Placement<'a> {
    pub first_record: u32,
    pub instance: Option<(u32, &'a InstanceRecord)>,
    pub tie: TieOrder<'a>,
    pub ids: Option<&'a [u32]>,
    pub filter: Option<&'a dyn PointFilter>,
}

impl Placement<'_> {
    /// Offers the mesh's record `local`, with vertices `vertices` (as stored), to `nearest`.
    #[inline(always)]
    fn offer(&self, nearest: &mut Nearest, local: u32, vertices: [[f32; 3]; 3]) {
        let placed = match self.instance {
            None => vertices.map(|v| v.map(f64::from)),
            Some((_, instance)) => vertices.map(|v| world_point(instance, v)),
        };
        if !placed.iter().flatten().all(|c| c.is_finite()) {
            return; // only in a file that breaks V12 or V42
        }
        self.offer_found(nearest, local, vertices, closest_on_triangle(nearest.point, placed));
    }

    /// Offers the mesh's record `local`, with vertices `vertices` (as stored, all finite), whose closest point
    /// (computed as [`closest_on_triangle`] computes it) is `found`, to `nearest`.
    #[inline(always)]
    fn offer_found(&self, nearest: &mut Nearest, local: u32, vertices: [[f32; 3]; 3], found: TrianglePoint) {
        if nearest.admits(found.d2) {
            if let Some(filter) = self.filter {
                let candidate = PointCandidate {
                    triangle_index: self.first_record.wrapping_add(local),
                    source_triangle_id: self.ids.and_then(|ids| ids.get(local as usize).copied()),
                    instance_index: self.instance.map(|(index, _)| index),
                };
                if !filter.keep(&candidate) {
                    return;
                }
            }
            let key = || match self.tie.key(local, || PackedTriangle { vertices }.coordinate_bits()) {
                TieKey::Record(record) => TieKey::Record(record.wrapping_add(self.first_record)),
                key => key,
            };
            nearest.offer(found, self.first_record.wrapping_add(local), self.instance.map(|(i, _)| i), key);
        }
    }
}

/// What the binary point walk does at a leaf.
pub(crate) trait PointLeaves {
    /// Offers what leaf `node` holds to `nearest`.
    fn test_leaf(&mut self, node: &PackedNode, nearest: &mut Nearest);
}

/// The triangle records of one mesh's binary tree: `triangles` (the mesh's range; leaf indices relative to it).
pub(crate) struct TriangleRecords<'a> {
    pub triangles: &'a [PackedTriangle],
    pub placement: Placement<'a>,
}

impl PointLeaves for TriangleRecords<'_> {
    #[inline(always)]
    fn test_leaf(&mut self, node: &PackedNode, nearest: &mut Nearest) {
        let end = (node.index as usize).saturating_add(node.count as usize);
        let records = self.triangles.get(node.index as usize..end).unwrap_or(&[]);
        for (offset, triangle) in records.iter().enumerate() {
            self.placement.offer(nearest, node.index.wrapping_add(offset as u32), triangle.vertices);
        }
    }
}

/// The triangle packets of one mesh's wide tree (the mesh's range; lanes index the mesh's records), and the
/// AVX2 token where the wide tracer runs that path (a world-space packet's four triangles are then measured in
/// binary64 lanes, `crate::simd::x86_points`, each then finished alone: the same bits as one at a time).
pub(crate) struct PacketRecords<'a> {
    pub packets: &'a [TrianglePacket4],
    pub placement: Placement<'a>,
    pub avx2: Option<Avx2>,
}

impl PacketRecords<'_> {
    /// Offers the packets of the wide leaf reference `reference` to `nearest`.
    #[inline(always)]
    pub(crate) fn test_leaf(&self, reference: u32, nearest: &mut Nearest) {
        let (first, count) = WideNode8::leaf_packets(reference);
        let packets = self.packets.get(first as usize..(first as usize).saturating_add(count as usize)).unwrap_or(&[]);
        for packet in packets {
            #[cfg(target_arch = "x86_64")]
            if let (Some(token), None) = (self.avx2, self.placement.instance) {
                let planes = crate::simd::x86_points::packet_planes(token, nearest.point, packet);
                for (lane, &local) in packet.triangle_index.iter().enumerate() {
                    if local == UNUSED_LANE {
                        break;
                    }
                    let vertices = packet.triangle(lane).vertices;
                    let placed = vertices.map(|v| v.map(f64::from));
                    if placed.iter().flatten().all(|c| c.is_finite()) {
                        let plane = PlaneValues {
                            n: planes.n.map(|axis| axis[lane]),
                            nn: planes.nn[lane],
                            weights: planes.weights.map(|w| w[lane]),
                        };
                        let found = closest_from_plane(nearest.point, placed, plane);
                        self.placement.offer_found(nearest, local, vertices, found);
                    }
                }
                continue;
            }
            for (lane, &local) in packet.triangle_index.iter().enumerate() {
                if local == UNUSED_LANE {
                    break;
                }
                self.placement.offer(nearest, local, packet.triangle(lane).vertices);
            }
        }
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;
    use crate::format::PackedTriangle;
    use crate::point::Point3;
    use crate::point::triangle::plane_values;
    use crate::simd::Avx2;
    use crate::simd::x86_points::packet_planes;

    #[test]
    fn lanes_hold_the_scalar_plane_values_bit_for_bit() {
        let Some(token) = Avx2::detect() else { return };
        let mut state = 11u64;
        let mut next = |scale: f32| {
            state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
            ((state >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * scale
        };
        for round in 0..2000 {
            // Scales from tiny to far, a shared vertex and a degenerate triangle now and then.
            let scale = [1e-6f32, 1.0, 3e4][round % 3];
            let mut triangles: Vec<(u32, PackedTriangle)> = (0..4u32)
                .map(|i| {
                    (i, PackedTriangle { vertices: std::array::from_fn(|_| std::array::from_fn(|_| next(scale))) })
                })
                .collect();
            triangles[1].1.vertices[0] = triangles[0].1.vertices[2];
            if round % 7 == 0 {
                triangles[2].1.vertices[2] = triangles[2].1.vertices[1];
            }
            let packet = TrianglePacket4::new(&triangles);
            let p: Point3 = std::array::from_fn(|_| f64::from(next(scale * 1.5)));
            let planes = packet_planes(token, p, &packet);
            for (lane, (_, triangle)) in triangles.iter().enumerate() {
                let scalar = plane_values(p, triangle.vertices.map(|v| v.map(f64::from)));
                let lanes = PlaneValues {
                    n: planes.n.map(|axis| axis[lane]),
                    nn: planes.nn[lane],
                    weights: planes.weights.map(|w| w[lane]),
                };
                let bits = |v: PlaneValues| (v.n.map(f64::to_bits), v.nn.to_bits(), v.weights.map(f64::to_bits));
                assert_eq!(bits(lanes), bits(scalar), "round {round}, lane {lane}");
            }
        }
    }
}
