//! The sampled cost of a wide tree: the work a wide kernel does for a set of rays, counted by tracing them
//! through the [`WideTree`] before it is packed. A conversion that compares candidate trees with ray tuning
//! on judges them by this cost on held-out rays instead of by their surface-area cost, which predicts ray
//! speed poorly (Aila, Karras, Laine, "On Quality Metrics of Bounding Volume Hierarchies", HPG 2013).
//!
//! The walk is the wide kernels' closest-hit walk: a node visit tests every child box; the children entered are
//! taken nearest first (leaves among them), and a child whose entry lies beyond the closest hit found so far is
//! skipped. A leaf costs its packets (`ceil(count / packet_width)`), as [`WideCosts::leaf`] prices it.

use bvhc_loader::{Ray, format::PackedTriangle, ray::PreparedRay};
use rayon::prelude::*;

use super::trace::packed;
use crate::layout::{WideChild, WideCosts, WideTree};

/// The wide kernel's work for a set of rays ([`sampled_wide_work`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WideWork {
    /// Rays traced.
    pub rays: u64,
    /// Wide nodes visited (every child box of a visited node is tested).
    pub node_visits: u64,
    /// Packets of leaf triangles tested.
    pub packet_tests: u64,
}

impl WideWork {
    /// The mean cost of a ray under `costs`: `node_visit * node_visits + packet_test * packet_tests` over the
    /// rays (0 without rays): the quantity the collapse's dynamic program estimates from areas or weights.
    pub fn cost_per_ray(&self, costs: &WideCosts) -> f64 {
        if self.rays == 0 {
            return 0.0;
        }
        (costs.node_visit * self.node_visits as f64 + costs.packet_test * self.packet_tests as f64) / self.rays as f64
    }

    fn add(self, other: WideWork) -> WideWork {
        WideWork {
            rays: self.rays + other.rays,
            node_visits: self.node_visits + other.node_visits,
            packet_tests: self.packet_tests + other.packet_tests,
        }
    }
}

/// Rays traced a chunk at a time; the chunks' counts are integer sums, so the total is the same for any thread
/// count.
const CHUNK: usize = 4096;

/// The work of tracing `rays` (closest hit) through `wide` over `triangles` (the soup its `triangle_order`
/// indexes), with `packet_width` triangles a packet.
pub fn sampled_wide_work(wide: &WideTree, triangles: &[[[f32; 3]; 3]], rays: &[Ray], packet_width: usize) -> WideWork {
    let packet_width = packet_width.max(1) as u64;
    rays.par_chunks(CHUNK)
        .map(|chunk| {
            let mut stack = Vec::with_capacity(64);
            let mut work = WideWork { rays: chunk.len() as u64, ..WideWork::default() };
            for ray in chunk {
                trace_wide(wide, triangles, ray, packet_width, &mut stack, &mut work);
            }
            work
        })
        .reduce(WideWork::default, WideWork::add)
}

/// One closest-hit walk, its work added to `work`; returns the closest hit's distance.
fn trace_wide(
    wide: &WideTree,
    triangles: &[[[f32; 3]; 3]],
    ray: &Ray,
    packet_width: u64,
    stack: &mut Vec<(WideChild, f32)>,
    work: &mut WideWork,
) -> Option<f32> {
    if wide.nodes.is_empty() {
        return None;
    }
    let prepared = PreparedRay::new(ray);
    let mut t_max = ray.t_max;
    let mut closest = None;
    stack.clear();
    if let Some(t) = prepared.enter_box(&packed(&wide.root_box), t_max) {
        stack.push((WideChild::Node(0), t));
    }
    let mut entered: Vec<(WideChild, f32)> = Vec::with_capacity(wide.width);
    while let Some((child, t_entry)) = stack.pop() {
        if t_entry > t_max {
            continue;
        }
        match child {
            WideChild::Node(n) => {
                work.node_visits += 1;
                entered.clear();
                for (aabb, child) in &wide.nodes[n as usize].children {
                    if let Some(t) = prepared.enter_box(&packed(aabb), t_max) {
                        entered.push((*child, t));
                    }
                }
                // Farthest pushed first, so the nearest is taken next (ties in slot order).
                entered.sort_by(|a, b| b.1.total_cmp(&a.1));
                stack.extend_from_slice(&entered);
            }
            WideChild::Leaf { first, count } => {
                work.packet_tests += u64::from(count).div_ceil(packet_width);
                let range = first as usize..(first + count) as usize;
                for &triangle in &wide.triangle_order[range] {
                    let triangle = PackedTriangle { vertices: triangles[triangle as usize] };
                    if let Some(hit) = prepared.intersect_triangle(&triangle, t_max) {
                        t_max = hit.t;
                        closest = Some(hit.t);
                    }
                }
            }
        }
    }
    closest
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builders::build_binned_sah;
    use crate::layout::collapse;
    use crate::optimize::OptTree;
    use crate::sampling::training_rays;

    fn grid(n: usize) -> Vec<[[f32; 3]; 3]> {
        let mut triangles = Vec::new();
        for i in 0..n {
            for j in 0..n {
                let (x, y, z) = (i as f32, j as f32, ((i * 7 + j * 3) % 5) as f32);
                triangles.push([[x, y, z], [x + 0.9, y, z], [x, y + 0.9, z + 0.5]]);
            }
        }
        triangles
    }

    #[test]
    fn closest_hits_match_brute_force_and_work_is_counted() {
        let triangles = grid(24);
        let tree = OptTree::from_build_tree(&build_binned_sah(&triangles, 1), &triangles);
        let costs = WideCosts { width: 8, packet_width: 4, max_leaf_size: 8, node_visit: 1.0, packet_test: 1.0 };
        let wide = collapse(&tree, &costs);
        let rays = training_rays(&tree, &triangles, 3000, 7);
        let mut stack = Vec::new();
        let mut hits = 0;
        for ray in &rays {
            let mut work = WideWork::default();
            let walked = trace_wide(&wide, &triangles, ray, 4, &mut stack, &mut work);
            let prepared = PreparedRay::new(ray);
            let brute = triangles
                .iter()
                .filter_map(|t| prepared.intersect_triangle(&PackedTriangle { vertices: *t }, ray.t_max))
                .map(|h| h.t)
                .min_by(f32::total_cmp);
            assert_eq!(walked, brute, "closest hit of {ray:?}");
            hits += usize::from(brute.is_some());
            if brute.is_some() {
                assert!(work.node_visits >= 1 && work.packet_tests >= 1, "a hit is found in a visited leaf");
            }
        }
        assert!(hits > 500, "the rays hit the grid ({hits})");
        let work = sampled_wide_work(&wide, &triangles, &rays, 4);
        assert_eq!(work.rays, rays.len() as u64);
        let one_thread = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("a pool");
        assert_eq!(one_thread.install(|| sampled_wide_work(&wide, &triangles, &rays, 4)), work);
        let expected = (work.node_visits + work.packet_tests) as f64 / work.rays as f64;
        assert_eq!(work.cost_per_ray(&costs), expected);
        assert_eq!(WideWork::default().cost_per_ray(&costs), 0.0);
    }
}
