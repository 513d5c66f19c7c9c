//! The WGSL kernel that traces the GPU sections of format 1.4 ([`GPU_TRAVERSAL_WGSL`], also shipped as
//! `src/gpu.wgsl`), and the records it reads and writes, for programs that bring their own pipeline. The
//! `wgpu` feature adds `GpuTracer` (feature `wgpu`), which does the uploading and dispatching.
//!
//! Bindings, all in group 0 (the shader's header repeats them):
//!
//! | binding | type | contents |
//! |---|---|---|
//! | 0 | `storage, read` | the `gpu_nodes` section's bytes, as they lie in the file |
//! | 1 | `storage, read` | the `gpu_triangles` section's bytes, as they lie in the file |
//! | 2 | `storage, read` | the rays, [`GpuRay`] each |
//! | 3 | `storage, read_write` | the results, [`GpuHitRecord`] each, one per ray |
//! | 4 | `uniform` | [`GpuParams`] |
//! | 5 | `storage, read` | the `triangle_ids` section's bytes (with split references, hits at one `t` with equal coordinates go to the lower id, `format-spec/bvh-1.md` 11.1); one `u32` of any value for a file without ids, with [`GpuParams::tie_by_ids`] 0 |
//!
//! Entry points `closest_hit` and `any_hit`, workgroups of [`GPU_WORKGROUP_SIZE`] invocations, one ray each:
//! dispatch `ceil(ray_count / 64)` workgroups in x. The sections need no conversion: a program uploads the bytes
//! of [`crate::GpuSections`] (`bytemuck::cast_slice`) as they are. A storage binding cannot be empty, so an
//! empty scene (no GPU node) is traced as all misses without a dispatch.

use crate::format::PackedTriangle;
use crate::ray::hit::{Hit, TriangleHit};
use crate::ray::intersect::Ray;

/// The kernel's source (WGSL).
pub const GPU_TRAVERSAL_WGSL: &str = include_str!("gpu.wgsl");

/// Invocations per workgroup of both entry points.
pub const GPU_WORKGROUP_SIZE: u32 = 64;

/// [`GpuHitRecord::triangle`] of a miss.
pub const GPU_NO_HIT: u32 = u32::MAX;

/// [`GpuHitRecord::t`] of a record whose [`GpuHitRecord::triangle`] is [`GPU_NO_HIT`] when the kernel met an
/// ill-conditioned hit that could decide the ray (`format-spec/bvh-1.md` 11.1 step 5, 11.4): its exact `t`,
/// `u`, `v` need arithmetic WGSL lacks, so the ray is to be traced on the CPU
/// ([`GpuLayoutTracer::record`](crate::gpu::GpuLayoutTracer::record) gives the record the kernel would have
/// written; `GpuTracer`, feature `wgpu`, does this itself). A miss has `t = 0`.
pub const GPU_REFINE_T: f32 = -1.0;

/// A ray as the kernel reads it (binding 2), 32 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuRay {
    /// Start point.
    pub origin: [f32; 3],
    /// Smallest distance that counts as a hit.
    pub t_min: f32,
    /// Direction; not the zero vector.
    pub direction: [f32; 3],
    /// Largest distance that counts as a hit; finite (WGSL may assume no infinities).
    pub t_max: f32,
}

impl GpuRay {
    /// `ray` for the kernel: an infinite `t_max` becomes `f32::MAX` (no finite hit lies beyond it).
    pub fn new(ray: &Ray) -> GpuRay {
        GpuRay { origin: ray.origin, t_min: ray.t_min, direction: ray.direction, t_max: ray.t_max.min(f32::MAX) }
    }
}

/// One ray's result as the kernel writes it (binding 3), 16 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuHitRecord {
    /// Distance along the ray.
    pub t: f32,
    /// Weight of `v1`.
    pub u: f32,
    /// Weight of `v2`.
    pub v: f32,
    /// The hit record in the `triangles` section, or [`GPU_NO_HIT`].
    pub triangle: u32,
}

impl GpuHitRecord {
    /// A miss.
    pub const MISS: GpuHitRecord = GpuHitRecord { t: 0.0, u: 0.0, v: 0.0, triangle: GPU_NO_HIT };

    /// Whether the kernel left this ray to the CPU (see [`GPU_REFINE_T`]).
    pub fn needs_cpu(&self) -> bool {
        self.triangle == GPU_NO_HIT && self.t == GPU_REFINE_T
    }

    /// The [`Hit`] this record reports for `ray` over the file's `triangles` and `triangle_ids`: the CPU
    /// kernels' hit record (source id, geometric normal, side), or `None` for a miss, a record left to the CPU
    /// ([`GpuHitRecord::needs_cpu`]) or an index out of range.
    pub fn to_hit(&self, ray: &Ray, triangles: &[PackedTriangle], triangle_ids: Option<&[u32]>) -> Option<Hit> {
        if self.triangle == GPU_NO_HIT || self.triangle as usize >= triangles.len() {
            return None;
        }
        let hit = TriangleHit { t: self.t, u: self.u, v: self.v };
        Some(Hit::new(self.triangle, hit, triangles, triangle_ids, &ray.direction))
    }
}

/// The kernel's uniform parameters (binding 4), 16 bytes.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct GpuParams {
    /// Rays in binding 2 (and results in binding 3).
    pub ray_count: u32,
    /// 1 when the file's triangles section has `SPLIT_REFERENCES` (hits at one `t` are then ordered by their
    /// triangles' coordinates, `format-spec/bvh-1.md` 11.1), else 0.
    pub split_references: u32,
    /// The tree's part in the walk's reach (`crate::ray::reach`: 2^-11 times the largest side of the root's
    /// decoded boxes), from `GpuLayoutTracer`.
    pub reach_scale: f32,
    /// 1 with `split_references` when binding 5 holds the records' source ids (the file has `triangle_ids`): hits
    /// at one `t` with the same coordinates are then ordered by id; else 0.
    pub tie_by_ids: u32,
}

crate::format::plain_data::plain_data! {
    GpuRay { [f32; 3], f32, [f32; 3], f32 }
    GpuHitRecord { f32, f32, f32, u32 }
    GpuParams { u32, u32, f32, u32 }
}
