//! The command line's arguments.

use std::path::PathBuf;

use clap::{Args, Parser, Subcommand};

use super::camera::{Camera, parse_camera};
pub use super::option_flags::OptionArgs;

/// bvhc: an offline BVH compiler. Converts a scene into an optimized, memory-mappable .bvh file.
#[derive(Debug, Parser)]
#[command(
    version,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true,
    after_help = "Examples:\n  bvhc scene.gltf -o scene.bvh\n  bvhc scan.ply.gz -o scan.bvh --preset max-quality --json\n  \
bvhc options --preset max-quality --no-splits\n  bvhc refit character.bvh --positions posed.glb -o posed.bvh\n  bvhc verify scene.bvh\n  bvhc info scene.bvh --json\n  bvhc render scene.bvh -o scene.png --width 1024 --height 768\n\n\
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
    /// Print the options a conversion would use (a preset and flags, resolved) as JSON, without converting.
    Options(OptionsArgs),
    /// Convert many scenes in one process on all cores: a manifest of JSON lines, a directory or a glob; up-to-date
    /// outputs skipped, a failing job reported and the others finished (exit 1 when any failed).
    Batch(BatchArgs),
    /// Refit a converted file to a moved pose of its asset (the same asset exported again with moved vertices)
    /// instead of converting it again: the same tree, new boxes, the costs recomputed; written atomically.
    Refit(RefitArgs),
}

/// `bvhc batch`'s arguments.
#[derive(Debug, Args)]
pub struct BatchArgs {
    /// A manifest (JSON lines, one job a line: {"input": PATH, "output": PATH, "options": {NAME: VALUE}}, paths
    /// relative to its folder, option names as `bvhc options --list` prints them), a directory (every scene
    /// file below it) or a glob (`'assets/**/*.glb'`, quoted).
    pub source: String,
    /// For a directory or a glob: each output's path, where `{dir}` is the input's folder below the directory
    /// (or below the glob's part before its first wildcard), `{stem}` its file name without the extension and
    /// `{name}` its file name [default: SOURCE's folder/{dir}/{stem}.bvh, beside each input].
    #[arg(short, long, value_name = "PATTERN")]
    pub output: Option<String>,
    /// Convert even the outputs that are up to date.
    #[arg(long)]
    pub force: bool,
    /// Print nothing but errors.
    #[arg(long, short)]
    pub quiet: bool,
    /// Print one JSON line a job on stdout, in the jobs' order: source, input, output, status (converted,
    /// up_to_date, failed, cancelled), seconds, threads, triangles, cost, output_hash, error, error_kind.
    #[arg(long)]
    pub json: bool,
    /// Options of every job (a manifest line's options are set over them).
    #[command(flatten)]
    pub options: OptionArgs,
}

/// `bvhc refit`'s arguments.
#[derive(Debug, Args)]
pub struct RefitArgs {
    /// The .bvh file to refit, best without split references (converted with `--no-splits`); a two-level file's
    /// instances move to where the asset's nodes stand.
    pub file: PathBuf,
    /// The moved asset: the file's input exported again with the same topology (.gltf, .glb, .obj, .ply,
    /// .obj.gz or .ply.gz).
    #[arg(long, value_name = "MESH")]
    pub positions: PathBuf,
    /// Take MESH as it stands SECONDS into its animation clip CLIP (a glTF's, by index or name), not in its
    /// default pose: a pipeline refits the converted file to each pose of the clip it needs.
    #[arg(long, value_name = "CLIP@SECONDS")]
    pub pose: Option<bvhc::import::PoseSelector>,
    /// The refit .bvh file to write (atomically; may be FILE itself, never MESH or a buffer it reads).
    #[arg(short, long, value_name = "OUTPUT.bvh")]
    pub output: PathBuf,
    /// Say that converting anew would pay once the refit tree's cost exceeds the converted one's by this factor
    /// (for a tree chosen for an animation, this factor times the largest ratio its sampled poses reach).
    #[arg(long, value_name = "RATIO", default_value_t = bvhc::loader::RebuildPolicy::DEFAULT.max_cost_ratio)]
    pub max_cost_ratio: f64,
    /// Print nothing but errors.
    #[arg(long, short)]
    pub quiet: bool,
    /// Print a JSON report on stdout.
    #[arg(long)]
    pub json: bool,
}

/// `bvhc trace`'s arguments (record layouts: `format-spec/rays-and-hits.md`).
#[derive(Debug, Args)]
pub struct TraceArgs {
    /// The .bvh file.
    pub file: PathBuf,
    /// The rays: 32-byte records (origin xyz, direction xyz, t_min, t_max; little-endian f32).
    #[arg(long, value_name = "RAYS.bin")]
    pub rays: PathBuf,
    /// Where to write the hits: 24-byte records, or with --any-hit one byte per ray. A file is written atomically;
    /// a device or FIFO (`/dev/null` to time the tracing alone) is written in place.
    #[arg(short, long, value_name = "HITS.bin")]
    pub output: Option<PathBuf>,
    /// Only ask whether each ray hits anything (occlusion).
    #[arg(long)]
    pub any_hit: bool,
    /// The rays come in coherent groups (camera rays of neighbouring pixels): trace each 8 consecutive rays
    /// together (the same hit for each ray as one at a time, ties included; with split references possibly
    /// another record of the same triangle).
    #[arg(long)]
    pub coherent: bool,
    /// Trace on the GPU: the loader's WGSL kernel over the file's GPU sections (written by `--gpu-layout`), on
    /// the first wgpu adapter (a software one, such as lavapipe, included). The same hit records, `t` within
    /// `format-spec/bvh-1.md` 11.4's bound.
    #[arg(long, conflicts_with = "coherent")]
    pub gpu: bool,
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
    /// The conversion's options.
    #[command(flatten)]
    pub options: OptionArgs,
    /// The .bvh file to write (atomically).
    #[arg(short, long, required = true, value_name = "OUTPUT.bvh", help_heading = "Output")]
    pub output: Option<PathBuf>,
    /// Convert even when the output is up to date.
    #[arg(long, help_heading = "Output")]
    pub force: bool,
    /// Print nothing but errors.
    #[arg(long, short, help_heading = "Output")]
    pub quiet: bool,
    /// Print a JSON report on stdout.
    #[arg(long, help_heading = "Output")]
    pub json: bool,
}

/// `bvhc options`: the options a conversion would use, as JSON.
#[derive(Debug, Args)]
pub struct OptionsArgs {
    /// List every option instead: its flag, manifest key and Python keyword, what it takes and what each preset
    /// sets (with --json as JSON, with --markdown as the table of docs/cli.md).
    #[arg(long)]
    pub list: bool,
    /// With --list: print JSON.
    #[arg(long, requires = "list", conflicts_with = "markdown")]
    pub json: bool,
    /// With --list: print the Markdown table of docs/cli.md.
    #[arg(long, requires = "list")]
    pub markdown: bool,
    /// The conversion's options.
    #[command(flatten)]
    pub options: OptionArgs,
}

/// `bvhc render`'s arguments.
#[derive(Debug, Args)]
pub struct RenderArgs {
    /// The .bvh file.
    pub file: PathBuf,
    /// The PNG file to write (atomically; a device or FIFO in place).
    #[arg(short, long, value_name = "IMAGE.png")]
    pub output: PathBuf,
    /// Image width in pixels.
    #[arg(long, default_value_t = 800)]
    pub width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 600)]
    pub height: u32,
    /// Camera position and target, `ex,ey,ez,tx,ty,tz` (default: framing the scene).
    #[arg(long, value_name = "EX,EY,EZ,TX,TY,TZ", value_parser = parse_camera)]
    pub camera: Option<Camera>,
    /// Color pixels by traversal steps instead of shading.
    #[arg(long)]
    pub heatmap: bool,
}
