//! Shared by the GPU tests (`gpu_layout`, `gpu_shader`): files with the GPU sections of format 1.4 built from
//! triangles, and the comparison of a GPU kernel's hits with the CPU kernel's, by the classes that
//! `format-spec/bvh-1.md` 11.4 allows.

use std::fmt;

use bvhc::cost::SahConstants;
use bvhc::layout::{GpuCosts, collapse, merge_leaves};
use bvhc::loader::{BvhFile, BvhView, Hit, Ray, ray::PreparedRay, write::BvhWriter};
use bvhc::optimize::OptTree;
use bvhc::pack::{pack, pack_gpu};

use crate::common::{Triangle, single_source_range};

/// Metadata for test files of version 1.4 (V28).
pub const METADATA_1_4: &str = r#"{"generator":"bvhc tests","format_version":"1.4"}"#;

/// A version 1.4 file over `triangles`: a binned SAH tree (leaves merged up to 8) with ids and source table,
/// and the GPU sections collapsed from the same tree with the default GPU costs, as the conversion does.
pub fn gpu_file(triangles: &[Triangle]) -> BvhFile {
    let build = bvhc::builders::build_binned_sah(triangles, 1);
    let opt = OptTree::from_build_tree(&build, triangles);
    let merged = merge_leaves(&opt, SahConstants::default(), 8);
    let packed = pack(&merged, triangles).expect("memory");
    let gpu_tree = collapse(&opt, &GpuCosts::default().wide_costs());
    let file_index_of = packed.file_index_of(triangles.len()).expect("memory");
    let layout =
        pack_gpu(&gpu_tree, &packed.triangles, &|t| file_index_of.get(t as usize).copied(), false).expect("packs");
    let ranges = single_source_range(packed.triangles.len());
    let writer = BvhWriter::new(&packed.nodes, &packed.triangles)
        .triangle_ids(&packed.triangle_ids)
        .metadata(METADATA_1_4)
        .gpu(&layout.nodes, &layout.triangles);
    let writer = if packed.triangles.is_empty() { writer } else { writer.source_table(&ranges) };
    writer.build().expect("a GPU layout always writes")
}

/// How a GPU kernel's closest hit compares with the CPU kernel's on one ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Agreement {
    /// The same triangle (with split references, possibly another of its records, 5.15) with the same `t`, `u`
    /// and `v` bit for bit, or both miss.
    Exact,
    /// The same triangle (same source id, or same vertices without ids) with `t` within the bound, other bits:
    /// where an edge function rounds to exactly 0, the GPU's test keeps the other two edge functions' f32 values
    /// where the CPU's recomputes all three in f64 (11.4); or a GPU's own arithmetic.
    Same,
    /// Another triangle with `t` within the bound of the CPU's: two triangles met at one point (a shared edge or
    /// vertex, or coincident faces), where the kernels' visit orders decide.
    Tie,
    /// Anything else: a missed hit, a farther hit, a hit on a triangle the CPU's test rejects, a `t` out of bounds.
    Differs,
}

/// Counts of [`Agreement`] over a set of rays, and the largest `t` difference relative to the bound's scale.
#[derive(Clone, Copy, Debug, Default)]
pub struct Tally {
    pub rays: usize,
    pub hits: usize,
    pub exact: usize,
    pub same: usize,
    pub ties: usize,
    pub differs: usize,
    pub any_hit_differs: usize,
    pub worst_t: f64,
}

impl Tally {
    pub fn add(&mut self, agreement: Agreement) {
        self.rays += 1;
        match agreement {
            Agreement::Exact => self.exact += 1,
            Agreement::Same => self.same += 1,
            Agreement::Tie => self.ties += 1,
            Agreement::Differs => self.differs += 1,
        }
    }
}

impl fmt::Display for Tally {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "| {} | {} | {} | {} | {} | {} | {} | {:.1e} |",
            self.rays, self.hits, self.exact, self.same, self.ties, self.differs, self.any_hit_differs, self.worst_t
        )
    }
}

/// The documented bound on `t` between kernels (`format-spec/bvh-1.md` 11.4): `2^-16 (t + |o| / |d|)`.
pub fn t_bound(ray: &Ray, t: f32) -> f64 {
    let norm = |v: [f32; 3]| v.iter().map(|&c| f64::from(c) * f64::from(c)).sum::<f64>().sqrt();
    (f64::from(t) + norm(ray.origin) / norm(ray.direction)) / 65_536.0
}

/// Compares `gpu` with `cpu` on `ray` over `view`'s records; adds the relative `t` difference to `worst`.
pub fn compare(view: &BvhView<'_>, ray: &Ray, cpu: Option<Hit>, gpu: Option<Hit>, worst: &mut f64) -> Agreement {
    let same_triangle = |a: &Hit, b: &Hit| match (a.source_triangle_id, b.source_triangle_id) {
        (Some(x), Some(y)) => x == y,
        _ => view.triangles()[a.triangle_index as usize] == view.triangles()[b.triangle_index as usize],
    };
    let bits = |h: &Hit| (h.t.to_bits(), h.u.to_bits(), h.v.to_bits());
    match (cpu, gpu) {
        (None, None) => Agreement::Exact,
        (Some(c), Some(g)) => {
            let difference = (f64::from(g.t) - f64::from(c.t)).abs();
            let bound = t_bound(ray, c.t);
            *worst = worst.max(difference / bound);
            if same_triangle(&c, &g) && bits(&c) == bits(&g) {
                Agreement::Exact
            } else if difference > bound || !accepted_by_cpu_test(view, ray, &g) {
                Agreement::Differs
            } else if same_triangle(&c, &g) {
                Agreement::Same
            } else {
                Agreement::Tie
            }
        }
        _ => Agreement::Differs,
    }
}

/// Whether the CPU kernels' triangle test (11.1) hits the GPU's hit record for this ray at all: a GPU hit on a
/// record 11.1 rejects (say just outside a silhouette edge) is never a tie, whatever its `t`.
fn accepted_by_cpu_test(view: &BvhView<'_>, ray: &Ray, hit: &Hit) -> bool {
    let triangle = &view.triangles()[hit.triangle_index as usize];
    PreparedRay::new(ray).intersect_triangle(triangle, ray.t_max).is_some()
}

/// The table header that [`Tally`]'s rows follow, with `extra` columns after them.
pub fn table_header(extra: &[&str]) -> String {
    let columns = ["scene", "rays", "hits", "bit for bit", "same record", "ties", "differ", "any-hit differs"];
    let names: Vec<&str> = columns.iter().copied().chain(["worst t / bound"]).chain(extra.iter().copied()).collect();
    format!("| {} |\n|{}", names.join(" | "), "---|".repeat(names.len()))
}
