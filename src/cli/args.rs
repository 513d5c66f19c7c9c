//! The command line's arguments.

use std::path::PathBuf;

use bvhc::import::ImportLimits;
use clap::{Args, Parser, Subcommand, ValueEnum};

/// bvhc: an offline BVH compiler. Converts a scene into an optimized, memory-mappable .bvh file.
#[derive(Debug, Parser)]
#[command(
    version,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true,
    after_help = "Examples:\n  bvhc scene.gltf -o scene.bvh\n  bvhc scan.ply.gz -o scan.bvh --preset max-quality --json\n  \
bvhc verify scene.bvh\n  bvhc info scene.bvh --json\n  bvhc render scene.bvh -o scene.png --width 1024 --height 768\n\n\
Exit codes: 0 success (also when the output is up to date), 1 invalid input, 2 usage error,\n\
3 a file cannot be read or written, 4 internal error."
)]
pub struct Cli {
    /// A subcommand; without one, bvhc converts INPUT into OUTPUT.
    #[command(subcommand)]
    pub command: Option<Command>,
    /// The conversion's arguments.
    #[command(flatten)]
    pub convert: ConvertArgs,
    /// Worker threads, 1 to 1024 (default: all cores). The output does not depend on it.
    #[arg(long, global = true, value_name = "N", value_parser = clap::value_parser!(u16).range(1..=1024))]
    pub threads: Option<u16>,
}

/// Subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Check every validity rule of a .bvh file (exit 0 only for a valid file).
    Verify {
        /// The .bvh file.
        file: PathBuf,
    },
    /// Show a .bvh file's header, sections, tree statistics, cost and build options.
    Info {
        /// The .bvh file.
        file: PathBuf,
        /// Print JSON on stdout.
        #[arg(long)]
        json: bool,
    },
    /// Render a picture of a .bvh file with the loader's own traversal kernel.
    Render(RenderArgs),
    /// Trace a binary ray file through a .bvh file; write the hits and report rays per second.
    Trace(TraceArgs),
}

/// `bvhc trace`'s arguments (record layouts: `format-spec/rays-and-hits.md`).
#[derive(Debug, Args)]
pub struct TraceArgs {
    /// The .bvh file.
    pub file: PathBuf,
    /// The rays: 32-byte records (origin xyz, direction xyz, t_min, t_max; little-endian f32).
    #[arg(long, value_name = "RAYS.bin")]
    pub rays: PathBuf,
    /// Where to write the hits: 24-byte records, or with --any-hit one byte per ray.
    #[arg(short, long, value_name = "HITS.bin")]
    pub output: Option<PathBuf>,
    /// Only ask whether each ray hits anything (occlusion).
    #[arg(long)]
    pub any_hit: bool,
    /// The rays come in coherent groups (camera rays of neighbouring pixels): trace each 8 consecutive rays
    /// together (the same t for each ray; on a tie at it, possibly another triangle).
    #[arg(long)]
    pub coherent: bool,
    /// Print one JSON object on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `bvhc INPUT -o OUTPUT` and its options.
#[derive(Debug, Args)]
pub struct ConvertArgs {
    /// The scene: .gltf, .glb, .obj, .ply, .obj.gz or .ply.gz.
    #[arg(required = true)]
    pub input: Option<PathBuf>,
    /// The .bvh file to write (atomically).
    #[arg(short, long, required = true, value_name = "OUTPUT.bvh")]
    pub output: Option<PathBuf>,
    /// Optimizer preset.
    #[arg(long, value_enum, default_value_t = PresetArg::Balanced)]
    pub preset: PresetArg,
    /// Initial builder.
    #[arg(long, value_enum, default_value_t = BuilderArg::BinnedSah)]
    pub builder: BuilderArg,
    /// How the optimizer ranks nodes.
    #[arg(long, value_enum, default_value_t = SelectionArg::Comb)]
    pub selection: SelectionArg,
    /// Largest merged leaf.
    #[arg(long, default_value_t = 8, value_name = "N")]
    pub max_leaf_size: usize,
    /// Keep one triangle per leaf (no leaf merging).
    #[arg(long)]
    pub no_merge: bool,
    /// Skip the optimizer (initial build only).
    #[arg(long)]
    pub no_optimize: bool,
    /// Stop optimizing after this many seconds (the result then depends on the machine's speed).
    #[arg(long, value_name = "SECONDS", value_parser = parse_seconds)]
    pub time_budget: Option<std::time::Duration>,
    /// Keep degenerate triangles instead of dropping them.
    #[arg(long)]
    pub keep_degenerate: bool,
    /// Omit the optional triangle_ids and source_table sections.
    #[arg(long)]
    pub no_ids: bool,
    /// Omit the wide sections (8-wide nodes and triangle packets for the SIMD kernel): a format 1.0 file.
    #[arg(long)]
    pub no_wide: bool,
    /// Cut triangles into split references where that makes the tree cheaper, at most this fraction of the
    /// triangles more (default 0.3 with the balanced and max-quality presets; fast does not split unless given
    /// this). Measured in docs/evaluation.md.
    #[arg(long, value_name = "FRACTION", value_parser = parse_split_budget, conflicts_with = "no_splits")]
    pub split_budget: Option<f64>,
    /// One reference a triangle: no split references, whatever the preset.
    #[arg(long)]
    pub no_splits: bool,
    /// Where split references are cut: during the build where children overlap (SBVH), or before it.
    #[arg(long, value_enum, default_value_t = SplitMethodArg::Sbvh)]
    pub split_method: SplitMethodArg,
    /// Which triangles split references are cut from: only those that waste much of their box (the balanced
    /// preset's), any the method finds worth cutting, or choose by converting both and keeping the tree whose
    /// wide cost is lower (the max-quality preset's; about twice the time). Default: the preset's.
    #[arg(long, value_enum, conflicts_with = "no_splits")]
    pub split_triangles: Option<SplitTrianglesArg>,
    /// What reinsertion optimizes over: one reference a leaf, the built tree's subtrees of up to 4 references
    /// kept as built (the fast and balanced presets'), or choose by converting with both and keeping the tree
    /// whose wide cost is lower (the max-quality preset's). Default: the preset's.
    #[arg(long, value_enum)]
    pub optimize_over: Option<OptimizeOverArg>,
    /// The glTF scene to convert, by index or name.
    #[arg(long, value_name = "N|NAME")]
    pub scene: Option<String>,
    /// Convert even when the output is up to date.
    #[arg(long)]
    pub force: bool,
    /// Print nothing but errors.
    #[arg(long, short)]
    pub quiet: bool,
    /// Print a JSON report on stdout.
    #[arg(long)]
    pub json: bool,
    /// Import limit: bytes of any one file read, after gunzip.
    #[arg(long, value_name = "BYTES", default_value_t = ImportLimits::default().max_input_bytes)]
    pub max_input_bytes: u64,
    /// Import limit: triangles placed (instancing multiplies), degenerate ones included.
    #[arg(long, value_name = "N", default_value_t = ImportLimits::default().max_triangles)]
    pub max_triangles: u64,
    /// Import limit: scalar values decoded (glTF accessors, OBJ and PLY vertex coordinates).
    #[arg(long, value_name = "N", default_value_t = ImportLimits::default().max_decoded_values)]
    pub max_decoded_values: u64,
    /// Import limit: glTF mesh placements (nodes with a mesh times their GPU instances).
    #[arg(long, value_name = "N", default_value_t = ImportLimits::default().max_placements)]
    pub max_placements: u64,
    /// Import limit: vertices of one OBJ or PLY polygon.
    #[arg(long, value_name = "N", default_value_t = ImportLimits::default().max_polygon_vertices)]
    pub max_polygon_vertices: u64,
    /// Follow glTF buffer URIs that leave the input's folder (`../`, absolute paths); off by default so that an
    /// untrusted asset cannot copy other files into the output.
    #[arg(long)]
    pub allow_outside_buffers: bool,
}

/// `--time-budget`: a finite, non-negative number of seconds, at most a year.
fn parse_seconds(text: &str) -> Result<std::time::Duration, String> {
    const MAX_SECONDS: f64 = 365.0 * 24.0 * 3600.0;
    let seconds: f64 = text.trim().parse().map_err(|_| format!("'{text}' is not a number of seconds"))?;
    if !(0.0..=MAX_SECONDS).contains(&seconds) {
        return Err(format!("'{text}': expected seconds from 0 to {MAX_SECONDS} (a year)"));
    }
    Ok(std::time::Duration::from_secs_f64(seconds))
}

fn parse_split_budget(text: &str) -> Result<f64, String> {
    let budget: f64 = text.trim().parse().map_err(|_| format!("'{text}' is not a number"))?;
    if !(0.0..=bvhc::builders::MAX_BUDGET).contains(&budget) {
        return Err(format!("'{text}': expected a fraction from 0 to 4 (at most five references a triangle)"));
    }
    Ok(budget)
}

/// `bvhc render`'s arguments.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// The .bvh file.
    pub file: PathBuf,
    /// The PNG file to write.
    #[arg(short, long, value_name = "IMAGE.png")]
    pub output: PathBuf,
    /// Image width in pixels.
    #[arg(long, default_value_t = 800)]
    pub width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 600)]
    pub height: u32,
    /// Camera position and target, `ex,ey,ez,tx,ty,tz` (default: framing the scene).
    #[arg(long, value_name = "EX,EY,EZ,TX,TY,TZ")]
    pub camera: Option<String>,
    /// Color pixels by traversal steps instead of shading.
    #[arg(long)]
    pub heatmap: bool,
}

/// `--preset`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PresetArg {
    /// One sequence of parallel rounds.
    Fast,
    /// The default.
    Balanced,
    /// The lowest cost.
    MaxQuality,
}

/// `--builder`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BuilderArg {
    /// Binned SAH.
    BinnedSah,
    /// Spatial median.
    SpatialMedian,
}

/// `--split-method`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SplitMethodArg {
    /// Spatial splits during the build (Stich et al. 2009).
    Sbvh,
    /// Large triangles cut at grid planes before the build (Karras and Aila 2013).
    PreSplit,
}

/// `--split-triangles`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SplitTrianglesArg {
    /// Only triangles whose pieces could remove a large part of their box's area.
    Wasteful,
    /// Any triangle the method finds worth cutting.
    Any,
    /// Convert with both and keep the tree whose wide cost is lower.
    Choose,
}

/// `--optimize-over`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum OptimizeOverArg {
    /// One reference a leaf.
    References,
    /// The built tree's subtrees of up to 4 references, kept as built.
    Clusters,
    /// Convert with both and keep the tree whose wide cost is lower.
    Choose,
}

/// `--selection`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SelectionArg {
    /// M_COMB.
    Comb,
    /// M_SUM.
    Sum,
    /// M_MIN.
    Min,
    /// M_AREA.
    Area,
    /// Random.
    Random,
}
