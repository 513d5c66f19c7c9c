//! [`GpuLayoutTracer`]: the GPU kernel's traversal of the compressed 8-wide sections (format 1.4), run on the
//! CPU step for step as `gpu.wgsl` runs it on a GPU. It is the shader's reference (tests compare the two), the
//! model a benchmark counts node visits and bytes read with, and a CPU tracer over these sections.
//!
//! The walk is Ylitie, Karras, Laine (HPG 2017), Algorithm 1, without the postponed triangle groups: a **node
//! group** is (first child node, hit bits 24-31 | the parent's inner mask in bits 0-7); visiting a node tests
//! its eight decoded slot boxes and forms the next node group from the inner children hit and a **triangle
//! group** (first triangle, hit bits 0-23) from the leaves hit, whose triangles are tested at once. Inner hit
//! bits sit at `24 + (slot ^ inv)`, where `inv` has bit 2, 1, 0 set when the direction's x, y, z is `>= 0`,
//! and the highest bit is taken first: the writer puts the child nearest to rays of octant `o` in slot `o`
//! (octant bits: x negative 4, y negative 2, z negative 1), so children are visited roughly front to back.
//! Triangles are taken highest bit first too. The stack holds node groups that still have hit bits; it never
//! holds more than [`GPU_MAX_DEPTH`] (one per level of the current path, V47).
//!
//! Tests, as the shader does them: the slab test of the CPU kernels (Ize 2013: exit distances through the
//! padded reciprocal, compare-selects that ignore a NaN) on the decoded boxes, with a wider padding
//! ([`GPU_EXIT_PADDING`]: WGSL's division is within 2.5 ulp, not correctly rounded), except that a direction
//! component below the smallest normal f32 is treated as zero (GPUs flush subnormals): that slab holds the
//! origin or nothing, decided by comparisons, so no infinity is formed; boxes are culled beyond the reach of the
//! closest hit (or `t_max`), as on the CPU (`crate::ray::reach`: the tree's part from the root's decoded boxes). Triangles: Woop et al.'s watertight test in f32 only: WGSL has
//! no f64, so where an edge function is exactly 0 the CPU kernels' f64 recomputation of all three is replaced by
//! that edge's exact value (computed here in f64, which is exact for it; the shader gets the same bits from
//! integer arithmetic), the other two keeping their f32 values, whose signs are exact already. Every hit-or-miss
//! decision is then the CPU kernels' for the same arithmetic; `t`, `u`, `v` can differ by a few ulps on rays with
//! such an edge (`format-spec/bvh-1.md` 11.4).

use crate::format::PackedNode;
use crate::format::{GPU_MAX_DEPTH, GPU_WIDE, GpuNode, GpuTriangle, PackedTriangle};
use crate::gpu::shader::GpuHitRecord;
use crate::open::sections::GpuSections;
use crate::open::view::BvhView;
use crate::ray::hit::{Hit, TraversalCounter, TriangleHit};
use crate::ray::intersect::{PreparedRay, Ray};
use crate::ray::query::{AnyHit, ClosestHit, Query, TieOrder};
use crate::ray::reach::{self, tree_scale};
use crate::trace::Trace;

/// Traces rays through a file's GPU sections on the CPU, exactly as the WGSL kernel does (see the module
/// documentation); hits name the record of the `triangles` section and its source id, as every kernel's do.
#[derive(Clone, Copy, Debug)]
pub struct GpuLayoutTracer<'a> {
    nodes: &'a [GpuNode],
    gpu_triangles: &'a [GpuTriangle],
    triangles: &'a [PackedTriangle],
    triangle_ids: Option<&'a [u32]>,
    /// The triangles section's `SPLIT_REFERENCES` flag: hits at one `t` ordered by coordinates, not records.
    split_references: bool,
    /// The tree's part in the walk's reach (`crate::ray::reach::tree_scale`: of the root's decoded slot boxes).
    reach_scale: f32,
}

impl<'a> BvhView<'a> {
    /// The CPU model of the GPU kernel over this file's GPU sections ([`GpuLayoutTracer`]), when it has them.
    pub fn gpu_layout_tracer(&self) -> Option<GpuLayoutTracer<'a>> {
        let tracer = GpuLayoutTracer::new(self.gpu_sections()?, self.triangles(), self.triangle_ids());
        Some(tracer.with_split_references(self.has_split_references()))
    }
}

/// Bytes one node visit reads (one [`GpuNode`]).
pub const GPU_NODE_BYTES: u64 = size_of::<GpuNode>() as u64;
/// Bytes one triangle test reads (one [`GpuTriangle`]).
pub const GPU_TRIANGLE_BYTES: u64 = size_of::<GpuTriangle>() as u64;

/// The GPU kernel's padding of slab exit distances, `1 + 2^-19`: Ize's `1 + 2 gamma(3)` assumes correctly rounded
/// operations, and WGSL's division is only within 2.5 ulp, so the GPU pads more (the model pads the same).
pub(crate) const GPU_EXIT_PADDING: f32 = 1.0 + 1.0 / 524_288.0;

/// The inner-child hit bits start here; bits below are triangle hits.
const INNER_BITS: u32 = 24;
const INNER_MASK: u32 = 0xff00_0000;

impl<'a> GpuLayoutTracer<'a> {
    /// A tracer over `gpu` whose triangles are records of `triangles` (the file's), with their ids.
    pub fn new(gpu: GpuSections<'a>, triangles: &'a [PackedTriangle], triangle_ids: Option<&'a [u32]>) -> Self {
        GpuLayoutTracer {
            nodes: gpu.nodes,
            gpu_triangles: gpu.triangles,
            triangles,
            triangle_ids,
            split_references: false,
            reach_scale: gpu.nodes.first().map_or(0.0, root_reach_scale),
        }
    }

    /// The tree's part in the walk's reach, which the shader reads from `Params::reach_scale`.
    #[cfg_attr(not(feature = "wgpu"), allow(dead_code))]
    pub(crate) fn reach_scale(&self) -> f32 {
        self.reach_scale
    }

    /// This tracer over a triangles section with the `SPLIT_REFERENCES` flag (`split`): of hits at one `t` the
    /// closest is then the one of lowest coordinates and source id, not of lowest record (`format-spec/bvh-1.md`
    /// 11.1), as the
    /// shader does with `Params::split_references` set.
    pub fn with_split_references(self, split: bool) -> Self {
        GpuLayoutTracer { split_references: split, ..self }
    }

    /// Whether this tracer orders hits at one `t` by coordinates ([`GpuLayoutTracer::with_split_references`]).
    #[cfg_attr(not(feature = "wgpu"), allow(dead_code))]
    pub(crate) fn splits_references(&self) -> bool {
        self.split_references
    }

    /// Whether of two hits at one `t` the one on GPU triangle `g` comes before the one on `best` (records
    /// `record` and `best_record`): the shader's `precedes_at_tie`.
    #[inline(never)]
    fn precedes_at_tie(&self, (g, record): (u32, u32), (best, best_record): (u32, u32)) -> bool {
        let tie = TieOrder::new(self.split_references, self.triangle_ids);
        let key = |g: u32, record: u32| {
            tie.key(record, || {
                let triangle = self.gpu_triangles.get(g as usize);
                triangle.map_or([u32::MAX; 9], |t| PackedTriangle { vertices: t.vertices }.coordinate_bits())
            })
        };
        key(g, record) < key(best, best_record)
    }

    /// The record the WGSL kernel writes for `ray` (the closest hit, or for `any_hit` the first hit found), with
    /// ill-conditioned hits given their exact values: what `GpuTracer` (feature `wgpu`) puts in place of a record the
    /// kernel left to the CPU ([`crate::gpu::shader::GpuHitRecord::needs_cpu`]).
    pub fn record(&self, ray: &Ray, any_hit: bool) -> GpuHitRecord {
        let found = if any_hit { self.walk::<AnyHit>(ray, &mut ()) } else { self.walk::<ClosestHit>(ray, &mut ()) };
        found
            .and_then(|(g, hit)| {
                let triangle = self.gpu_triangles.get(g as usize)?.triangle_index;
                Some(GpuHitRecord { t: hit.t, u: hit.u, v: hit.v, triangle })
            })
            .unwrap_or(GpuHitRecord::MISS)
    }

    /// The walk; returns the GPU triangle hit and the hit. Safe on any bytes: indices are checked, at most
    /// `node_count` nodes are visited and a full stack ends the walk.
    fn walk<Q: Query>(&self, ray: &Ray, counter: &mut impl TraversalCounter) -> Option<(u32, TriangleHit)> {
        if self.nodes.is_empty() {
            return None;
        }
        let prepared = PreparedRay::new(ray);
        let inv = octant_inverse(&ray.direction);
        let mut best_t = ray.t_max.min(f32::MAX);
        let mut found: Option<(u32, TriangleHit)> = None;
        // The closest hit's record and GPU triangle: of two hits at one `t`, the first in spec 11.1's order is
        // kept; u32::MAX, the shader's NO_HIT, before the first hit.
        let (mut best_record, mut best_g) = (u32::MAX, u32::MAX);
        let mut stack = [(0u32, 0u32); GPU_MAX_DEPTH];
        let mut stack_len = 0;
        let mut visits_left = self.nodes.len();
        // The root as the only inner child (slot 0) of a group based at node 0.
        let mut node_group = (0u32, (1u32 << (INNER_BITS + inv)) | 1);
        loop {
            let mut triangle_group = (0u32, 0u32);
            if node_group.1 & INNER_MASK != 0 {
                let bit = 31 - node_group.1.leading_zeros();
                node_group.1 &= !(1 << bit);
                let slot = (bit - INNER_BITS) ^ inv;
                let index = node_group.0.wrapping_add((node_group.1 & 0xff & ((1 << slot) - 1)).count_ones());
                if node_group.1 & INNER_MASK != 0 {
                    if stack_len == GPU_MAX_DEPTH {
                        return found;
                    }
                    stack[stack_len] = node_group;
                    stack_len += 1;
                }
                let node = self.nodes.get(index as usize)?;
                visits_left = visits_left.checked_sub(1)?;
                counter.node_visited();
                // Culled beyond the reach of the closest hit so far, or of `t_max` before one is found
                // (`crate::ray::reach`); kept finite for WGSL.
                let far = gpu_cull(best_t, self.reach_scale * prepared.shear().1[2].abs());
                let hits = node_hits(node, &prepared, &ray.direction, inv, far);
                node_group = (node.child_base, (hits & INNER_MASK) | u32::from(node.inner_mask));
                triangle_group = (node.triangle_base, hits & !INNER_MASK);
            }
            while triangle_group.1 != 0 {
                let bit = 31 - triangle_group.1.leading_zeros();
                triangle_group.1 &= !(1 << bit);
                let g = triangle_group.0.wrapping_add(bit);
                let triangle = self.gpu_triangles.get(g as usize)?;
                counter.triangle_tested();
                let packed = PackedTriangle { vertices: triangle.vertices };
                if let Some(hit) = prepared.intersect_triangle_f32(&packed, best_t)
                    && (Q::FIRST_HIT_ENDS
                        || hit.t < best_t
                        || best_record == u32::MAX
                        || (hit.t == best_t
                            && self.precedes_at_tie((g, triangle.triangle_index), (best_g, best_record))))
                {
                    best_t = hit.t;
                    best_record = triangle.triangle_index;
                    best_g = g;
                    found = Some((g, hit));
                    if Q::FIRST_HIT_ENDS {
                        return found;
                    }
                }
            }
            if node_group.1 & INNER_MASK == 0 {
                if stack_len == 0 {
                    return found;
                }
                stack_len -= 1;
                node_group = stack[stack_len];
            }
        }
    }
}

/// The CPU model's walk, a step-for-step mirror of the WGSL kernel's.
impl Trace for GpuLayoutTracer<'_> {
    /// [`Trace::closest_hit`], counting node visits and triangle tests into `counter` (bytes read:
    /// [`GPU_NODE_BYTES`] and [`GPU_TRIANGLE_BYTES`] each).
    fn closest_hit_counted(&self, ray: &Ray, counter: &mut impl TraversalCounter) -> Option<Hit> {
        let (g, hit) = self.walk::<ClosestHit>(ray, counter)?;
        let index = self.gpu_triangles.get(g as usize)?.triangle_index;
        Some(Hit::new(index, hit, self.triangles, self.triangle_ids, &ray.direction))
    }

    /// [`Trace::any_hit`], counting node visits and triangle tests into `counter`.
    fn any_hit_counted(&self, ray: &Ray, counter: &mut impl TraversalCounter) -> bool {
        self.walk::<AnyHit>(ray, counter).is_some()
    }
}

/// The reach's tree scale of a GPU tree whose root node is `root`: of the union of its slots' decoded boxes, which
/// hold every record below it (V50).
fn root_reach_scale(root: &GpuNode) -> f32 {
    let (mut min, mut max) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for slot in (0..GPU_WIDE).filter(|&slot| root.meta[slot] != 0) {
        let (lo, hi) = root.slot_box(slot);
        for a in 0..3 {
            (min[a], max[a]) = (min[a].min(lo[a]), max[a].max(hi[a]));
        }
    }
    let root = PackedNode { min, max, index: 0, count: 0 };
    if min[0] > max[0] { 0.0 } else { tree_scale(&root, 1.0) }
}

/// The cull distance of the GPU walks: [`reach::cull`] of `t` with `2^-11 D = offset`, kept finite (WGSL may
/// assume that no infinity occurs): `f32::MAX` where it would overflow or is NaN.
pub(crate) fn gpu_cull(t: f32, offset: f32) -> f32 {
    let far = reach::cull(t, offset);
    if far <= f32::MAX { far } else { f32::MAX }
}

/// `inv`: bit 2, 1, 0 set when the direction's x, y, z is `>= 0` (so `-0.0` counts as positive).
pub(crate) fn octant_inverse(direction: &[f32; 3]) -> u32 {
    u32::from(direction[0] >= 0.0) << 2 | u32::from(direction[1] >= 0.0) << 1 | u32::from(direction[2] >= 0.0)
}

/// The hit bits of one node: for each occupied slot whose decoded box the ray enters within `[t_min, far]`,
/// `1 << (24 + (slot ^ inv))` for an inner child, the leaf's unary count shifted to its offset for a leaf.
fn node_hits(node: &GpuNode, ray: &PreparedRay, direction: &[f32; 3], inv: u32, far: f32) -> u32 {
    let mut hits = 0;
    for slot in 0..GPU_WIDE {
        let meta = u32::from(node.meta[slot]);
        if meta == 0 || !enters_slot(node, slot, ray, direction, far) {
            continue;
        }
        let is_inner = meta & 0b11000 == 0b11000;
        let bit_index = if is_inner { (meta & 31) ^ inv } else { meta & 31 };
        hits |= (meta >> 5) << bit_index;
    }
    hits
}

/// The robust slab test of `slot`'s decoded box (module documentation): near starts at `t_min`, far at `far`.
fn enters_slot(node: &GpuNode, slot: usize, ray: &PreparedRay, direction: &[f32; 3], far: f32) -> bool {
    let (mut near, mut far) = (ray.t_min, far);
    for (axis, &d) in direction.iter().enumerate() {
        let lo = node.decode(axis, node.quantized_min[axis][slot]);
        let hi = node.decode(axis, node.quantized_max[axis][slot]);
        let origin = ray.origin[axis];
        if d.abs() < f32::MIN_POSITIVE {
            if origin < lo || origin > hi {
                return false;
            }
            continue;
        }
        let (entry, exit) = if ray.negative[axis] { (hi, lo) } else { (lo, hi) };
        let t_entry = (entry - origin) * ray.inverse_direction[axis];
        let t_exit = (exit - origin) * (ray.inverse_direction[axis] * GPU_EXIT_PADDING);
        near = if t_entry > near { t_entry } else { near };
        far = if t_exit < far { t_exit } else { far };
    }
    near <= far
}
