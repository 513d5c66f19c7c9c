//! Leaf triangles of the wide BVH in packets of four, structure of arrays (`v[vertex][axis][lane]`), and the
//! watertight test of Woop, Benthin and Wald (JCGT 2013) on all four lanes at once with SSE2 (part of every
//! x86-64 CPU). Each lane performs the scalar test's operations in the same order, unfused, so it yields the
//! same `t`, `u`, `v` bit for bit; a lane where an edge function is exactly 0 is redone by the scalar test (its
//! f64 recomputation), and padding lanes (NaN vertices) never hit.

use crate::format::{PACKET_LANES as LANES, TrianglePacket4};
use crate::intersect::{PreparedRay, TriangleHit};

/// The closest hit among the packet's lanes within `t_max` (ties: the last lane, as a scalar loop that accepts
/// `t <= t_max` would end with), as (lane, hit). A lane with a zero edge function is redone by the scalar test.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)] // SSE2 intrinsics: part of the x86-64 baseline, so always available
pub fn closest_in_packet(packet: &TrianglePacket4, ray: &PreparedRay, t_max: f32) -> Option<(usize, TriangleHit)> {
    use std::arch::x86_64::*;
    let ([kx, ky, kz], [sx, sy, sz]) = ray.shear();
    let (origin, t_min) = (ray.origin, ray.t_min);
    // SAFETY: SSE2 is part of every x86-64 CPU; all loads read 16 bytes from `[f32; 4]` arrays of the packet,
    // the stores write `[f32; 4]` locals.
    let (v, w, t, det, zero, valid) = unsafe {
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
        let (az, bz, cz) = (_mm_mul_ps(sz, akz), _mm_mul_ps(sz, bkz), _mm_mul_ps(sz, ckz));
        let t = _mm_div_ps(_mm_add_ps(_mm_add_ps(_mm_mul_ps(u, az), _mm_mul_ps(v, bz)), _mm_mul_ps(w, cz)), det);
        let in_range = _mm_and_ps(_mm_cmpge_ps(t, _mm_set1_ps(t_min)), _mm_cmple_ps(t, _mm_set1_ps(t_max)));
        let valid = _mm_andnot_ps(_mm_or_ps(outside, _mm_cmpeq_ps(det, z)), in_range);
        let mut out = [[0f32; LANES]; 4];
        for (slot, value) in out.iter_mut().zip([v, w, t, det]) {
            _mm_storeu_ps(slot.as_mut_ptr(), value);
        }
        (out[0], out[1], out[2], out[3], _mm_movemask_ps(zero), _mm_movemask_ps(valid))
    };
    let mut best: Option<(usize, TriangleHit)> = None;
    let mut limit = t_max;
    for lane in 0..LANES {
        let hit = if zero & (1 << lane) != 0 {
            ray.intersect_triangle(&packet.triangle(lane), limit)
        } else if valid & (1 << lane) != 0 && t[lane] <= limit {
            let inverse_det = 1.0 / det[lane];
            Some(TriangleHit { t: t[lane], u: v[lane] * inverse_det, v: w[lane] * inverse_det })
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
