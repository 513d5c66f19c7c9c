//! Leaf triangles of the wide BVH in packets of four, structure of arrays (`vertices[vertex][axis][lane]`), and
//! the watertight test ([`crate::ray::watertight`]) on all four lanes at once, in the instruction set's four lanes
//! (SSE2 on the AVX2 path, portable arrays otherwise). Each lane gives the scalar test's `t`, `u`, `v` bit for
//! bit; a lane where an edge function is exactly 0 is redone by the scalar test (its f64 recomputation), and so
//! is a lane whose hit is ill-conditioned (its exact `t`, `u`, `v`); unused lanes (NaN vertices) never hit. A
//! lane's hit counts where it meets the box condition (`crate::ray::reach`), checked for the lane taken.

use crate::format::{PACKET_LANES as LANES, TrianglePacket4};
use crate::ray::candidates::Candidates;
use crate::ray::hit::TriangleHit;
use crate::ray::intersect::PreparedRay;
use crate::ray::query::{Query, TieOrder};
use crate::ray::watertight::{
    EXACT_SIGNS, ILL_CONDITIONED, RelativeTriangle, TINY_EXTENT, barycentrics, conditioning, determinant, distance,
    edge_functions, has_zero_edge, hits, outside, sheared,
};
use crate::simd::{Isa, LaneMask, Lanes};

/// Per lane: the edge functions, `t`, the determinant, and bit masks of lanes the scalar test redoes (an edge
/// function exactly 0, or an ill-conditioned hit, which takes its exact values), of lanes that hit within
/// `[t_min, t_max]`, and of the hit lanes at the smallest `t` among them.
struct PacketLanes {
    v: [f32; LANES],
    w: [f32; LANES],
    t: [f32; LANES],
    det: [f32; LANES],
    redo: u32,
    valid: u32,
    nearest: u32,
    /// Lanes whose edge functions have their exact signs ([`conditioning`]): a well-conditioned hit there
    /// meets the box condition without testing it.
    exact_signs: u32,
}

/// The closest hit among the packet's lanes within `t_max` (ties: the first lane in spec 11.1's order), as
/// (lane, hit); for an any-hit query, the last lane that hits when no lane needs the
/// scalar redo, without looking for the nearest or computing `u` and `v` (0). The same hits on every
/// instruction set. With active `candidates` (a hit filter), the lanes go one by one as in the scalar redo,
/// each hit asked whether it is accepted (with its `u` and `v`), and the closest accepted one returned (for
/// an any-hit query, the first).
#[inline(always)]
pub(crate) fn closest_in_packet<Q: Query, I: Isa, C: Candidates>(
    isa: I,
    packet: &TrianglePacket4,
    ray: &PreparedRay,
    t_max: f32,
    candidates: &C,
    tie: TieOrder<'_>,
) -> Option<(usize, TriangleHit)> {
    let lanes = packet_lanes::<Q, I>(isa, packet, ray, t_max)?;
    let hit_in = |lane: usize| {
        let (u, v) = barycentrics([0.0, lanes.v[lane], lanes.w[lane]], lanes.det[lane], 1.0);
        TriangleHit { t: lanes.t[lane], u, v }
    };
    // A filter is consulted only when a lane that may hit is one it asks about (in practice: a lane of a
    // not-opaque triangle); otherwise every hit is accepted and the plain choice below is the filtered one.
    if C::ACTIVE && asks_in_packet(packet, lanes.valid | lanes.redo, candidates) {
        return accepted_in_packet::<Q, C>(packet, ray, (t_max, tie), &lanes, &hit_in, candidates);
    }
    if lanes.redo == 0 {
        // No lane needs the scalar redo: the loop below would end on the first in tie order at the smallest t,
        // once the lane taken meets the box condition (a lane that does not is rare: the loop then decides).
        // An any-hit query only needs to know that a lane hits: its `u` and `v` are not computed (0).
        if Q::FIRST_HIT_ENDS {
            let mut valid = lanes.valid;
            while valid != 0 {
                let last = (31 - valid.leading_zeros()) as usize & (LANES - 1);
                if counts(ray, packet, (last, lanes.t[last]), lanes.exact_signs) {
                    return Some((last, TriangleHit { t: lanes.t[last], u: 0.0, v: 0.0 }));
                }
                valid &= !(1 << last);
            }
            return None;
        }
        let last = 31usize.checked_sub(lanes.nearest.leading_zeros() as usize)? & (LANES - 1);
        // Two lanes at the nearest `t` (rare) are ordered out of line.
        let lane = match lanes.nearest == 1 << last {
            true => last,
            false => first_in_tie_order(packet, lanes.nearest, tie),
        };
        if counts(ray, packet, (lane, lanes.t[lane]), lanes.exact_signs) {
            return Some((lane, hit_in(lane)));
        }
    }
    let mut best: Option<(usize, TriangleHit)> = None;
    let mut limit = t_max;
    for lane in 0..LANES {
        let hit = if lanes.redo & (1 << lane) != 0 {
            ray.intersect_triangle(&packet.triangle(lane), limit)
        } else if lanes.valid & (1 << lane) != 0
            && lanes.t[lane] <= limit
            && counts(ray, packet, (lane, lanes.t[lane]), lanes.exact_signs)
        {
            Some(hit_in(lane))
        } else {
            None
        };
        if let Some(hit) = hit
            && best
                .is_none_or(|(best, _)| hit.t < limit || (hit.t == limit && lane_first_at_tie(packet, lane, best, tie)))
        {
            limit = hit.t;
            best = Some((lane, hit));
        }
    }
    best
}

/// Whether the well-conditioned hit of lane `lane` at `t` meets the box condition (`crate::ray::reach`): at once
/// where the lane's edge functions have their exact signs and `t` is finite, else by the test; a lane the scalar
/// test redoes is checked there.
#[inline(always)]
fn counts(ray: &PreparedRay, packet: &TrianglePacket4, (lane, t): (usize, f32), exact_signs: u32) -> bool {
    (exact_signs & (1 << lane) != 0 && t < f32::INFINITY) || lane_meets_record_box(ray, packet, lane, t)
}

/// [`PreparedRay::meets_record_box`] for lane `lane`: out of line, as it rarely runs.
#[cold]
#[inline(never)]
fn lane_meets_record_box(ray: &PreparedRay, packet: &TrianglePacket4, lane: usize, t: f32) -> bool {
    ray.meets_record_box(&packet.triangle(lane), t)
}

/// Of the lanes in `mask` (two or more hit lanes at the smallest `t`), the first in the tie order ([`TieKey`]:
/// the lowest record, or with split references the lowest coordinates and id; the first lane of equal keys). Cold: one
/// lane, the usual case, needs no key.
#[cold]
#[inline(never)]
fn first_in_tie_order(packet: &TrianglePacket4, mask: u32, tie: TieOrder<'_>) -> usize {
    let mut lowest = mask.trailing_zeros() as usize & (LANES - 1);
    let mut rest = mask & mask.wrapping_sub(1);
    while rest != 0 {
        let lane = rest.trailing_zeros() as usize & (LANES - 1);
        rest &= rest - 1;
        if lane_first_at_tie(packet, lane, lowest, tie) {
            lowest = lane;
        }
    }
    lowest
}

/// Whether, of two hits at one `t`, lane `lane`'s comes before lane `best`'s in spec 11.1's order.
#[cold]
#[inline(never)]
fn lane_first_at_tie(packet: &TrianglePacket4, lane: usize, best: usize, tie: TieOrder<'_>) -> bool {
    let key = |l: usize| tie.key(packet.triangle_index[l], || packet.triangle(l).coordinate_bits());
    key(lane) < key(best)
}

/// Whether `candidates` asks about any of the lanes in `mask`.
#[inline]
fn asks_in_packet<C: Candidates>(packet: &TrianglePacket4, mask: u32, candidates: &C) -> bool {
    let mut lanes = mask & ((1 << LANES) - 1);
    while lanes != 0 {
        if candidates.asks(packet.triangle_index[lanes.trailing_zeros() as usize]) {
            return true;
        }
        lanes &= lanes - 1;
    }
    false
}

/// The closest lane hit within `t_max` that `candidates` accepts (the first, for an any-hit query), the lanes taken one
/// by one (a lane with a zero edge function redone by the scalar test), each hit offered to `candidates` with
/// its record index; ties as [`closest_in_packet`] (the accepted lane first in tie order at the smallest `t`).
#[inline(never)]
fn accepted_in_packet<Q: Query, C: Candidates>(
    packet: &TrianglePacket4,
    ray: &PreparedRay,
    (t_max, tie): (f32, TieOrder<'_>),
    lanes: &PacketLanes,
    hit_in: &impl Fn(usize) -> TriangleHit,
    candidates: &C,
) -> Option<(usize, TriangleHit)> {
    let mut best: Option<(usize, TriangleHit)> = None;
    let mut limit = t_max;
    for lane in 0..LANES {
        let hit = if lanes.redo & (1 << lane) != 0 {
            ray.intersect_triangle(&packet.triangle(lane), limit)
        } else if lanes.valid & (1 << lane) != 0
            && lanes.t[lane] <= limit
            && counts(ray, packet, (lane, lanes.t[lane]), lanes.exact_signs)
        {
            Some(hit_in(lane))
        } else {
            None
        };
        if let Some(hit) = hit
            && candidates.accept(packet.triangle_index[lane], &hit)
        {
            if Q::FIRST_HIT_ENDS {
                return Some((lane, hit));
            }
            if best
                .is_none_or(|(best, _)| hit.t < limit || (hit.t == limit && lane_first_at_tie(packet, lane, best, tie)))
            {
                limit = hit.t;
                best = Some((lane, hit));
            }
        }
    }
    best
}

/// The four lanes' test; `None` as soon as the edge functions show that no lane can hit (every lane outside or
/// unused, none with a zero edge function), before `t` is computed: most packet tests end there.
#[inline(always)]
fn packet_lanes<Q: Query, I: Isa>(
    isa: I,
    packet: &TrianglePacket4,
    ray: &PreparedRay,
    t_max: f32,
) -> Option<PacketLanes> {
    let ([kx, ky, kz], [sx, sy, sz]) = ray.shear();
    // The ray's values copied out and spread over the lanes where they are used: reading them through the
    // reference, or spreading them once for a leaf, let the compiler keep fewer of them in registers (3-9%
    // more instructions a ray through the wide kernel, measured with callgrind).
    let (origin, t_min) = (ray.origin, ray.t_min);
    let load = |vertex: usize, axis: usize| isa.f4(&packet.vertices[vertex][axis]).sub(isa.f4_splat(origin[axis]));
    let (sx, sy, sz) = (isa.f4_splat(sx), isa.f4_splat(sy), isa.f4_splat(sz));
    let r = RelativeTriangle {
        a: [load(0, kx), load(0, ky), load(0, kz)],
        b: [load(1, kx), load(1, ky), load(1, kz)],
        c: [load(2, kx), load(2, ky), load(2, kz)],
    };
    let zero = isa.f4_splat(0.0);
    let p = sheared(&r, sx, sy);
    let e = edge_functions(p);
    let on_edge = has_zero_edge(e, zero);
    let outside = outside(e, zero);
    let det = determinant(e);
    let inside = det.is_number().and_not(outside);
    if inside.or(on_edge).bits() == 0 {
        return None;
    }
    let thresholds = (isa.f4_splat(ILL_CONDITIONED), isa.f4_splat(TINY_EXTENT), isa.f4_splat(EXACT_SIGNS));
    let (ill, exact_signs) = conditioning(e, p, &r, det, thresholds);
    let redo = on_edge.or(ill.and(inside));
    let t = distance(e, &r, sz, det);
    let valid = hits(outside, det, t, zero, isa.f4_splat(t_min), isa.f4_splat(t_max));
    let exact_signs = exact_signs.bits();
    let nearest = if Q::FIRST_HIT_ENDS {
        0 // an any-hit query takes any valid lane
    } else {
        let masked = I::F4::select(valid, t, isa.f4_splat(f32::INFINITY));
        valid.and(masked.eq(masked.min_across())).bits()
    };
    Some(PacketLanes {
        v: e[1].to_array(),
        w: e[2].to_array(),
        t: t.to_array(),
        det: det.to_array(),
        redo: redo.bits(),
        valid: valid.bits(),
        nearest,
        exact_signs,
    })
}
