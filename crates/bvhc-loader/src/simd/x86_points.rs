//! The plane values of a triangle packet's four triangles for one query point in AVX2 binary64 lanes
//! ([`packet_planes`]): the first steps of `crate::point::closest_on_triangle` (normal, its square, the three
//! weights), operation for operation and in its order (no fused operation), so each lane holds the scalar
//! values bit for bit (`crate::point::records` finishes each triangle alone and tests the lanes against the
//! scalar values).

#![allow(unsafe_code)] // intrinsics: each block states what it relies on

use std::arch::x86_64::*;

use super::x86::Avx2;
use crate::format::{PACKET_LANES, TrianglePacket4};

type V = __m256d;
type V3 = [V; 3];

// Each helper is one AVX instruction, inlined into `closest_on_packet_avx2`, which runs with AVX2 enabled.
#[inline(always)]
fn add(a: V, b: V) -> V {
    // SAFETY: only called from `closest_on_packet_avx2`, whose caller proved AVX2.
    unsafe { _mm256_add_pd(a, b) }
}
#[inline(always)]
fn sub(a: V, b: V) -> V {
    // SAFETY: as `add`.
    unsafe { _mm256_sub_pd(a, b) }
}
#[inline(always)]
fn mul(a: V, b: V) -> V {
    // SAFETY: as `add`.
    unsafe { _mm256_mul_pd(a, b) }
}
#[inline(always)]
fn splat(x: f64) -> V {
    // SAFETY: as `add`.
    unsafe { _mm256_set1_pd(x) }
}
#[inline(always)]
fn lanes(v: V) -> [f64; PACKET_LANES] {
    let mut out = [0.0; PACKET_LANES];
    // SAFETY: as `add`; `out` has room for four f64.
    unsafe { _mm256_storeu_pd(out.as_mut_ptr(), v) };
    out
}

#[inline(always)]
fn sub3(a: V3, b: V3) -> V3 {
    [sub(a[0], b[0]), sub(a[1], b[1]), sub(a[2], b[2])]
}
#[inline(always)]
fn dot3(a: V3, b: V3) -> V {
    add(add(mul(a[0], b[0]), mul(a[1], b[1])), mul(a[2], b[2]))
}
#[inline(always)]
fn cross3(a: V3, b: V3) -> V3 {
    [
        sub(mul(a[1], b[2]), mul(a[2], b[1])),
        sub(mul(a[2], b[0]), mul(a[0], b[2])),
        sub(mul(a[0], b[1]), mul(a[1], b[0])),
    ]
}

/// The plane values of a packet's four triangles, lane by lane: the normal `n = (v1 - v0) x (v2 - v0)` by axis,
/// `n . n`, and the weights of `v0`, `v1`, `v2`, in binary64.
pub(crate) struct PacketPlanes {
    pub n: [[f64; PACKET_LANES]; 3],
    pub nn: [f64; PACKET_LANES],
    pub weights: [[f64; PACKET_LANES]; 3],
}

/// The plane values of each lane's triangle of `packet` for the point `p`: those `closest_on_triangle` computes
/// from the lane's vertices (as f64), bit for bit.
pub(crate) fn packet_planes(token: Avx2, p: [f64; 3], packet: &TrianglePacket4) -> PacketPlanes {
    let _ = token;
    // SAFETY: `token` exists, so `Avx2::detect` found AVX2 on this CPU.
    unsafe { packet_planes_avx2(p, packet) }
}

/// # Safety
/// The CPU must support AVX2.
#[target_feature(enable = "avx2")]
unsafe fn packet_planes_avx2(p: [f64; 3], packet: &TrianglePacket4) -> PacketPlanes {
    let mut corners = [[_mm256_setzero_pd(); 3]; 3];
    for (corner, rows) in corners.iter_mut().zip(&packet.vertices) {
        for (lanes, row) in corner.iter_mut().zip(rows) {
            // SAFETY: a packet row is four f32, 16 readable bytes; AVX2 (with SSE) is enabled here.
            *lanes = unsafe { _mm256_cvtps_pd(_mm_loadu_ps(row.as_ptr())) };
        }
    }
    let [a, b, c] = corners;
    let q: V3 = p.map(splat);
    let n = cross3(sub3(b, a), sub3(c, a));
    PacketPlanes {
        nn: lanes(dot3(n, n)),
        weights: [
            lanes(dot3(cross3(sub3(c, b), sub3(q, b)), n)),
            lanes(dot3(cross3(sub3(a, c), sub3(q, c)), n)),
            lanes(dot3(cross3(sub3(b, a), sub3(q, a)), n)),
        ],
        n: n.map(lanes),
    }
}
