//! The leaf test of a coherent packet: each triangle of a leaf against all the packet's rays in lanes, with the
//! single-ray watertight test's operations ([`crate::ray::watertight`]), whether the rays share their shear axes
//! or not ([`LaneAxes`]).

use crate::format::TrianglePacket4;
use crate::ray::hit::{TriangleHit, lane_address};
use crate::ray::intersect::{PreparedRay, Ray};
use crate::ray::query::Query;
use crate::ray::watertight::{
    EXACT_SIGNS, ILL_CONDITIONED, RelativeTriangle, TINY_EXTENT, barycentrics, conditioning, determinant, distance,
    edge_functions, has_zero_edge, hits, outside, sheared,
};
use crate::simd::{Isa, LaneMask, Lanes};
use crate::wide::coherent::lanes::{Found, LaneAxes, PACKET_RAYS, RayLanes};
use crate::wide::walk::Sections;

/// The triangles of `packets`, one after the other, against the `active` rays in lanes, each lane in its ray's
/// shear axes (`axes`): per (ray, triangle) the scalar watertight test's operations in its order, a lane with an
/// edge function exactly 0 or an ill-conditioned hit redone by the scalar test, and a hit taken when it precedes
/// the ray's closest so far (a smaller `t`, or the same and a lower record), so each ray ends with what the
/// single-ray packet test gives (a redo prepares its ray, `rays[l]`, then). Returns the rays that took a hit.
#[inline(always)]
#[allow(clippy::too_many_arguments)] // the packet's state, passed apart so that it stays in registers
pub(super) fn leaf_in_lanes<Q: Query, I: Isa>(
    isa: I,
    sections: &Sections<'_>,
    (first, packets): (usize, &[TrianglePacket4]),
    lanes: &RayLanes,
    axes: &impl LaneAxes<I>,
    mut active: u8,
    rays: &[Ray],
    found: &mut Found,
) -> u8 {
    let mut hit_rays = 0u8;
    let origin = [isa.f8(&lanes.origin[0]), isa.f8(&lanes.origin[1]), isa.f8(&lanes.origin[2])];
    let (sx, sy, sz) = (isa.f8(&lanes.shear[0]), isa.f8(&lanes.shear[1]), isa.f8(&lanes.shear[2]));
    let (t_min, zero, one) = (isa.f8(&lanes.t_min), isa.f8_splat(0.0), isa.f8_splat(1.0));
    // Each ray's `t_max` kept in lanes and narrowed in lanes as hits are taken, not reloaded from `found` for
    // each triangle: a vector load of what the hits just stored lane by lane cannot be forwarded from the
    // stores and waits for them.
    let mut t_max = isa.f8(&found.t_max);
    for (p, packet) in packets.iter().enumerate() {
        for tri in 0..packet.used_lanes() {
            let r = RelativeTriangle {
                a: relative_vertex(isa, &packet.vertices[0], tri, axes, &origin),
                b: relative_vertex(isa, &packet.vertices[1], tri, axes, &origin),
                c: relative_vertex(isa, &packet.vertices[2], tri, axes, &origin),
            };
            let projected = sheared(&r, sx, sy);
            let e = edge_functions(projected);
            let outside = outside(e, zero);
            let mut redo_rays = has_zero_edge(e, zero).bits() as u8 & active;
            // Every active ray strictly outside (no edge function 0 to redo): nothing below can take a hit or
            // touch `found`, so the division and the conditioning are skipped (Embree's leaves exit here too).
            if !outside.bits() as u8 & active == 0 && redo_rays == 0 {
                continue;
            }
            let det = determinant(e);
            let t = distance(e, &r, sz, det);
            let valid = hits(outside, det, t, zero, t_min, t_max);
            let inside = det.is_number().and_not(outside);
            let mut exact_signs = 0u8;
            if inside.bits() as u8 & active != 0 {
                // Ill-conditioned hits get their exact values from the scalar test.
                let thresholds = (isa.f8_splat(ILL_CONDITIONED), isa.f8_splat(TINY_EXTENT), isa.f8_splat(EXACT_SIGNS));
                let (ill, exact) = conditioning(e, projected, &r, det, thresholds);
                redo_rays |= ill.and(inside).bits() as u8 & active;
                exact_signs = exact.bits() as u8;
            }
            let valid_rays = valid.bits() as u8 & active & !redo_rays;
            let address = lane_address(first + p, tri);
            let mut refused = false;
            if valid_rays != 0 {
                let (u, v) = barycentrics(e, det, one);
                let (t_lanes, u, v) = (t.to_array(), u.to_array(), v.to_array());
                let mut valid_left = valid_rays;
                while valid_left != 0 {
                    let l = valid_left.trailing_zeros() as usize & (PACKET_RAYS - 1);
                    valid_left &= valid_left - 1;
                    // A hit counts where it meets the box condition, which a lane with its edge functions' exact
                    // signs does (rare not to: the lanes are then reloaded).
                    let sure = exact_signs & (1 << l) != 0 && t_lanes[l] < f32::INFINITY;
                    if !sure {
                        let kz = rays.get(l).map_or(2, |ray| axes.kz(ray));
                        let ray = (lanes.t_min[l], kz, lanes.shear[2][l]);
                        if !lanes.box_ray(l).meets_record_box(&packet.triangle(tri), t_lanes[l], ray) {
                            refused = true;
                            continue;
                        }
                    }
                    if Q::FIRST_HIT_ENDS || found.taken_by(sections, l, t_lanes[l], address) {
                        found.take(l, address, TriangleHit { t: t_lanes[l], u: u[l], v: v[l] });
                        hit_rays |= 1 << l;
                    }
                }
                // A taken hit sets its ray's `t_max` to its `t`; a valid one not taken is a tie lost at that very
                // `t`. So the lanes' minimum with the valid `t`s is what `found` now holds in every active lane
                // that no redo touches (the other lanes' tests are masked off), unless a lane was refused.
                if !refused {
                    t_max = t_max.min_or(I::F8::select(valid, t, isa.f8_splat(f32::INFINITY)));
                }
            }
            let mut redo = redo_rays;
            while redo != 0 {
                let l = redo.trailing_zeros() as usize & (PACKET_RAYS - 1);
                redo &= redo - 1;
                let Some(ray) = rays.get(l).map(PreparedRay::new) else { continue };
                if let Some(hit) = ray.intersect_triangle(&packet.triangle(tri), found.t_max[l])
                    && (Q::FIRST_HIT_ENDS || found.taken_by(sections, l, hit.t, address))
                {
                    found.take(l, address, hit);
                    hit_rays |= 1 << l;
                }
            }
            if redo_rays != 0 || refused {
                t_max = isa.f8(&found.t_max);
            }
        }
        if Q::FIRST_HIT_ENDS {
            active &= !hit_rays;
            if active == 0 {
                break;
            }
        }
    }
    hit_rays
}

/// Vertex `vertex` of the packet's triangle in lane `tri` minus each ray's origin (`origin`, by axis), in each
/// lane's permuted axes `[kx, ky, kz]`: the differences by axis, as the scalar test takes them, then permuted.
#[inline(always)]
fn relative_vertex<I: Isa>(
    isa: I,
    vertex: &[[f32; 4]; 3],
    tri: usize,
    axes: &impl LaneAxes<I>,
    origin: &[I::F8; 3],
) -> [I::F8; 3] {
    // Written out: a closure (`array::map`) would be compiled apart from the instruction set's function.
    axes.pick([
        isa.f8_splat(vertex[0][tri]).sub(origin[0]),
        isa.f8_splat(vertex[1][tri]).sub(origin[1]),
        isa.f8_splat(vertex[2][tri]).sub(origin[2]),
    ])
}
