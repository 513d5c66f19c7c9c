//! The peer benchmark's coherent table: the camera's primary rays through bvhc's single-ray call, its 8-ray packets
//! (`closest_hits_coherent`) and Embree's packet calls, the rays in rows (8 neighbouring pixels of a row a packet)
//! and in 4x2 tiles (8 consecutive rays a block of 4 pixels by 2 rows), closest hits.

use std::cell::RefCell;
use std::time::Instant;

use bvhc::loader::{BvhView, Hit, Ray, Trace};

use super::{Answers, disagreements, median};
use crate::embree::{Embree, FlushToZero};

/// The order in which a `width` x `height` camera's row-major rays are traced in 4x2 tiles: indices into the rays,
/// tile by tile (row-major tiles, row-major pixels inside a tile), the tiles at the right and bottom edges cut to
/// the image.
pub fn tile_order((width, height): (usize, usize)) -> Vec<usize> {
    let mut order = Vec::with_capacity(width * height);
    for top in (0..height).step_by(2) {
        for left in (0..width).step_by(4) {
            for y in top..(top + 2).min(height) {
                order.extend((left..(left + 4).min(width)).map(|x| y * width + x));
            }
        }
    }
    order
}

/// The coherent table's row of one scene for `rays`, the row-major rays of a `camera` (width, height); asserts that
/// every contender finds the same hits (`t` within 1e-4, or a miss) on all but a few rays. The tiled passes take
/// the rays laid out in tile order once (as a renderer would make them) and put each result back in its pixel's
/// place inside the timed pass.
pub fn coherent_row(
    name: &str,
    view: &BvhView<'_>,
    triangles: &[[[f32; 3]; 3]],
    (rays, camera): (&[Ray], (usize, usize)),
    rounds: usize,
) -> String {
    let tracer = view.tracer();
    let avx2 = Embree::with_isa(triangles, false, Some("avx2"));
    let native = Embree::with_isa(triangles, false, None);
    let order = tile_order(camera);
    let mut pixels = order.clone();
    pixels.sort_unstable();
    assert!(pixels.iter().copied().eq(0..rays.len()), "{name}: the tiles cover every pixel of the camera once");
    let tiled: Vec<Ray> = order.iter().map(|&i| rays[i]).collect();
    let mut hits = vec![None; rays.len()];
    let mut ts = vec![None; rays.len()];
    // The hit records of the packet calls, allocated once as a renderer would (a fresh allocation a pass timed its
    // page faults, a third of the pass on this VM).
    let found: RefCell<Vec<Option<Hit>>> = RefCell::new(vec![None; rays.len()]);
    let tiled_ts: RefCell<Vec<Option<f32>>> = RefCell::new(vec![None; rays.len()]);
    type Pass<'p> = Box<dyn Fn(&mut [Option<f32>]) + 'p>;
    let passes: [(bool, Pass<'_>); 7] = [
        (
            false,
            Box::new(|out: &mut [Option<f32>]| {
                for (slot, ray) in out.iter_mut().zip(rays) {
                    *slot = tracer.closest_hit(ray).map(|h| h.t);
                }
            }),
        ),
        (
            false,
            Box::new(|out: &mut [Option<f32>]| {
                let mut found = found.borrow_mut();
                tracer.closest_hits_coherent(rays, &mut found);
                for (slot, hit) in out.iter_mut().zip(found.iter()) {
                    *slot = hit.map(|h| h.t);
                }
            }),
        ),
        (
            false,
            Box::new(|out: &mut [Option<f32>]| {
                let mut found = found.borrow_mut();
                tracer.closest_hits_coherent(&tiled, &mut found);
                for (&pixel, hit) in order.iter().zip(found.iter()) {
                    out[pixel] = hit.map(|h| h.t);
                }
            }),
        ),
        (
            true,
            Box::new(|out: &mut [Option<f32>]| {
                rays.chunks(8).zip(out.chunks_mut(8)).for_each(|(r, o)| avx2.closest8_into(r, o))
            }),
        ),
        (
            true,
            Box::new(|out: &mut [Option<f32>]| {
                let mut tiled_ts = tiled_ts.borrow_mut();
                tiled.chunks(8).zip(tiled_ts.chunks_mut(8)).for_each(|(r, o)| avx2.closest8_into(r, o));
                for (&pixel, &t) in order.iter().zip(tiled_ts.iter()) {
                    out[pixel] = t;
                }
            }),
        ),
        (
            true,
            Box::new(|out: &mut [Option<f32>]| {
                rays.chunks(16).zip(out.chunks_mut(16)).for_each(|(r, o)| avx2.closest16_into(r, o))
            }),
        ),
        (
            true,
            Box::new(|out: &mut [Option<f32>]| {
                rays.chunks(16).zip(out.chunks_mut(16)).for_each(|(r, o)| native.closest16_into(r, o))
            }),
        ),
    ];
    let mut samples = vec![Vec::new(); passes.len()];
    let mut unlike = 0;
    for round in 0..rounds {
        for (p, (is_embree, pass)) in passes.iter().enumerate() {
            let out = if p == 0 { &mut hits } else { &mut ts };
            let start = Instant::now();
            {
                let _ftz = is_embree.then(FlushToZero::set);
                pass(out);
            }
            samples[p].push(rays.len() as f64 / start.elapsed().as_secs_f64() / 1e6);
            if round == 0 && p > 0 {
                unlike = unlike.max(disagreements(&Answers::Closest(hits.clone()), &Answers::Closest(ts.clone())));
            }
        }
    }
    assert!(unlike * 1000 <= rays.len(), "{name}: {unlike} coherent answers unlike single rays");
    let speeds: Vec<f64> = samples.into_iter().map(median).collect();
    let best_embree = [speeds[3], speeds[4], speeds[5], speeds[6]].into_iter().fold(0.0, f64::max);
    format!(
        "| {name} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |",
        speeds[0],
        speeds[1],
        speeds[2],
        speeds[3],
        speeds[4],
        speeds[5],
        speeds[6],
        speeds[1] / best_embree,
        speeds[2] / best_embree
    )
}
