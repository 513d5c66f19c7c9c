//! The order a batch of point queries is answered in: along a Morton curve over the points' own box, so that
//! consecutive queries walk the same nodes while they are in the caches, and each query starts from a bound
//! the previous one gives (its triangle's distance from the next point). The answers go back to the caller's
//! order and do not depend on it: a query's answer is defined without reference to any other
//! (`format-spec/point-queries.md`), so the order only changes how fast it is found.
//!
//! On 200,000 points (AMD EPYC Zen 4, one thread) the curve order alone measured 1.6-2.4x faster than the
//! same points in random order on the kitchen, the engine and the dragon; the predecessor's bound then
//! 1.05-1.35x more (100,000 points, three alternating runs, the Buddha least, the kitchen most), and gathering
//! the points in order before the queries up to 1.25x more (200,000 points, three alternating runs: the
//! kitchen's uniform points 0.58-0.73 to 0.49-0.50 us a point, the beetle's near ones 0.64-0.76 to 0.49-0.65).

use crate::parallel::Workers;

/// Points a thread takes at least in a batch (fewer stay on the calling thread).
const MIN_POINTS_A_THREAD: usize = 256;

/// Cells of the curve along each axis (`2^10`: 30 bits of key beside a 32-bit index in one `u64`).
const CELL_BITS: u32 = 10;

/// `x`'s low 10 bits spread to every third bit (bit `k` to bit `3k`).
fn spread(x: u64) -> u64 {
    let mut x = x & 0x3ff;
    x = (x | (x << 16)) & 0x0300_00ff;
    x = (x | (x << 8)) & 0x0300_f00f;
    x = (x | (x << 4)) & 0x030c_30c3;
    (x | (x << 2)) & 0x0924_9249
}

/// The indices of `points` in Morton order (ties, and points that are not finite, by index); `None` when there
/// are more than `u32::MAX` of them or memory for the order cannot be had.
pub(crate) fn morton_order(points: &[[f32; 3]]) -> Option<Vec<u32>> {
    u32::try_from(points.len()).ok()?;
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for point in points.iter().filter(|p| p.iter().all(|c| c.is_finite())) {
        for a in 0..3 {
            lo[a] = lo[a].min(point[a]);
            hi[a] = hi[a].max(point[a]);
        }
    }
    let cells = f64::from((1u32 << CELL_BITS) - 1);
    let scale: [f64; 3] = std::array::from_fn(|a| {
        let size = f64::from(hi[a]) - f64::from(lo[a]);
        if size > 0.0 { cells / size } else { 0.0 }
    });
    let mut keys: Vec<u64> = Vec::new();
    keys.try_reserve_exact(points.len()).ok()?;
    keys.extend(points.iter().enumerate().map(|(index, point)| {
        let cell = |a: usize| {
            let x = (f64::from(point[a]) - f64::from(lo[a])) * scale[a];
            if x.is_finite() { x.clamp(0.0, cells) as u64 } else { 0 }
        };
        let key = spread(cell(0)) | spread(cell(1)) << 1 | spread(cell(2)) << 2;
        key << 32 | index as u64
    }));
    let mut spare: Vec<u64> = Vec::new();
    spare.try_reserve_exact(points.len()).ok()?;
    spare.resize(points.len(), 0);
    radix_sort_keys(&mut keys, &mut spare);
    let mut order: Vec<u32> = Vec::new();
    order.try_reserve_exact(points.len()).ok()?;
    order.extend(keys.iter().map(|&key| key as u32));
    Some(order)
}

/// Sorts `keys` (a 30-bit Morton key above a 32-bit index, indices in increasing order) by the key, stably, so
/// ties stay in index order: three passes of a least-significant-digit radix sort over the key's 10-bit digits,
/// through `spare` (as long as `keys`): linear time, where a comparison sort's grows with `n log n`.
fn radix_sort_keys(keys: &mut [u64], spare: &mut [u64]) {
    const DIGIT: u32 = CELL_BITS;
    let (mut from, mut to) = (keys, spare);
    for pass in 0..3 {
        let shift = 32 + DIGIT * pass;
        let digit = |key: u64| (key >> shift) as usize & ((1 << DIGIT) - 1);
        let mut starts = [0usize; 1 << DIGIT];
        for &key in from.iter() {
            starts[digit(key)] += 1;
        }
        let mut sum = 0;
        for start in starts.iter_mut() {
            (*start, sum) = (sum, sum + *start);
        }
        for &key in from.iter() {
            let slot = &mut starts[digit(key)];
            to[*slot] = key;
            *slot += 1;
        }
        std::mem::swap(&mut from, &mut to);
    }
    // After an odd number of passes the sorted keys are in the spare buffer.
    to.copy_from_slice(from);
}

/// `answer(point, state)` of each of `points` into `out` (the same length), on up to `threads` threads (0 counts
/// as 1), no thread taking fewer than [`MIN_POINTS_A_THREAD`] points: the points answered in Morton order
/// ([`morton_order`]), each run of consecutive points on one thread sharing one `state` (started
/// `S::default()`), the answers put back in the caller's order. Where memory for the order cannot be had, in the
/// caller's order. `answer`'s result must not depend on `state` (only how fast it is found), so the answers are
/// the same on any thread count.
pub(crate) fn answer_in_order<T: Copy + Send, S: Default>(
    points: &[[f32; 3]],
    out: &mut [T],
    threads: usize,
    answer: impl Fn([f32; 3], &mut S) -> T + Sync,
) {
    let workers = Workers::new(threads);
    // The points gathered in order first (a tight loop whose cache misses overlap, where reading each at the
    // start of its query would wait for it), the answers written in order and scattered at the end.
    let in_order = morton_order(points).and_then(|order| {
        let mut answers: Vec<T> = Vec::new();
        answers.try_reserve_exact(out.len()).ok()?;
        answers.extend_from_slice(out);
        let mut gathered: Vec<[f32; 3]> = Vec::new();
        gathered.try_reserve_exact(points.len()).ok()?;
        gathered.extend(order.iter().map(|&index| points[index as usize]));
        Some((order, gathered, answers))
    });
    let Some((order, gathered, mut answers)) = in_order else {
        workers.for_chunks(out, MIN_POINTS_A_THREAD, |first, chunk| {
            let mut state = S::default();
            for (slot, &point) in chunk.iter_mut().zip(&points[first..]) {
                *slot = answer(point, &mut state);
            }
        });
        return;
    };
    workers.for_chunks(&mut answers, MIN_POINTS_A_THREAD, |first, chunk| {
        let mut state = S::default();
        for (slot, &point) in chunk.iter_mut().zip(&gathered[first..]) {
            *slot = answer(point, &mut state);
        }
    });
    for (&index, &value) in order.iter().zip(&answers) {
        out[index as usize] = value;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_interleaves_ten_bits() {
        assert_eq!(spread(0b1), 0b1);
        assert_eq!(spread(0b11), 0b1001);
        assert_eq!(spread(0x3ff), 0x0924_9249);
        assert_eq!(spread(0x7ff), 0x0924_9249, "bits above the tenth are dropped");
    }

    #[test]
    fn the_order_is_a_permutation_along_the_curve() {
        let mut points = Vec::new();
        let mut s = 12345u32;
        for _ in 0..1000 {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            points.push([(s >> 8) as f32, (s >> 4 & 0xff) as f32, -((s & 0xf) as f32)]);
        }
        points.push([f32::NAN, 0.0, 0.0]);
        points.push([0.0, f32::INFINITY, 0.0]);
        let order = morton_order(&points).unwrap();
        let mut seen = vec![false; points.len()];
        for &k in &order {
            assert!(!std::mem::replace(&mut seen[k as usize], true), "{k} twice");
        }
        assert!(seen.iter().all(|&s| s));
        // The two corners of the points' box come first and last.
        let corner = points.len();
        points.push([0.0, 0.0, -15.0]);
        points.push([(u32::MAX >> 8) as f32, 255.0, 0.0]);
        let order = morton_order(&points).unwrap();
        assert_eq!(order.last(), Some(&(corner as u32 + 1)));
        assert!(order[..3].contains(&(corner as u32)));
    }

    #[test]
    fn the_radix_sort_equals_a_comparison_sort() {
        let mut s = 99u64;
        let mut keys: Vec<u64> = (0..5000u64)
            .map(|index| {
                s = s.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
                (s >> 34) << 32 | index
            })
            .collect();
        keys.extend((5000..5100u64).map(|index| 7 << 32 | index)); // ties, in index order
        let mut expected = keys.clone();
        expected.sort_unstable();
        let mut spare = vec![0; keys.len()];
        radix_sort_keys(&mut keys, &mut spare);
        assert_eq!(keys, expected);
    }

    #[test]
    fn answers_return_to_the_callers_order_on_any_thread_count() {
        let points: Vec<[f32; 3]> = (0..5000).map(|k| [((k * 7919) % 5000) as f32, (k % 13) as f32, 0.0]).collect();
        for threads in [0, 1, 2, 3] {
            let mut out = vec![0f32; points.len()];
            answer_in_order(&points, &mut out, threads, |p, calls: &mut usize| {
                *calls += 1;
                p[0] + p[1]
            });
            assert!(out.iter().zip(&points).all(|(&o, p)| o == p[0] + p[1]), "{threads} threads");
        }
    }
}
