//! tinybvh 1.6.8's `BVH8_CPU` (Fuetterling, Lojewski, Pfreundt, Ebert, "Accelerated single ray tracing for wide
//! vector units", HPG 2017: 8-wide nodes, children ordered per ray octant at build time, four-triangle leaves)
//! as a second kernel peer in the peer benchmark, through the `tinybvh-rs` wrapper pinned to 0.1.0-beta.3.
//! Closest hits only: the wrapper offers no occlusion query for this layout.
//!
//! The tree is tinybvh's own: its SBVH (`BuildHQ`), leaves split to at most four triangles as the layout
//! requires, converted to its 8-wide form, built from the same triangles Embree is built from. Its triangle
//! test is not watertight (Moeller-Trumbore on precomputed edges), so it answers some rays unlike bvhc: the
//! table counts them.
//!
//! The wrapper compiles the traversal only where the benchmark is built for AVX2 and FMA (`RUSTFLAGS="-C
//! target-feature=+avx2,+fma"`, as tinybvh requires); elsewhere `Bvh8Cpu` does not exist and the benchmark
//! says so.

use bvhc::loader::Ray;
use tinybvh_rs::Intersector;

/// tinybvh's 8-wide CPU tree over a triangle soup; it owns a copy of the triangles.
pub struct Bvh8Cpu {
    bvh: tinybvh_rs::bvh8_cpu::BVH,
}

impl Bvh8Cpu {
    /// The tree over `triangles` (tinybvh's SBVH, its leaves split to four triangles, converted to 8-wide).
    pub fn new(triangles: &[[[f32; 3]; 3]]) -> Bvh8Cpu {
        let vertices: Vec<[f32; 4]> = triangles.iter().flat_map(|t| t.map(|v| [v[0], v[1], v[2], 0.0])).collect();
        let mut binary = tinybvh_rs::bvh::BVH::new_hq(vertices.as_slice().into()).expect("three vertices a triangle");
        binary.split_leaves(4);
        let wide = tinybvh_rs::mbvh::BVH::new(&binary);
        let bvh = tinybvh_rs::bvh8_cpu::BVH::new(&wide).expect("leaves of at most four triangles");
        Bvh8Cpu { bvh }
    }

    /// The `t` of `ray`'s closest hit within `[0, t_max]`, in the units of `ray.direction`. tinybvh's ray
    /// carries a unit direction and its reciprocal (its constructor's set-up, `Ray(O, D)`: `D` normalized, each
    /// reciprocal component `1 / d`, or `+-1e30` where `|d| <= 1e-12`), made here in Rust as a C++ caller's
    /// inline constructor would, rather than through the wrapper's out-of-line `Ray::new`; its distances stop
    /// at its `INFINITE` (1e30).
    #[inline]
    pub fn closest(&self, ray: &Ray) -> Option<f32> {
        let d = ray.direction;
        let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let dir = d.map(|c| c / length);
        let reciprocal = |c: f32| match c.abs() > 1e-12 {
            true => 1.0 / c,
            false => tinybvh_rs::INFINITE.copysign(if c >= 0.0 { 1.0 } else { -1.0 }),
        };
        let limit = (ray.t_max * length).min(tinybvh_rs::INFINITE);
        let mut query = tinybvh_rs::Ray {
            origin: ray.origin,
            dir,
            r_d: dir.map(reciprocal),
            hit: tinybvh_rs::Intersection { t: limit, ..Default::default() },
            padding_0: 0xFFFF, // the constructor's ray mask (every geometry), unused by this layout
            ..Default::default()
        };
        self.bvh.intersect(&mut query);
        (query.hit.t < limit).then_some(query.hit.t / length)
    }
}
