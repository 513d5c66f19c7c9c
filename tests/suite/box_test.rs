//! The robust slab test (Ize 2013, with the exit padding folded into the ray's reciprocals) against exact
//! arithmetic: a box that the exact ray meets is never missed, by the binary kernel's `enter_box` nor by the
//! wide kernel's slot test on any path. The boxes are the tightest f32 boxes around a point of the exact ray,
//! from origins and directions of many magnitudes, with zero, negative-zero and tiny direction components.

use bvhc::loader::{
    Ray, TraversalStats, WideTracer, format::PackedNode, format::PackedTriangle, format::TrianglePacket4,
    format::WideNode8, ray::PreparedRay, wide::WideBvh,
};
use bvhc_loader::Trace;
use rand::RngExt;

use crate::common::{kernel_paths, rng};

/// The largest f32 not above `x` and the smallest not below it, after widening `x` by a few f64 ulps (which
/// covers the rounding of the f64 computation of the point).
fn f32_bracket(x: f64) -> (f32, f32) {
    let slack = x.abs() * 2f64.powi(-50) + f64::MIN_POSITIVE;
    let (low, high) = (x - slack, x + slack);
    let down = low as f32;
    let down = if f64::from(down) > low { down.next_down() } else { down };
    let up = high as f32;
    let up = if f64::from(up) < high { up.next_up() } else { up };
    (down, up)
}

/// A wide tree of one node whose only slot is a leaf with `box_min..box_max`, holding one triangle collapsed to
/// `point`: a ray that enters the slot tests the packet, which the counter sees.
fn one_slot_tree(box_min: [f32; 3], box_max: [f32; 3], point: [f32; 3]) -> WideBvh {
    let triangle = PackedTriangle { vertices: [point; 3] };
    let mut node = WideNode8::EMPTY;
    for axis in 0..3 {
        node.min[axis][0] = box_min[axis];
        node.max[axis][0] = box_max[axis];
    }
    node.child[0] = WideNode8::leaf(0, 1).expect("one packet");
    let packets = vec![TrianglePacket4::new(&[(0, triangle)])];
    WideBvh::new(vec![node], packets, (box_min, box_max), &[triangle]).expect("a valid one-slot tree")
}

#[test]
fn a_box_the_exact_ray_meets_is_never_missed() {
    let mut rng = rng(2013);
    let paths = kernel_paths();
    let mut cases = 0;
    while cases < 20_000 {
        let scale = 10f64.powf(rng.random_range(-3.0..5.0));
        let origin: [f32; 3] = std::array::from_fn(|_| (rng.random_range(-1.0..1.0) * scale) as f32);
        let direction: [f32; 3] = std::array::from_fn(|_| match rng.random_range(0..8) {
            0 => 0.0,
            1 => -0.0,
            _ => rng.random_range(-1.0f32..1.0) * 10f32.powf(rng.random_range(-6.0..1.0)),
        });
        if direction.iter().all(|&c| c == 0.0) {
            continue;
        }
        cases += 1;
        let t: f64 = rng.random_range(0.0..1.0) * 10f64.powf(rng.random_range(-4.0..4.0));
        let point: [f64; 3] = std::array::from_fn(|a| f64::from(origin[a]) + t * f64::from(direction[a]));
        let brackets: [(f32, f32); 3] = std::array::from_fn(|a| f32_bracket(point[a]));
        let (box_min, box_max) = (brackets.map(|b| b.0), brackets.map(|b| b.1));
        let ray = Ray::new(origin, direction);
        let node = PackedNode { min: box_min, max: box_max, index: 0, count: 0 };
        assert!(
            PreparedRay::new(&ray).enter_box(&node, f32::INFINITY).is_some(),
            "binary box test missed {box_min:?}..{box_max:?} met at t = {t} by {ray:?}"
        );
        let bvh = one_slot_tree(box_min, box_max, point.map(|c| c as f32));
        for &path in &paths {
            let mut stats = TraversalStats::default();
            WideTracer::new(&bvh, None, path).closest_hit_counted(&ray, &mut stats);
            assert_eq!(
                stats.triangle_tests, 1,
                "{path:?} slot test missed {box_min:?}..{box_max:?} met at t = {t} by {ray:?}"
            );
        }
    }
}
