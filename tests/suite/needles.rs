//! Accuracy at needles and slivers (`format-spec/bvh-1.md` 11.1, "Accuracy"), against exact arithmetic.
//!
//! Scenes of needles and slivers whose normal is `1e-3` to `1e-9` of their longest edge squared, mixed with
//! ordinary triangles and with plates crossing them a hair's breadth away (near ties), at several scales and
//! offsets; random rays, rays aimed at points of the thin triangles, and rays grazing along them. Every kernel
//! (binary, wide on every path, batches, coherent packets) is checked against an independent reading of 11.1
//! (`exact_reference.rs`: the f32 steps from the spec, the exact values in big integers):
//! * the closest hit is the reference's, bit for bit (`t`, and a triangle the reference hits at that `t`, with
//!   its `u`, `v`); any-hit agrees;
//! * an ill-conditioned hit's `t`, `u`, `v` are the exact values rounded to nearest;
//! * every other hit's `t` is within the proven bound `T_BOUND (|t*| + depth)` of the exact `t*`, and its
//!   `u`, `v` lie on the triangle (`u, v >= 0`, `u + v <= 1 + 2^-21`);
//! * no triangle the procedure hits is nearer, exactly, than the returned one by more than both bounds.
//!
//! The table (`cargo test --release --test suite needles -- --nocapture`) is kept in `docs/stability.md`.

use bvhc::loader::{Hit, Ray};
use bvhc_loader::Trace;
use rand::RngExt;
use rand_pcg::Pcg64Mcg;

use crate::common::{Triangle, every_kernel, rng, write_wide_file};
use crate::exact_reference::{T_BOUND, exact, reference_hit};

/// A generated scene: triangles, whether each is a needle or sliver, and the rays.
pub(crate) struct Scene {
    pub name: String,
    pub triangles: Vec<Triangle>,
    pub thin: Vec<bool>,
    pub rays: Vec<Ray>,
}

/// The scenes: seeds, scales and offsets.
pub(crate) fn needle_scenes() -> Vec<Scene> {
    [(1, 1.0, 0.0), (2, 1e-3, 0.0), (3, 1e3, 0.0), (4, 1.0, 1e3), (5, 1e2, 1e5)]
        .into_iter()
        .map(|(seed, scale, offset)| scene(seed, scale, offset))
        .collect()
}

fn unit(r: &mut Pcg64Mcg) -> [f64; 3] {
    loop {
        let v: [f64; 3] = std::array::from_fn(|_| r.random_range(-1.0..1.0));
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if l > 0.2 && l <= 1.0 {
            return v.map(|c| c / l);
        }
    }
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn normalized(a: [f64; 3]) -> [f64; 3] {
    let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    a.map(|c| c / l)
}

fn round(p: [f64; 3]) -> [f32; 3] {
    p.map(|c| c as f32)
}

/// Needles and slivers of thinness `1e-3 .. 1e-9` (normal over longest edge squared), ordinary triangles, and
/// plates through points of some thin triangles shifted by `1e-7` of their length; at `scale`, moved by
/// `offset`. The thinnest are made near the coordinate origin, where f32 resolves them.
fn scene(seed: u64, scale: f64, offset: f64) -> Scene {
    let mut r = rng(seed);
    let mut triangles = Vec::new();
    let mut thin = Vec::new();
    let mut targets: Vec<([f64; 3], [f64; 3])> = Vec::new(); // (a point of a thin triangle, its long axis)
    for i in 0..240 {
        let thinness = 10f64.powi(-3 - (i % 7));
        let axis = unit(&mut r);
        let side = normalized(cross(axis, unit(&mut r)));
        let length = scale * r.random_range(0.5..2.0);
        // The thinnest near the coordinate origin (offset aside), the others anywhere in the box.
        let start: [f64; 3] = if i % 7 >= 4 {
            std::array::from_fn(|a| offset + axis[a] * 1e-4 * length)
        } else {
            std::array::from_fn(|_| offset + scale * r.random_range(-3.0..3.0))
        };
        let far: [f64; 3] = std::array::from_fn(|a| start[a] + axis[a] * length);
        let third: [f64; 3] = if i % 2 == 0 {
            // A needle: the third vertex close to the first, off the axis by thinness * length.
            let along = 1e-4 * length;
            std::array::from_fn(|a| start[a] + axis[a] * along + side[a] * thinness * length)
        } else {
            // A sliver: the third vertex near the middle of the long edge.
            std::array::from_fn(|a| start[a] + axis[a] * length * 0.5 + side[a] * thinness * length)
        };
        let triangle = [round(start), round(far), round(third)];
        targets.push((std::array::from_fn(|a| (start[a] + far[a] + third[a]) / 3.0), axis));
        triangles.push(triangle);
        thin.push(true);
        if i % 5 == 0 {
            // A plate crossing the thin triangle's centroid, shifted by 1e-7 of its length.
            let (center, _) = targets[targets.len() - 1];
            let (u, v) = (unit(&mut r), unit(&mut r));
            let shift = unit(&mut r);
            let c: [f64; 3] = std::array::from_fn(|a| center[a] + shift[a] * 1e-7 * length);
            let corner = |s: f64, t: f64| round(std::array::from_fn(|a| c[a] + (u[a] * s + v[a] * t) * length));
            triangles.push([corner(-1.0, -1.0), corner(2.0, -0.5), corner(-0.5, 2.0)]);
            thin.push(false);
        }
    }
    for _ in 0..120 {
        let c: [f64; 3] = std::array::from_fn(|_| offset + scale * r.random_range(-3.0..3.0));
        let p = |r: &mut Pcg64Mcg| round(std::array::from_fn(|a| c[a] + scale * r.random_range(-0.7..0.7)));
        triangles.push([p(&mut r), p(&mut r), p(&mut r)]);
        thin.push(false);
    }
    let mut rays = Vec::new();
    let around = |r: &mut Pcg64Mcg| -> [f64; 3] { std::array::from_fn(|_| offset + scale * r.random_range(-6.0..6.0)) };
    for _ in 0..1500 {
        let (o, t) = (around(&mut r), around(&mut r));
        rays.push(Ray::new(round(o), round(std::array::from_fn(|a| t[a] - o[a]))));
    }
    for (k, &(target, axis)) in targets.iter().enumerate() {
        for j in 0..6 {
            let o = around(&mut r);
            let d: [f64; 3] = if j < 3 {
                std::array::from_fn(|a| target[a] - o[a]) // aimed
            } else {
                // Grazing: along the long axis, tilted by 1e-2 .. 1e-6 of a radian, through the target.
                let tilt = unit(&mut r).map(|c| c * 10f64.powi(-2 - ((k + j) % 5) as i32));
                std::array::from_fn(|a| axis[a] + tilt[a])
            };
            let origin: [f64; 3] = if j < 3 { o } else { std::array::from_fn(|a| target[a] - d[a] * scale * 4.0) };
            rays.push(Ray::new(round(origin), round(d)));
        }
    }
    Scene { name: format!("scale {scale:e}, offset {offset:e}"), triangles, thin, rays }
}

#[derive(Default)]
struct Tally {
    rays: usize,
    hits: usize,
    ill_hits: usize,
    thin_hits: usize,
    candidates: usize,
    ill_candidates: usize,
    worst_ratio: f64,
}

/// Every kernel's hits against the reference, with the checks of the module documentation.
fn check(scene: &Scene) -> Tally {
    let file = write_wide_file(&scene.triangles, 4);
    let view = file.view();
    let ids = view.triangle_ids().expect("ids");
    let kernels = every_kernel(&view);
    assert!(kernels.len() >= 2, "the binary kernel and at least the portable wide path");
    let mut tally = Tally::default();
    let mut expected_hits: Vec<Option<(f32, Vec<usize>)>> = Vec::new();
    for ray in &scene.rays {
        tally.rays += 1;
        // The reference over every triangle: each candidate's hit, and its exact t* and bound.
        let mut best: Option<f32> = None;
        let mut candidates = Vec::new();
        for (i, triangle) in scene.triangles.iter().enumerate() {
            let Some(hit) = reference_hit(ray, triangle) else { continue };
            tally.candidates += 1;
            tally.ill_candidates += usize::from(hit.ill_conditioned);
            let exact = exact(ray, triangle);
            if let Some(exact) = exact {
                if hit.ill_conditioned {
                    assert_eq!(
                        [hit.t, hit.u, hit.v].map(f32::to_bits),
                        exact.rounded.map(f32::to_bits),
                        "{}: an ill-conditioned hit takes the exact values; ray {ray:?}, triangle {i}",
                        scene.name
                    );
                } else {
                    let bound = T_BOUND * (exact.t.abs() + exact.depth);
                    let error = (f64::from(hit.t) - exact.t).abs();
                    tally.worst_ratio = tally.worst_ratio.max(error / (exact.t.abs() + exact.depth) * 16_777_216.0);
                    assert!(
                        error <= bound,
                        "{}: t {} vs exact {}, bound {bound:e}; ray {ray:?}",
                        scene.name,
                        hit.t,
                        exact.t
                    );
                    assert!(hit.u >= 0.0 && hit.v >= 0.0 && hit.u + hit.v <= 1.0 + 1.0 / 2_097_152.0, "{hit:?}");
                }
            }
            best = Some(best.map_or(hit.t, |b: f32| b.min(hit.t)));
            candidates.push((i, hit, exact));
        }
        let expected = best.map(|t| {
            let at: Vec<usize> = candidates.iter().filter(|c| c.1.t == t).map(|c| c.0).collect();
            (t, at)
        });
        if let Some((t, at)) = &expected {
            tally.hits += 1;
            let winner = &candidates.iter().find(|c| c.0 == at[0]).expect("a candidate").clone();
            tally.ill_hits += usize::from(winner.1.ill_conditioned);
            tally.thin_hits += usize::from(scene.thin[winner.0]);
            // No candidate is exactly nearer than the returned hit by more than both bounds.
            if let Some(w) = winner.2 {
                let bound = |e: &crate::exact_reference::Exact, ill: bool| {
                    if ill { e.t.abs() * 6e-8 } else { T_BOUND * (e.t.abs() + e.depth) }
                };
                for (i, hit, exact) in &candidates {
                    if let Some(e) = exact
                        && e.t < w.t - bound(&w, winner.1.ill_conditioned) - bound(e, hit.ill_conditioned)
                    {
                        panic!(
                            "{}: triangle {i} is exactly nearer ({} < {}) than the hit at t {t}",
                            scene.name, e.t, w.t
                        );
                    }
                }
            }
        }
        expected_hits.push(expected);
    }
    let compare = |what: &str, ray: &Ray, expected: &Option<(f32, Vec<usize>)>, got: Option<Hit>| match (expected, got)
    {
        (None, None) => {}
        (Some((t, at)), Some(hit)) => {
            let source = ids[hit.triangle_index as usize] as usize;
            assert!(
                hit.t == *t && at.contains(&source),
                "{}: {what}: hit {hit:?} (source {source}), reference t {t} on {at:?}; ray {ray:?}",
                scene.name
            );
            let reference = reference_hit(ray, &scene.triangles[source]).expect("the reference hits it");
            assert_eq!(
                [hit.u, hit.v].map(f32::to_bits),
                [reference.u, reference.v].map(f32::to_bits),
                "{}: {what}: u, v",
                scene.name
            );
        }
        (e, g) => panic!("{}: {what}: reference {e:?}, kernel {g:?}; ray {ray:?}", scene.name),
    };
    for (k, tracer) in kernels.iter().enumerate() {
        for (ray, expected) in scene.rays.iter().zip(&expected_hits) {
            compare(&format!("kernel {k}"), ray, expected, tracer.closest_hit(ray));
            assert_eq!(tracer.any_hit(ray), expected.is_some(), "{}: kernel {k} any hit; ray {ray:?}", scene.name);
        }
        let mut batch = vec![None; scene.rays.len()];
        tracer.closest_hits(&scene.rays, &mut batch);
        let mut coherent = vec![None; scene.rays.len()];
        tracer.closest_hits_coherent(&scene.rays, &mut coherent);
        for (i, ray) in scene.rays.iter().enumerate() {
            compare(&format!("kernel {k} batch"), ray, &expected_hits[i], batch[i]);
            // Coherent packets give the single ray's hit, ties included (the lowest record, spec 11.1).
            compare(&format!("kernel {k} coherent"), ray, &expected_hits[i], coherent[i]);
            assert_eq!(
                coherent[i].map(|h| h.triangle_index),
                batch[i].map(|h| h.triangle_index),
                "{}: kernel {k} coherent; ray {ray:?}",
                scene.name
            );
        }
    }
    tally
}

#[test]
fn needles_and_slivers_hit_within_the_bound_and_ill_conditioned_hits_are_exact() {
    println!(
        "| scene | rays | hits (on thin triangles) | candidates (ill-conditioned) | ill-conditioned closest hits | worst t error / (2^-24 (t* + depth)), other hits |"
    );
    println!("|---|---|---|---|---|---|");
    let mut total = Tally::default();
    for scene in needle_scenes() {
        let tally = check(&scene);
        println!(
            "| {} | {} | {} ({}) | {} ({}) | {} | {:.1} |",
            scene.name,
            tally.rays,
            tally.hits,
            tally.thin_hits,
            tally.candidates,
            tally.ill_candidates,
            tally.ill_hits,
            tally.worst_ratio
        );
        total.ill_hits += tally.ill_hits;
        total.thin_hits += tally.thin_hits;
        total.ill_candidates += tally.ill_candidates;
    }
    assert!(
        total.thin_hits > 500 && total.ill_hits > 200 && total.ill_candidates > 1000,
        "the scenes exercise the exact path"
    );
}
