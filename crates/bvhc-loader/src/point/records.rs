//! What a point walk's leaves hold, offered to the query: triangle records from a binary tree's leaves
//! ([`TriangleRecords`]) or from a wide tree's packets ([`PacketRecords`]), in world space or placed by an
//! instance ([`Placement`]). Both read the same vertices (a packet's lane repeats its record bit for bit), so the
//! two layouts offer the same candidates.

use crate::format::{InstanceRecord, PackedNode, PackedTriangle, TrianglePacket4, UNUSED_LANE, WideNode8};
use crate::point::nearest::Nearest;
use crate::point::triangle::closest_from_plane;
use crate::point::{TrianglePoint, closest_on_triangle};
use crate::ray::query::{TieKey, TieOrder};
use crate::ray::transform::world_point;
use crate::simd::Avx2;

/// Where a mesh's records are: the first's absolute index, the instance placing them (`None`: world space), and
/// the mesh's tie order (its range of the source ids).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Placement<'a> {
    pub first_record: u32,
    pub instance: Option<(u32, &'a InstanceRecord)>,
    pub tie: TieOrder<'a>,
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
                        let found = closest_from_plane(nearest.point, placed, planes[lane]);
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
