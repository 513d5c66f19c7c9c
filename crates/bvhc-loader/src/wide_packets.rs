//! Leaf triangles of the wide BVH in packets of four, structure of arrays (`vertices[vertex][axis][lane]`), and
//! the watertight test of Woop, Benthin and Wald (JCGT 2013) on all four lanes at once: with SSE2 (part of every
//! x86-64 CPU) or in a portable loop over the same arrays. Each lane performs the scalar test's operations in
//! the same order, unfused, so both give the scalar test's `t`, `u`, `v` bit for bit; a lane where an edge
//! function is exactly 0 is redone by the scalar test (its f64 recomputation), and unused lanes (NaN vertices)
//! never hit.

use crate::format::{PACKET_LANES as LANES, TrianglePacket4};
use crate::intersect::{PreparedRay, TriangleHit};

/// Per lane: the edge functions V and W, `t`, the determinant, and bit masks of lanes with a zero edge
/// function, of lanes that hit within `[t_min, t_max]`, and of the hit lanes at the smallest `t` among them.
struct Lanes {
    v: [f32; LANES],
    w: [f32; LANES],
    t: [f32; LANES],
    det: [f32; LANES],
    zero: i32,
    valid: i32,
    nearest: i32,
}

/// The closest hit among the packet's lanes within `t_max` (ties: the last lane, as a scalar loop that accepts
/// `t <= t_max` would end with), as (lane, hit); for `ANY_HIT`, the last lane that hits when no lane needs the
/// scalar redo, without looking for the nearest. `SIMD` picks the SSE2 lanes on x86-64; both give the same hits.
#[inline(always)]
pub fn closest_in_packet<const ANY_HIT: bool, const SIMD: bool>(
    packet: &TrianglePacket4,
    ray: &PreparedRay,
    t_max: f32,
) -> Option<(usize, TriangleHit)> {
    #[cfg(target_arch = "x86_64")]
    let lanes = if SIMD { sse2_lanes(packet, ray, t_max)? } else { portable_lanes(packet, ray, t_max) };
    #[cfg(not(target_arch = "x86_64"))]
    let lanes = portable_lanes(packet, ray, t_max);
    let hit_in = |lane: usize| {
        let inverse_det = 1.0 / lanes.det[lane];
        TriangleHit { t: lanes.t[lane], u: lanes.v[lane] * inverse_det, v: lanes.w[lane] * inverse_det }
    };
    if lanes.zero == 0 {
        // No lane needs the scalar redo: the loop below would end on the last lane at the smallest t.
        let candidates = if ANY_HIT { lanes.valid } else { lanes.nearest };
        let last = 31usize.checked_sub(candidates.leading_zeros() as usize)?;
        return Some((last, hit_in(last)));
    }
    let mut best: Option<(usize, TriangleHit)> = None;
    let mut limit = t_max;
    for lane in 0..LANES {
        let hit = if lanes.zero & (1 << lane) != 0 {
            ray.intersect_triangle(&packet.triangle(lane), limit)
        } else if lanes.valid & (1 << lane) != 0 && lanes.t[lane] <= limit {
            Some(hit_in(lane))
        } else {
            None
        };
        if let Some(hit) = hit {
            limit = hit.t;
            best = Some((lane, hit));
        }
    }
    best
}

/// The four lanes in plain Rust: the SSE2 version's operations, lane by lane.
#[inline(always)]
#[allow(clippy::needless_range_loop)] // the lane indexes nine coordinate arrays and four outputs alike
fn portable_lanes(packet: &TrianglePacket4, ray: &PreparedRay, t_max: f32) -> Lanes {
    let ([kx, ky, kz], [sx, sy, sz]) = ray.shear();
    let p = &packet.vertices;
    let o = ray.origin;
    let mut out =
        Lanes { v: [0.0; LANES], w: [0.0; LANES], t: [0.0; LANES], det: [0.0; LANES], zero: 0, valid: 0, nearest: 0 };
    for lane in 0..LANES {
        let at = |vertex: usize, axis: usize| p[vertex][axis][lane] - o[axis];
        let (akz, bkz, ckz) = (at(0, kz), at(1, kz), at(2, kz));
        let (ax, ay) = (at(0, kx) - sx * akz, at(0, ky) - sy * akz);
        let (bx, by) = (at(1, kx) - sx * bkz, at(1, ky) - sy * bkz);
        let (cx, cy) = (at(2, kx) - sx * ckz, at(2, ky) - sy * ckz);
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        let outside = (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0);
        let det = u + v + w;
        let t = (u * (sz * akz) + v * (sz * bkz) + w * (sz * ckz)) / det;
        let in_range = t >= ray.t_min && t <= t_max;
        out.zero |= i32::from(u == 0.0 || v == 0.0 || w == 0.0) << lane;
        out.valid |= i32::from(!(outside || det == 0.0) && in_range) << lane;
        (out.v[lane], out.w[lane], out.t[lane], out.det[lane]) = (v, w, t, det);
    }
    let masked = |lane: usize| if out.valid & (1 << lane) != 0 { out.t[lane] } else { f32::INFINITY };
    let smallest = (0..LANES).map(masked).fold(f32::INFINITY, f32::min);
    out.nearest =
        (0..LANES).fold(0, |m, lane| m | (i32::from(out.valid & (1 << lane) != 0 && out.t[lane] == smallest) << lane));
    out
}

/// The four lanes with SSE2; `None` as soon as the edge functions show that no lane can hit (every lane
/// outside or unused, none with a zero edge function), before `t` is computed: most packet tests end there,
/// and the portable lanes would then find no hit either.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)] // SSE2 intrinsics: part of the x86-64 baseline, so always available
#[inline(always)]
fn sse2_lanes(packet: &TrianglePacket4, ray: &PreparedRay, t_max: f32) -> Option<Lanes> {
    use std::arch::x86_64::*;
    let ([kx, ky, kz], [sx, sy, sz]) = ray.shear();
    let (origin, t_min) = (ray.origin, ray.t_min);
    // SAFETY: SSE2 is part of every x86-64 CPU; all loads read 16 bytes from `[f32; 4]` arrays of the packet,
    // the stores write `[f32; 4]` locals.
    unsafe {
        let o = |axis: usize| _mm_set1_ps(origin[axis]);
        let load =
            |vertex: usize, axis: usize| _mm_sub_ps(_mm_loadu_ps(packet.vertices[vertex][axis].as_ptr()), o(axis));
        let (sx, sy, sz) = (_mm_set1_ps(sx), _mm_set1_ps(sy), _mm_set1_ps(sz));
        let (akz, bkz, ckz) = (load(0, kz), load(1, kz), load(2, kz));
        let ax = _mm_sub_ps(load(0, kx), _mm_mul_ps(sx, akz));
        let ay = _mm_sub_ps(load(0, ky), _mm_mul_ps(sy, akz));
        let bx = _mm_sub_ps(load(1, kx), _mm_mul_ps(sx, bkz));
        let by = _mm_sub_ps(load(1, ky), _mm_mul_ps(sy, bkz));
        let cx = _mm_sub_ps(load(2, kx), _mm_mul_ps(sx, ckz));
        let cy = _mm_sub_ps(load(2, ky), _mm_mul_ps(sy, ckz));
        let u = _mm_sub_ps(_mm_mul_ps(cx, by), _mm_mul_ps(cy, bx));
        let v = _mm_sub_ps(_mm_mul_ps(ax, cy), _mm_mul_ps(ay, cx));
        let w = _mm_sub_ps(_mm_mul_ps(bx, ay), _mm_mul_ps(by, ax));
        let z = _mm_setzero_ps();
        let zero = _mm_or_ps(_mm_or_ps(_mm_cmpeq_ps(u, z), _mm_cmpeq_ps(v, z)), _mm_cmpeq_ps(w, z));
        let negative = _mm_or_ps(_mm_or_ps(_mm_cmplt_ps(u, z), _mm_cmplt_ps(v, z)), _mm_cmplt_ps(w, z));
        let positive = _mm_or_ps(_mm_or_ps(_mm_cmpgt_ps(u, z), _mm_cmpgt_ps(v, z)), _mm_cmpgt_ps(w, z));
        let outside = _mm_and_ps(negative, positive);
        let det = _mm_add_ps(_mm_add_ps(u, v), w);
        // A lane can hit only when it is not outside and its det is a number (unused lanes are NaN), or when
        // an edge function is zero (the scalar redo decides).
        if _mm_movemask_ps(_mm_or_ps(_mm_andnot_ps(outside, _mm_cmpord_ps(det, det)), zero)) == 0 {
            return None;
        }
        let (az, bz, cz) = (_mm_mul_ps(sz, akz), _mm_mul_ps(sz, bkz), _mm_mul_ps(sz, ckz));
        let t = _mm_div_ps(_mm_add_ps(_mm_add_ps(_mm_mul_ps(u, az), _mm_mul_ps(v, bz)), _mm_mul_ps(w, cz)), det);
        let in_range = _mm_and_ps(_mm_cmpge_ps(t, _mm_set1_ps(t_min)), _mm_cmple_ps(t, _mm_set1_ps(t_max)));
        let valid = _mm_andnot_ps(_mm_or_ps(outside, _mm_cmpeq_ps(det, z)), in_range);
        // The smallest t of the valid lanes (others +inf) in every lane, then the valid lanes at it.
        let masked = _mm_or_ps(_mm_and_ps(valid, t), _mm_andnot_ps(valid, _mm_set1_ps(f32::INFINITY)));
        let smallest = _mm_min_ps(masked, _mm_shuffle_ps::<0b10_11_00_01>(masked, masked));
        let smallest = _mm_min_ps(smallest, _mm_shuffle_ps::<0b01_00_11_10>(smallest, smallest));
        let nearest = _mm_and_ps(valid, _mm_cmpeq_ps(masked, smallest));
        let mut out = [[0f32; LANES]; 4];
        for (slot, value) in out.iter_mut().zip([v, w, t, det]) {
            _mm_storeu_ps(slot.as_mut_ptr(), value);
        }
        Some(Lanes {
            v: out[0],
            w: out[1],
            t: out[2],
            det: out[3],
            zero: _mm_movemask_ps(zero),
            valid: _mm_movemask_ps(valid),
            nearest: _mm_movemask_ps(nearest),
        })
    }
}
