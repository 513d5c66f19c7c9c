//! The command line's arguments.

use std::path::PathBuf;

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
    /// Worker threads (default: all cores). The output does not depend on it.
    #[arg(long, global = true, value_name = "N")]
    pub threads: Option<usize>,
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
    #[arg(long, value_name = "SECONDS")]
    pub time_budget: Option<f64>,
    /// Keep degenerate triangles instead of dropping them.
    #[arg(long)]
    pub keep_degenerate: bool,
    /// Omit the optional triangle_ids and source_table sections.
    #[arg(long)]
    pub no_ids: bool,
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
