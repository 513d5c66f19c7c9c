//! One tree of a conversion, from triangles to the file's arrays: the candidate stages (build, optimize, leaf
//! layout), then packing the binary and the wide trees, with each record's source id and source vertices. A
//! one-level file is one part; a two-level file has one part per mesh.
//!
//! Each large intermediate is dropped once its stage is done (the tree after packing, the triangles after the
//! check, the soup's ids once mapped), so the peak is one stage's working set, as `crate::import::memory`
//! estimates it.

use std::ops::ControlFlow;
use std::path::Path;
use std::time::Instant;

use bvhc_loader::{format::SourceVertexIndices, wide::WideBvh};

use super::candidates::{Candidate, Chosen, best_candidate, lap};
use super::report::{Choice, ConvertError, Event, Stage, Timings, WideSummary};
use crate::animation::{AnimationRecord, PoseSet};
use crate::cost::SahCost;
use crate::fallible::{collect_exact, probe};
use crate::optimize::OptimizeReport;
use crate::options::ConvertOptions;
use crate::pack::{GpuLayout, PackedTree, pack, pack_gpu, pack_wide};
use crate::sampling::SamplingSummary;

/// Address space a worker thread may take when it first allocates, for the probe before the build: glibc's
/// malloc reserves 64 MiB for each thread's arena, and a thread's stack is 8 MiB. Only reserved, never touched,
/// so this matters only under an address-space limit (`ulimit -v`), where the probe would otherwise pass and a
/// thread's first allocation abort the conversion (measured: `docs/scale.md`).
const THREAD_ADDRESS_SPACE: usize = 72 << 20;

/// The build and optimization of a tree over `triangle_count` triangles allocate many vectors without reporting
/// failure: makes sure their estimated peak at `peak_bytes_per_triangle`, beyond the triangles held already, can
/// be allocated before starting (see `crate::fallible`).
pub(super) fn probe_working_set(
    input: &Path,
    triangle_count: usize,
    peak_bytes_per_triangle: u64,
) -> Result<(), ConvertError> {
    let working_set = triangle_count.saturating_mul(peak_bytes_per_triangle as usize - size_of::<[[f32; 3]; 3]>());
    let threads = rayon::current_num_threads().saturating_mul(THREAD_ADDRESS_SPACE);
    probe(working_set.saturating_add(threads), "building and optimizing the tree")
        .map_err(|e| out_of_memory(input, "building", e))
}

/// One tree, packed.
pub(super) struct PackedPart {
    /// The binary tree's nodes and records (`triangle_ids` here: each record's index in the part's triangles).
    pub packed: PackedTree,
    /// Each record's source id.
    pub source_ids: Vec<u32>,
    /// Each record's source vertices (empty unless the options write them).
    pub source_vertices: Vec<SourceVertexIndices>,
    /// The wide sections and their summary, with the options' wide layout.
    pub wide: Option<(WideBvh, WideSummary)>,
    /// The GPU sections (format 1.4), with the options' GPU layout.
    pub gpu: Option<GpuLayout>,
    /// The binary tree's SAH cost.
    pub cost: SahCost,
    /// The part's triangles (distinct; some stored more than once with split references).
    pub triangle_count: usize,
    /// The references the tree was built over.
    pub reference_count: usize,
    /// The optimizer's report, when it ran.
    pub optimization: Option<OptimizeReport>,
    /// The candidates' costs, when the options asked to choose.
    pub choice: Option<Choice>,
    /// With ray tuning: the sample's sizes, or why it was skipped.
    pub sampling: Option<SamplingSummary>,
    /// With an animation: the trees' costs in each sampled pose.
    pub animation: Option<AnimationRecord>,
}

/// Builds, optimizes, lays out and packs one tree over `triangles`, whose source ids are `source_ids` and source
/// vertices `source_vertices` (empty when not written), in the order of `triangles`; with `poses` (an animation's,
/// the same triangles in each pose) the tree is chosen for the cost averaged over them.
#[allow(clippy::too_many_arguments)] // the part's arrays, then the conversion's context
pub(super) fn build_part(
    input: &Path,
    triangles: Vec<[[f32; 3]; 3]>,
    source_ids: Vec<u32>,
    source_vertices: Vec<[u32; 3]>,
    deforming: &dyn Fn(u32) -> bool,
    poses: Option<&PoseSet>,
    options: &ConvertOptions,
    observer: &mut dyn FnMut(Event<'_>) -> ControlFlow<()>,
    timings: &mut Timings,
) -> Result<PackedPart, ConvertError> {
    // Under `--no-splits-deforming`, the triangles of geometry meant to deform (by their source ids) stay whole.
    let whole: Vec<bool> = match options.splits {
        Some(splits) if !splits.deforming => source_ids.iter().map(|&id| deforming(id)).collect(),
        _ => Vec::new(),
    };
    let Chosen { candidate, choice, sampling } =
        best_candidate(input, &triangles, &whole, poses, options, observer, timings)?;
    drop(whole);
    let Candidate { final_tree, wide_tree, gpu_tree, reference_count, optimization, animation, .. } = candidate;
    let over_references = reference_count > triangles.len();
    let _ = observer(Event::Stage(Stage::Write));
    let clock = Instant::now();
    let cost = final_tree.sah_cost(options.optimize.constants);
    let packed = pack(&final_tree, &triangles).map_err(|e| out_of_memory(input, "packing", e))?;
    drop(final_tree);
    let triangle_count = triangles.len();
    drop(triangles);
    check_every_triangle_stored(&packed.triangle_ids, triangle_count, over_references)?;
    let stored_triangle_count = packed.triangles.len();
    // The packer numbers triangles by their index in the part; the file stores their source ids.
    let ids = packed.triangle_ids.iter().map(|&t| source_ids[t as usize]);
    let mapped_ids = collect_exact(packed.triangle_ids.len(), ids, "the source ids")
        .map_err(|e| out_of_memory(input, "packing", e))?;
    drop(source_ids);
    // Each record's source vertices, in the record's corner order (the soup's order, mirrored already).
    let mapped_vertices = if source_vertices.is_empty() {
        Vec::new()
    } else {
        let records = packed.triangle_ids.iter().map(|&t| SourceVertexIndices { indices: source_vertices[t as usize] });
        collect_exact(packed.triangle_ids.len(), records, "the source vertices")
            .map_err(|e| out_of_memory(input, "packing", e))?
    };
    drop(source_vertices);
    let wide = match wide_tree {
        Some((wide_tree, costs)) => {
            let split = stored_triangle_count > triangle_count;
            let bvh = if split {
                let mut records =
                    packed.record_cursor(triangle_count).map_err(|e| out_of_memory(input, "packing", e))?;
                pack_wide(&wide_tree, &packed.triangles, &mut |t| records.next(t), true)
                    .map_err(|e| out_of_memory(input, "packing", e))?
            } else {
                let file_index_of =
                    packed.file_index_of(triangle_count).map_err(|e| out_of_memory(input, "packing", e))?;
                pack_wide(&wide_tree, &packed.triangles, &mut |t| file_index_of.get(t as usize).copied(), false)
                    .map_err(|e| out_of_memory(input, "packing", e))?
            };
            let summary = WideSummary {
                node_count: bvh.nodes().len(),
                packet_count: bvh.packets().len(),
                cost: wide_tree.cost(&costs),
            };
            Some((bvh, summary))
        }
        None => None,
    };
    let gpu = match gpu_tree {
        Some(gpu_tree) => {
            let split = stored_triangle_count > triangle_count;
            let file_index_of = packed.file_index_of(triangle_count).map_err(|e| out_of_memory(input, "packing", e))?;
            let record_of = |t: u32| file_index_of.get(t as usize).copied();
            Some(
                pack_gpu(&gpu_tree, &packed.triangles, &record_of, split)
                    .map_err(|e| out_of_memory(input, "packing", e))?,
            )
        }
        None => None,
    };
    timings.pack += lap(clock);
    Ok(PackedPart {
        gpu,
        packed,
        source_ids: mapped_ids,
        source_vertices: mapped_vertices,
        wide,
        cost,
        triangle_count,
        reference_count,
        optimization,
        choice,
        sampling,
        animation,
    })
}

/// The file may legally repeat triangles (split references), so its verifier cannot notice a triangle lost or
/// doubled by a builder bug; this O(n) check refuses to write such a tree: every triangle at least once, and
/// exactly once without splits.
fn check_every_triangle_stored(ids: &[u32], triangle_count: usize, split: bool) -> Result<(), ConvertError> {
    let mut seen = vec![false; triangle_count];
    let mut repeated = false;
    for &t in ids {
        let Some(slot) = seen.get_mut(t as usize) else {
            return Err(ConvertError::Internal(format!("the built tree holds triangle {t} of {triangle_count}")));
        };
        repeated |= std::mem::replace(slot, true);
    }
    if let Some(t) = seen.iter().position(|&s| !s) {
        return Err(ConvertError::Internal(format!("the built tree lost triangle {t}")));
    }
    if repeated && !split {
        return Err(ConvertError::Internal("the built tree holds a triangle twice without split references".into()));
    }
    Ok(())
}

/// `error` as the conversion's error: [`ConvertError::OutOfMemory`] naming `input` and `stage` when the system
/// refused memory, otherwise a write error.
pub(super) fn out_of_memory(input: &Path, stage: &'static str, error: bvhc_loader::Error) -> ConvertError {
    let refused = match &error {
        bvhc_loader::Error::OutOfMemory { .. } => true,
        bvhc_loader::Error::Io { source, .. } => source.kind() == std::io::ErrorKind::OutOfMemory,
        _ => false,
    };
    if refused {
        ConvertError::OutOfMemory { path: input.to_path_buf(), stage, source: error }
    } else {
        ConvertError::Write(error)
    }
}
