//! What a GPU whose arithmetic is not correctly rounded and unfused (as Mesa's lavapipe is) does with the WGSL
//! kernel's triangle test (`format-spec/bvh-1.md` 11.4), emulated on the CPU: the shader compiler fuses every
//! multiply that feeds an add into one fused multiply-add (the sheared coordinates, the edge functions'
//! differences, the numerator of `t`), and every division with a nonzero quotient lands one ulp off the correctly
//! rounded one (WGSL allows 2.5). Brute force over every stress scene against 11.1's procedure: closed meshes lose no ray
//! (shared edges and vertices stay watertight, since both triangles compute the same sheared vertices), and
//! wherever the decision differs the triangle hit or passed lies within rounding of the ray: the ray passes one
//! of its edges within the stress test's false-hit tolerance (4 ulps of the coordinates' magnitude).

use bvhc::loader::Ray;

use crate::common::{Triangle, brute_force_closest};
use crate::gpu_compare::t_bound;
use crate::stress::{FALSE_HIT_TOLERANCE, stress_cases};

/// A quotient `x` one ulp up or down (0, from a zero numerator, stays exact: no division algorithm errs there).
fn off_by_one(x: f32, up: bool) -> f32 {
    if x == 0.0 {
        x
    } else if up {
        x.next_up()
    } else {
        x.next_down()
    }
}

/// 11.1's test as the WGSL kernel runs it on such a GPU; `skew` picks which way each division errs.
fn fused_gpu_hit(ray: &Ray, tri: &Triangle, skew: u32) -> Option<f32> {
    let d = ray.direction;
    let abs = d.map(f32::abs);
    let kz = if abs[0] >= abs[1] && abs[0] >= abs[2] {
        0
    } else if abs[1] >= abs[2] {
        1
    } else {
        2
    };
    let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
    if d[kz] < 0.0 {
        std::mem::swap(&mut kx, &mut ky);
    }
    let sx = off_by_one(d[kx] / d[kz], skew & 1 != 0);
    let sy = off_by_one(d[ky] / d[kz], skew & 2 != 0);
    let sz = off_by_one(1.0 / d[kz], skew & 4 != 0);
    let relative = tri.map(|v| std::array::from_fn::<f32, 3, _>(|a| v[a] - ray.origin[a]));
    let sheared = relative.map(|r| [(-sx).mul_add(r[kz], r[kx]), (-sy).mul_add(r[kz], r[ky])]);
    let [[ax, ay], [bx, by], [cx, cy]] = sheared;
    // The kernel's edge_function: the exact value where the rounded products are equal, else their difference,
    // here fused (its sign is still the products' order).
    let edge = |a: f32, b: f32, c: f32, d: f32| {
        let (p, q) = (a * b, c * d);
        if p == q && p.is_normal() {
            let x = f64::from(a) * f64::from(b) - f64::from(c) * f64::from(d);
            if x != 0.0 && x.abs() < f64::from(f32::MIN_POSITIVE) {
                f32::MIN_POSITIVE.copysign(x as f32)
            } else {
                x as f32
            }
        } else {
            a.mul_add(b, -q)
        }
    };
    let (u, v, w) = (edge(cx, by, cy, bx), edge(ax, cy, ay, cx), edge(bx, ay, by, ax));
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    let z = [relative[0][kz], relative[1][kz], relative[2][kz]].map(|c| sz * c);
    let numerator = w.mul_add(z[2], v.mul_add(z[1], u * z[0]));
    let t = off_by_one(numerator / det, skew & 8 != 0);
    (t >= ray.t_min && t <= ray.t_max).then_some(t)
}

/// The emulated GPU's closest hit over every triangle.
fn fused_gpu_closest(triangles: &[Triangle], ray: &Ray, skew: u32) -> Option<(f32, usize)> {
    let mut best: Option<(f32, usize)> = None;
    for (i, tri) in triangles.iter().enumerate() {
        if let Some(t) = fused_gpu_hit(ray, tri, skew)
            && best.is_none_or(|b| t < b.0)
        {
            best = Some((t, i));
        }
    }
    best
}

/// How close `ray`'s line passes to `tri`'s edges, relative to the stress test's tolerance for the coordinates'
/// magnitude (at most 1: within rounding of an edge). Measured between the line and each edge segment, in f64,
/// so a grazing ray is not judged by where it meets the plane.
fn edge_distance_over_tolerance(tri: &Triangle, ray: &Ray, scale: f64) -> f64 {
    let o = ray.origin.map(f64::from);
    let d = ray.direction.map(f64::from);
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let sub = |a: [f64; 3], b: [f64; 3]| -> [f64; 3] { std::array::from_fn(|k| a[k] - b[k]) };
    let distance = (0..3)
        .map(|i| {
            let (a, b) = (tri[i].map(f64::from), tri[(i + 1) % 3].map(f64::from));
            let e = sub(b, a);
            let w = sub(a, o);
            // The edge point a + s e nearest the line: minimize |w + s e - t d| over t, then s in [0, 1].
            let (dd, de, ee, dw, ew) = (dot(d, d), dot(d, e), dot(e, e), dot(d, w), dot(e, w));
            let denominator = dd * ee - de * de;
            let s = if denominator > 0.0 { ((de * dw - dd * ew) / denominator).clamp(0.0, 1.0) } else { 0.0 };
            let p: [f64; 3] = std::array::from_fn(|k| w[k] + s * e[k]);
            let t = dot(p, d) / dd;
            let r: [f64; 3] = std::array::from_fn(|k| p[k] - t * d[k]);
            dot(r, r).sqrt()
        })
        .fold(f64::INFINITY, f64::min);
    let magnitude = dot(o, o).sqrt() + scale;
    distance / (FALSE_HIT_TOLERANCE * magnitude)
}

/// The teapot fixture (a real scene with shared vertices) with rays aimed at its vertices and edges from around
/// it, and random rays.
fn teapot_case() -> crate::stress::Case {
    use rand::RngExt;
    let soup = bvhc::import::import(&crate::convert::teapot(), &Default::default()).unwrap().soup;
    let triangles: Vec<Triangle> = soup.triangles.iter().map(|t| t.map(|i| soup.positions[i as usize])).collect();
    let mut rng = crate::common::rng(3702);
    let mut rays = crate::common::random_rays(3703, 2000, 3.0);
    while rays.len() < 8000 {
        let tri = &triangles[rng.random_range(0..triangles.len())];
        let s = if rays.len().is_multiple_of(2) { 0.0 } else { rng.random_range(0.0..1.0f32) };
        let target: [f32; 3] = std::array::from_fn(|a| tri[0][a] + s * (tri[1][a] - tri[0][a]));
        let origin = crate::common::random_point(&mut rng, 6.0);
        rays.push(Ray::new(origin, std::array::from_fn(|a| target[a] - origin[a])));
    }
    crate::stress::Case {
        name: "teapot fixture, rays at its vertices and edges".into(),
        triangles,
        rays,
        must_hit: false,
    }
}

#[test]
fn a_fusing_gpu_decides_differently_only_within_rounding_of_an_edge_and_keeps_closed_meshes_closed() {
    println!("\n| case | rays | agree (t within the bound) | decided otherwise | worst edge distance / tolerance |");
    println!("|---|---|---|---|---|");
    for case in stress_cases().into_iter().chain([teapot_case()]) {
        let scale = case.triangles.iter().flatten().flatten().fold(0.0f64, |m, &c| m.max(f64::from(c.abs())));
        let (mut agree, mut otherwise, mut worst) = (0, 0, 0.0f64);
        for (i, ray) in case.rays.iter().enumerate() {
            let cpu = brute_force_closest(&case.triangles, ray);
            let gpu = fused_gpu_closest(&case.triangles, ray, i as u32);
            if case.must_hit {
                assert!(gpu.is_some(), "{}: ray {i} from inside a closed mesh escaped: {ray:?}", case.name);
            }
            match (cpu, gpu) {
                (None, None) => agree += 1,
                (Some(c), Some(g)) if (f64::from(g.0) - f64::from(c.0)).abs() <= t_bound(ray, c.0) => agree += 1,
                _ => {
                    // The nearer of the two answers is the triangle one test hit and the other passed.
                    let nearer = match (cpu, gpu) {
                        (Some(c), Some(g)) => {
                            if g.0 < c.0 {
                                g.1
                            } else {
                                c.1
                            }
                        }
                        (Some(c), None) => c.1,
                        (None, Some(g)) => g.1,
                        (None, None) => unreachable!(),
                    };
                    let distance = edge_distance_over_tolerance(&case.triangles[nearer], ray, scale);
                    assert!(distance <= 1.0, "{}: ray {i} decided {distance} tolerances from an edge", case.name);
                    worst = worst.max(distance);
                    otherwise += 1;
                }
            }
        }
        println!("| {} | {} | {agree} | {otherwise} | {worst:.2} |", case.name, case.rays.len());
    }
}
