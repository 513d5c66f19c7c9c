//! The conversion pipeline: import -> initial build (one triangle per leaf) -> optimize -> depth limit ->
//! leaf merging -> pack -> write (atomically). Deterministic: the same input and options give the same bytes,
//! whatever the number of threads (nothing that varies between runs, such as times or absolute paths, is
//! written into the file).

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use bvhc_loader::format::MAX_DEPTH;
use bvhc_loader::{AtomicOutput, BvhFile, BvhWriter};
use serde::Serialize;

use crate::build_tree::BuildTree;
use crate::builders::sbvh::{SbvhParams, build_sbvh};
use crate::builders::{Builder, split_triangles_with};
use crate::cost::SahCost;
use crate::import::{ImportOptions, ImportReport, TriangleSoup, import};
use crate::layout::{WideCosts, WideTree, cluster_roots};
use crate::optimize::{
    DEFAULT_CLUSTER_SIZE, OptTree, OptimizeParams, OptimizeReport, Preset, Progress, StopReason, optimize,
    optimize_over_clusters,
};
use crate::pack::{pack, pack_wide};
use crate::up_to_date::input_entries;

/// Largest leaf the merger makes by default (the reference table's M = 3 uses 8).
pub const DEFAULT_MAX_LEAF_SIZE: usize = 8;

/// Everything a conversion can be told; `Default` is the balanced preset.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ConvertOptions {
    /// Import options (glTF scene, keeping degenerate triangles).
    pub import: ImportOptions,
    /// The initial builder.
    pub builder: Builder,
    /// The preset the optimizer parameters came from (recorded for reference).
    pub preset: Preset,
    /// Optimizer parameters.
    pub optimize: OptimizeParams,
    /// Skip the optimizer entirely.
    pub skip_optimization: bool,
    /// Merge leaves bottom-up by SAH (up to `max_leaf_size` triangles each).
    pub merge_leaves: bool,
    /// Largest merged leaf.
    pub max_leaf_size: usize,
    /// Write the triangle_ids and source_table sections.
    pub write_ids: bool,
    /// Write the wide sections of format 1.1 (`wide_nodes`, `triangle_packets`), collapsed from the optimized
    /// tree with these constants; `None` writes a 1.0 file without them.
    pub wide: Option<WideCosts>,
    /// Cut triangles into split references ([`crate::builders::presplit`]); `None`: one reference a triangle. Recorded only
    /// when on, so files converted without splits keep the bytes they had before splits existed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub splits: Option<SplitOptions>,
    /// What the optimizer's leaves are. Recorded only when not one reference a leaf, so files converted that
    /// way before the choice existed keep their bytes.
    #[serde(skip_serializing_if = "OptimizeOver::is_default")]
    pub optimize_over: OptimizeOver,
}

/// What reinsertion optimizes over.
///
/// With one reference a leaf (Bittner et al.'s setting) the optimizer lowers the binary tree's inner areas but
/// breaks up the small subtrees the builder made, which become the file's leaves; over the builder's subtrees
/// of up to [`DEFAULT_CLUSTER_SIZE`] references ([`optimize_over_clusters`]) those stay as built. Which wins
/// depends on the scene (wide render time through the default kernel, clusters against references, two runs:
/// kitchen 0.925 and 0.926, milk truck 0.974 and 0.979, 2CylinderEngine 1.022 and 0.996, dragon res2 1.015
/// and 1.004, the others within 1.5%: `docs/evaluation.md`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum OptimizeOver {
    /// One reference a leaf.
    #[default]
    References,
    /// The built tree's subtrees of up to [`DEFAULT_CLUSTER_SIZE`] references, kept as built.
    Clusters,
    /// Both, each optimized and merged; the tree whose wide cost (binary SAH without wide sections) is lower
    /// is written, `References`' on a tie.
    Choose,
}

impl OptimizeOver {
    /// The name used in options.
    pub fn name(self) -> &'static str {
        match self {
            OptimizeOver::References => "references",
            OptimizeOver::Clusters => "clusters",
            OptimizeOver::Choose => "choose",
        }
    }

    /// A preset's choice: `balanced` and `fast` optimize over clusters, `max-quality` chooses. Balanced,
    /// measured through the wide kernel against references: kitchen 0.928, milk truck 0.988 of the render time,
    /// the other six scenes within noise, at 0.1-0.7% higher wide cost on the scanned meshes; the 7.8M-triangle
    /// dragon grid converts in 24.8 s instead of 37.4 s (`docs/evaluation.md`, `docs/scale.md`). Fast shows the
    /// same wide costs (kitchen 10.47 against 11.08, scanned meshes +0.5-0.6%) in half the optimization time.
    pub fn for_preset(preset: Preset) -> OptimizeOver {
        match preset {
            Preset::Fast | Preset::Balanced => OptimizeOver::Clusters,
            Preset::MaxQuality => OptimizeOver::Choose,
        }
    }

    fn is_default(&self) -> bool {
        *self == OptimizeOver::References
    }
}

/// How a conversion splits references, and how many it may add.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct SplitOptions {
    /// At most `budget * triangles` references beyond one a triangle (0.3: 30% more).
    pub budget: f64,
    /// Where the cuts are made.
    pub method: SplitMethod,
    /// Which triangles may be cut. Recorded only when not the default, so files converted before the choice
    /// existed keep their bytes.
    #[serde(skip_serializing_if = "SplitTriangles::is_default")]
    pub triangles: SplitTriangles,
}

impl SplitOptions {
    /// The default method and triangles with `budget`.
    pub fn with_budget(budget: f64) -> SplitOptions {
        SplitOptions { budget, method: SplitMethod::default(), triangles: SplitTriangles::default() }
    }

    /// A preset's splits: the SBVH within [`DEFAULT_SPLIT_BUDGET`] for `balanced` and `max-quality`, none for
    /// `fast` (whose point is the conversion's speed: the SBVH build takes about four times the binned one).
    /// `max-quality` also chooses which triangles to cut ([`SplitTriangles::Choose`]: two builds).
    pub fn for_preset(preset: Preset) -> Option<SplitOptions> {
        match preset {
            Preset::Fast => None,
            Preset::Balanced => Some(SplitOptions::with_budget(DEFAULT_SPLIT_BUDGET)),
            Preset::MaxQuality => Some(SplitOptions {
                triangles: SplitTriangles::Choose,
                ..SplitOptions::with_budget(DEFAULT_SPLIT_BUDGET)
            }),
        }
    }
}

/// Which triangles a conversion may cut into split references.
///
/// Triangles that fill half of their box's face (the two halves of an axis-aligned rectangle) are the case that
/// matters: cutting them lowers the binary tree's SAH everywhere, but the wide tree that files are traced by
/// gets cheaper on some scenes and dearer on others, and no per-triangle threshold separates the two (balanced
/// preset, SBVH 0.3, wide cost against the default `Wasteful`: kitchen 11.46 / 10.85, 2CylinderEngine 24.79 /
/// 26.12, wide render time through the default kernel 1.057 / 0.987 and 0.888 / 0.956 of the unsplit file;
/// thresholds of 0.5 and 0.501 gave the same split as 0 and as 0.55 on both scenes: `cargo bench --bench
/// evaluate`, 2026-12-03, `docs/evaluation.md`). So the choice is made by measuring both trees.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SplitTriangles {
    /// Only triangles whose pieces could remove a large part of their box's area (at least
    /// [`crate::builders::sbvh::MIN_WASTE_RATIO`], [`crate::builders::presplit::MIN_WASTE_RATIO`] for pre-splitting).
    #[default]
    Wasteful,
    /// Any triangle the method finds worth cutting (no waste threshold).
    Any,
    /// Both of the above, each built, optimized and merged; the tree whose wide collapse costs less (the binary
    /// SAH without wide sections) is written, `Wasteful`'s on a tie. About twice the build, optimization and
    /// merge time.
    Choose,
}

impl SplitTriangles {
    /// The name used in options.
    pub fn name(self) -> &'static str {
        match self {
            SplitTriangles::Wasteful => "wasteful",
            SplitTriangles::Any => "any",
            SplitTriangles::Choose => "choose",
        }
    }

    fn is_default(&self) -> bool {
        *self == SplitTriangles::Wasteful
    }
}

/// The default split budget: at most 30% more references (the 1.3x). It is a cap rather than a target:
/// with the SBVH's thresholds the evaluated scenes used 0.1-2.7% more references at 0.1 and at 0.3 alike
/// (`cargo bench --bench evaluate`, files table, 2026-12-03), and 0.3 gave the engine and toy car slightly lower
/// wide costs (26.12 / 9.26 against 26.20 / 9.32).
pub const DEFAULT_SPLIT_BUDGET: f64 = 0.3;

/// Where triangles are cut into split references.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SplitMethod {
    /// During the top-down build, where a node's children would overlap ([`crate::builders::sbvh`], Stich et
    /// al. 2009): the better trees in every scene measured (`docs/evaluation.md`).
    #[default]
    Sbvh,
    /// Before the build, large triangles at grid planes ([`crate::builders::split_triangles`], Karras and Aila
    /// 2013).
    PreSplit,
}

impl SplitMethod {
    /// The name used in options and reports.
    pub fn name(self) -> &'static str {
        match self {
            SplitMethod::Sbvh => "sbvh",
            SplitMethod::PreSplit => "pre-split",
        }
    }
}

impl Default for ConvertOptions {
    fn default() -> Self {
        ConvertOptions::preset(Preset::Balanced)
    }
}

impl ConvertOptions {
    /// The options as recorded in the metadata's `build` object (and compared by the up-to-date check).
    /// `max_leaf_size` is recorded as 1 when leaves are not merged (the file then has one triangle per leaf).
    pub fn recorded(&self) -> serde_json::Value {
        let mut recorded = serde_json::to_value(self).unwrap_or_default();
        if !self.merge_leaves {
            recorded["max_leaf_size"] = serde_json::json!(1);
        }
        recorded
    }

    /// The options of a preset.
    pub fn preset(preset: Preset) -> ConvertOptions {
        ConvertOptions {
            import: ImportOptions::default(),
            builder: Builder::BinnedSah,
            preset,
            optimize: OptimizeParams::preset(preset),
            skip_optimization: false,
            merge_leaves: true,
            max_leaf_size: DEFAULT_MAX_LEAF_SIZE,
            write_ids: true,
            wide: Some(WideCosts::default()),
            splits: SplitOptions::for_preset(preset),
            optimize_over: OptimizeOver::for_preset(preset),
        }
    }
}

/// What a conversion produced and measured.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ConvertReport {
    /// The output file.
    pub output: PathBuf,
    /// Every input file read.
    pub files_read: Vec<PathBuf>,
    /// What the import read and skipped.
    pub import: ImportReport,
    /// The optimizer's report (absent when skipped).
    pub optimization: Option<OptimizeReport>,
    /// Cost of the written tree.
    pub cost: SahCost,
    /// Triangles written (distinct; with split references some are stored more than once).
    pub triangle_count: usize,
    /// The references the tree was built over (`triangle_count` without splits).
    pub reference_count: usize,
    /// Triangle records written (more than `triangle_count` when leaves repeat split triangles).
    pub stored_triangle_count: usize,
    /// Nodes written.
    pub node_count: usize,
    /// Wide nodes and triangle packets written (absent without wide sections).
    pub wide: Option<WideSummary>,
    /// Bytes written.
    pub file_byte_len: usize,
    /// Seconds per stage: import, build, optimize, merge, pack, write.
    pub timings: Timings,
    /// With [`SplitTriangles::Choose`] or [`OptimizeOver::Choose`]: the candidates' costs and the one written
    /// (absent when a cancelled optimization ended the search at the first).
    pub choice: Option<Choice>,
}

/// The wide sections of a conversion: their sizes and the collapsed tree's cost.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct WideSummary {
    /// Elements of `wide_nodes`.
    pub node_count: usize,
    /// Elements of `triangle_packets`.
    pub packet_count: usize,
    /// The wide tree's cost under the collapse's constants ([`crate::layout::WideTree::cost`]).
    pub cost: f64,
}

/// Seconds spent per stage.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Timings {
    /// Import.
    pub import: f64,
    /// Initial build.
    pub build: f64,
    /// Optimization by reinsertion.
    pub optimize: f64,
    /// Depth limiting, the wide collapse and leaf merging.
    pub merge: f64,
    /// Packing the binary and the wide trees into the file's arrays.
    pub pack: f64,
    /// Writing the file (metadata, checksums, atomic rename).
    pub write: f64,
}

impl Timings {
    /// All stages together.
    pub fn total(&self) -> f64 {
        self.import + self.build + self.optimize + self.merge + self.pack + self.write
    }
}

/// Why a conversion failed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ConvertError {
    /// The input could not be imported.
    #[error(transparent)]
    Import(#[from] crate::import::ImportError),
    /// The output could not be written.
    #[error(transparent)]
    Write(#[from] bvhc_loader::Error),
    /// A bug in bvhc was caught before writing: please report it with the input.
    #[error("internal error (please report with the input): {0}")]
    Internal(String),
    /// The output names one of the files the conversion reads (the input, or a glTF buffer): writing it would
    /// destroy the input.
    #[error("{}: the output is one of the inputs ({}); choose another output path", output.display(), input.display())]
    OutputIsInput {
        /// The output path.
        output: PathBuf,
        /// The input file it names.
        input: PathBuf,
    },
    /// The scene has more triangles than the format's u32 indices allow.
    #[error("{}: {count} triangles (or split references) exceed the .bvh limit of 2^32 - 1", path.display())]
    TooLarge {
        /// The input.
        path: PathBuf,
        /// Its triangle count.
        count: usize,
    },
}

/// Converts `input` into the `.bvh` file `output` with the default options.
pub fn convert(input: &Path, output: &Path) -> Result<ConvertReport, ConvertError> {
    convert_with(input, output, &ConvertOptions::default(), &mut |_| ControlFlow::Continue(()))
}

/// A stage of the pipeline, as reported to the observer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Reading the scene.
    Import,
    /// The initial build.
    Build,
    /// Optimization and leaf merging.
    Optimize,
    /// Packing, writing and verifying.
    Write,
}

/// What the pipeline tells its observer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Event<'a> {
    /// A stage begins.
    Stage(Stage),
    /// An optimizer batch ended.
    Batch(&'a Progress),
}

/// Converts `input` into `output` (written atomically). `observer` sees every stage and optimizer batch;
/// returning `ControlFlow::Break` on a batch cancels the optimization (the best tree so far is written).
pub fn convert_with(
    input: &Path,
    output: &Path,
    options: &ConvertOptions,
    observer: &mut dyn FnMut(Event<'_>) -> ControlFlow<()>,
) -> Result<ConvertReport, ConvertError> {
    let mut timings = Timings::default();
    bvhc_loader::check_replaceable(output)?;
    refuse_output_among(output, std::slice::from_ref(&input.to_path_buf()))?;
    let _ = observer(Event::Stage(Stage::Import));
    let clock = Instant::now();
    let imported = import(input, &options.import)?;
    timings.import = lap(clock);
    refuse_output_among(output, &imported.files_read)?;
    let soup = imported.soup;
    let triangles = soup.triangle_vertices();
    // Each large intermediate is dropped once its stage is done, so the peak is one stage's working set: here
    // the soup's vertices and indices (the triangles hold the positions now).
    let TriangleSoup { positions, triangles: vertex_indices, source_ids: soup_source_ids, sources: soup_sources } =
        soup;
    drop((positions, vertex_indices));
    if u32::try_from(triangles.len()).is_err() {
        return Err(ConvertError::TooLarge { path: input.to_path_buf(), count: triangles.len() });
    }
    let (candidate, choice) = best_candidate(input, &triangles, options, observer, &mut timings)?;
    let Candidate { final_tree, wide_tree, reference_count, optimization } = candidate;
    let over_references = reference_count > triangles.len();
    let _ = observer(Event::Stage(Stage::Write));
    let clock = Instant::now();
    let cost = final_tree.sah_cost(options.optimize.constants);
    let packed = pack(&final_tree, &triangles);
    drop(final_tree);
    let triangle_count = triangles.len();
    drop(triangles);
    check_every_triangle_stored(&packed.triangle_ids, triangle_count, over_references)?;
    let stored_triangle_count = packed.triangles.len();
    // The packer numbers triangles by their index in the soup; the file stores their source ids.
    let source_ids: Vec<u32> = packed.triangle_ids.iter().map(|&t| soup_source_ids[t as usize]).collect();
    drop(soup_source_ids);
    let wide = match wide_tree {
        Some((wide_tree, costs)) => {
            let split = stored_triangle_count > triangle_count;
            let bvh = if split {
                let mut records = packed.record_cursor(triangle_count);
                pack_wide(&wide_tree, &packed.triangles, &mut |t| records.next(t), true)?
            } else {
                let file_index_of = packed.file_index_of(triangle_count);
                pack_wide(&wide_tree, &packed.triangles, &mut |t| file_index_of.get(t as usize).copied(), false)?
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
    timings.pack = lap(clock);
    let clock = Instant::now();
    let inputs = input_entries(input, &imported.files_read)
        .map_err(|source| bvhc_loader::Error::Io { path: input.to_path_buf(), source })?;
    let summary = wide.as_ref().map(|(_, summary)| *summary);
    let metadata = metadata_json(inputs, options, &cost, &imported.report, summary.as_ref(), choice.as_ref());
    let mut writer = BvhWriter::new(&packed.nodes, &packed.triangles)
        .metadata(&metadata)
        .split_references(stored_triangle_count > triangle_count);
    if options.write_ids {
        writer = writer.triangle_ids(&source_ids).source_table(&soup_sources);
    }
    if let Some((bvh, _)) = &wide {
        writer = writer.wide(bvh.nodes(), bvh.packets());
    }
    // Streamed to a temporary file, then read back and verified in full once the packed arrays are freed, so
    // the file is in memory once (laying it out in memory beside the arrays took twice its size); the output
    // is replaced only by a verified file. Both transfers bypass the page cache where the system allows it
    // (see `UncachedWriter`): 1 GB through the cache took 4.7 s of a 7.3 s write stage on this project's VMs.
    let mut atomic = AtomicOutput::create(output)?;
    let mut sink = atomic.uncached_writer();
    writer.write_unverified(&mut sink)?;
    let file_byte_len = sink
        .finish()
        .map_err(|source| bvhc_loader::Error::Io { path: atomic.temporary_path().to_path_buf(), source })?;
    let node_count = packed.nodes.len();
    drop(writer);
    drop((packed, wide, source_ids));
    let file = BvhFile::read_uncached(atomic.temporary_path())?;
    file.view().verify().map_err(bvhc_loader::Error::from)?;
    drop(file);
    atomic.commit()?;
    timings.write = lap(clock);
    Ok(ConvertReport {
        output: output.to_path_buf(),
        files_read: imported.files_read,
        import: imported.report,
        optimization,
        cost,
        triangle_count,
        reference_count,
        stored_triangle_count,
        node_count,
        wide: summary,
        file_byte_len: file_byte_len as usize,
        timings,
        choice,
    })
}

/// A conversion's tree before packing: built, optimized and merged.
struct Candidate {
    final_tree: BuildTree,
    wide_tree: Option<(WideTree, WideCosts)>,
    /// The references the tree was built over.
    reference_count: usize,
    optimization: Option<OptimizeReport>,
}

impl Candidate {
    /// What a [`Choice`] compares: the wide tree's cost, or the binary SAH without wide sections.
    fn score(&self, options: &ConvertOptions) -> f64 {
        match &self.wide_tree {
            Some((wide, costs)) => wide.cost(costs),
            None => self.final_tree.sah_cost(options.optimize.constants).cost,
        }
    }
}

/// Every candidate the options ask for (which triangles may be cut, what the optimizer's leaves are: one each
/// unless told to choose), built, optimized and merged, and the one whose [`Candidate::score`] is lowest (the
/// first on a tie), with the costs of all when there were several. A time budget is shared equally; a
/// cancelled optimization ends the search (its tree competes with those made before it).
fn best_candidate(
    input: &Path,
    triangles: &[[[f32; 3]; 3]],
    options: &ConvertOptions,
    observer: &mut dyn FnMut(Event<'_>) -> ControlFlow<()>,
    timings: &mut Timings,
) -> Result<(Candidate, Option<Choice>), ConvertError> {
    let cut_any: &[bool] = match options.splits.map(|s| s.triangles) {
        Some(SplitTriangles::Choose) => &[false, true],
        Some(SplitTriangles::Any) => &[true],
        _ => &[false],
    };
    // Without optimization both ways give the same tree.
    let over_clusters: &[bool] = match options.optimize_over {
        _ if options.skip_optimization => &[false],
        OptimizeOver::References => &[false],
        OptimizeOver::Clusters => &[true],
        OptimizeOver::Choose => &[false, true],
    };
    let mut shared = options.clone();
    let count = (cut_any.len() * over_clusters.len()) as u32;
    shared.optimize.time_budget = options.optimize.time_budget.map(|t| t / count);
    // (candidate, its score, its index in `costs`)
    let mut best: Option<(Candidate, f64, usize)> = None;
    let mut costs = Vec::new();
    'search: for &any_triangle in cut_any {
        let (built, reference_count) = build_stage(input, triangles, &shared, any_triangle, observer, timings)?;
        let mut built = Some(built);
        for (k, &clusters) in over_clusters.iter().enumerate() {
            // The last candidate of this build takes the tree; the others optimize a copy.
            let tree = if k + 1 < over_clusters.len() { built.clone() } else { built.take() };
            let Some(tree) = tree else { unreachable!("the built tree is taken by the last candidate only") };
            let candidate =
                optimize_and_merge(tree, reference_count, triangles.len(), &shared, clusters, observer, timings);
            let score = candidate.score(options);
            let cancelled = candidate.optimization.as_ref().is_some_and(|r| r.stop == StopReason::Cancelled);
            costs.push(CandidateCost {
                split_triangles: if any_triangle { SplitTriangles::Any } else { SplitTriangles::Wasteful },
                optimize_over: if clusters { OptimizeOver::Clusters } else { OptimizeOver::References },
                cost: score,
            });
            if best.as_ref().is_none_or(|(_, lowest, _)| score < *lowest) {
                best = Some((candidate, score, costs.len() - 1));
            }
            if cancelled {
                break 'search;
            }
        }
    }
    let Some((kept, _, kept_index)) = best else { unreachable!("at least one candidate is made") };
    let choice = (costs.len() > 1).then(|| Choice {
        measure: if options.wide.is_some() { "wide_cost" } else { "sah_cost" },
        kept: kept_index,
        candidates: costs,
    });
    Ok((kept, choice))
}

/// The build stage: the initial tree, cutting split references (where `options.splits` allows them) in any
/// triangle worth cutting when `any_triangle`, else only in triangles that waste a large part of their box;
/// and the number of references it holds.
fn build_stage(
    input: &Path,
    triangles: &[[[f32; 3]; 3]],
    options: &ConvertOptions,
    any_triangle: bool,
    observer: &mut dyn FnMut(Event<'_>) -> ControlFlow<()>,
    timings: &mut Timings,
) -> Result<(OptTree, usize), ConvertError> {
    let _ = observer(Event::Stage(Stage::Build));
    let clock = Instant::now();
    let too_large = |count: usize| ConvertError::TooLarge { path: input.to_path_buf(), count };
    let (build, reference_count) = match options.splits {
        Some(SplitOptions { budget, method: SplitMethod::PreSplit, .. }) => {
            let ratio = if any_triangle { 0.0 } else { crate::builders::presplit::MIN_WASTE_RATIO };
            let references = split_triangles_with(triangles, budget, ratio);
            u32::try_from(references.len()).map_err(|_| too_large(references.len()))?;
            (options.builder.build_references(&references), references.len())
        }
        Some(SplitOptions { budget, method: SplitMethod::Sbvh, .. }) => {
            let ratio = if any_triangle { 0.0 } else { crate::builders::sbvh::MIN_WASTE_RATIO };
            let params = SbvhParams { min_waste_ratio: ratio, ..SbvhParams::with_budget(budget) };
            let build = build_sbvh(triangles, &params);
            let reference_count = build.triangle_order.len();
            u32::try_from(reference_count).map_err(|_| too_large(reference_count))?;
            (build, reference_count)
        }
        None => (options.builder.build(triangles, 1), triangles.len()),
    };
    let tree = OptTree::from_build(build, triangles);
    timings.build += lap(clock);
    Ok((tree, reference_count))
}

/// The optimize and merge stages of a conversion (their times added to `timings`): reinsertion over one
/// reference a leaf, or with `clusters` over the built tree's small subtrees ([`optimize_over_clusters`]).
fn optimize_and_merge(
    mut tree: OptTree,
    reference_count: usize,
    triangle_count: usize,
    options: &ConvertOptions,
    clusters: bool,
    observer: &mut dyn FnMut(Event<'_>) -> ControlFlow<()>,
    timings: &mut Timings,
) -> Candidate {
    let _ = observer(Event::Stage(Stage::Optimize));
    let clock = Instant::now();
    let mut progress = |p: &Progress| observer(Event::Batch(p));
    let optimization = (!options.skip_optimization).then(|| match clusters {
        true => {
            let roots = cluster_roots(&tree, options.optimize.constants, DEFAULT_CLUSTER_SIZE);
            optimize_over_clusters(&mut tree, &options.optimize, &roots, &mut progress)
        }
        false => optimize(&mut tree, &options.optimize, &mut progress),
    });
    timings.optimize += lap(clock);
    let clock = Instant::now();
    tree.limit_depth(MAX_DEPTH);
    let repeats = reference_count > triangle_count;
    let (final_tree, wide_tree) = merge_and_collapse(&tree, options, triangle_count, repeats);
    drop(tree);
    timings.merge += lap(clock);
    Candidate { final_tree, wide_tree, reference_count, optimization }
}

/// How a conversion chose among candidate trees ([`SplitTriangles::Choose`], [`OptimizeOver::Choose`]).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Choice {
    /// What was compared: `wide_cost` (the wide collapse's cost, [`crate::layout::WideTree::cost`]) or `sah_cost`
    /// (the binary tree's, for files without wide sections).
    pub measure: &'static str,
    /// Every candidate made, in the order made.
    pub candidates: Vec<CandidateCost>,
    /// The index in `candidates` of the one written.
    pub kept: usize,
}

/// One candidate of a [`Choice`].
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CandidateCost {
    /// Which triangles it could cut: [`SplitTriangles::Wasteful`] or [`SplitTriangles::Any`].
    pub split_triangles: SplitTriangles,
    /// What its optimizer's leaves were: [`OptimizeOver::References`] or [`OptimizeOver::Clusters`].
    pub optimize_over: OptimizeOver,
    /// Its cost under the choice's measure.
    pub cost: f64,
}

/// The merge stage of a conversion: [`crate::layout::merge_and_collapse`] with the options' leaf size and
/// wide costs.
pub fn merge_and_collapse(
    tree: &OptTree,
    options: &ConvertOptions,
    triangle_count: usize,
    repeats: bool,
) -> (BuildTree, Option<(WideTree, WideCosts)>) {
    let leaf_size = if options.merge_leaves { options.max_leaf_size.max(1) } else { 1 };
    crate::layout::merge_and_collapse(
        tree,
        options.optimize.constants,
        leaf_size,
        options.wide,
        triangle_count,
        repeats,
    )
}

/// Fails when `output` is (the same file as) one of `inputs`.
pub fn refuse_output_among(output: &Path, inputs: &[PathBuf]) -> Result<(), ConvertError> {
    match inputs.iter().find(|input| is_same_file(output, input)) {
        Some(input) => Err(ConvertError::OutputIsInput { output: output.to_path_buf(), input: input.clone() }),
        None => Ok(()),
    }
}

/// Whether two paths name the same existing file (same device and inode on Unix, so hard links and symbolic
/// links count; the same canonical path elsewhere).
pub fn is_same_file(a: &Path, b: &Path) -> bool {
    let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) else { return false };
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        ma.dev() == mb.dev() && ma.ino() == mb.ino()
    }
    #[cfg(not(unix))]
    {
        let _ = (ma, mb);
        matches!((std::fs::canonicalize(a), std::fs::canonicalize(b)), (Ok(x), Ok(y)) if x == y)
    }
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

fn lap(start: Instant) -> f64 {
    Duration::as_secs_f64(&start.elapsed())
}

/// The metadata object (`format-spec/metadata.schema.json`): generator, format version, inputs (names relative
/// to the input, content hashes), build options, cost, what became of the scene's triangles, and the wide
/// sections' sizes and cost when there are any.
fn metadata_json(
    inputs: Vec<serde_json::Value>,
    options: &ConvertOptions,
    cost: &SahCost,
    import: &ImportReport,
    wide: Option<&WideSummary>,
    choice: Option<&Choice>,
) -> String {
    let keep = options.import.keep_degenerate;
    let dropped = |count: u64| if keep { 0 } else { count };
    let minor = bvhc_loader::format::written_minor(wide.is_some());
    let mut metadata = serde_json::json!({
        "generator": concat!("bvhc ", env!("CARGO_PKG_VERSION")),
        "format_version": format!("{}.{minor}", bvhc_loader::format::VERSION_MAJOR),
        "inputs": inputs,
        "build": options.recorded(),
        "cost": {
            "sah_cost": cost.cost,
            "c_t": options.optimize.constants.traversal,
            "c_i": options.optimize.constants.intersection,
            "inner_area_ratio": cost.inner_area_ratio,
            "leaf_area_ratio": cost.leaf_area_ratio,
        },
        "triangles": {
            "source_triangle_count": import.source_triangles,
            "stored_count": import.triangles,
            "dropped": {
                "repeated_index": dropped(import.degenerate_repeated_index),
                "zero_area": dropped(import.degenerate_zero_area),
                "zero_area_after_placement": dropped(import.degenerate_zero_area_after_placement),
            },
            "degenerate_kept": if keep { import.degenerate() } else { 0 },
        },
    });
    if let Some(wide) = wide {
        metadata["wide"] = serde_json::to_value(wide).unwrap_or_default();
    }
    if let Some(choice) = choice {
        metadata["choice"] = serde_json::to_value(choice).unwrap_or_default();
    }
    metadata.to_string()
}

/// The input files an existing output records, resolved next to `main_input` (empty when unreadable).
pub fn recorded_inputs(output: &Path, main_input: &Path) -> Vec<PathBuf> {
    let base = main_input.parent().unwrap_or(Path::new(""));
    let Ok(file) = bvhc_loader::BvhFile::read(output) else { return Vec::new() };
    let Some(Ok(text)) = file.view().metadata_str() else { return Vec::new() };
    let metadata: serde_json::Value = serde_json::from_str(text).unwrap_or_default();
    metadata["inputs"]
        .as_array()
        .map(|inputs| inputs.iter().filter_map(|e| e["file_name"].as_str()).map(|name| base.join(name)).collect())
        .unwrap_or_default()
}
