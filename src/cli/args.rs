//! The command line's arguments.

use std::path::PathBuf;

use bvhc::builders::Builder;
use bvhc::import::memory::{MemoryLimit, parse_size};
use bvhc::import::{ImportLimits, Instancing, SceneSelector};
use bvhc::optimize::Selection;
use bvhc::options::{OptimizeOver, Overrides, Preset, SplitMethod, SplitTriangles};
use clap::{Args, Parser, Subcommand};

use super::camera::{Camera, parse_camera};

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
    /// Refit a converted file to a moved pose of its asset (the same asset exported again with moved vertices)
    /// instead of converting it again: the same tree, new boxes, the costs recomputed; written atomically.
    Refit(RefitArgs),
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
    /// The conversion's options.
    #[command(flatten)]
    pub options: OptionArgs,
}

/// The options of a conversion, by stage: a preset, and overrides that take effect or are refused (exit 2) when
/// another setting would make them do nothing. `bvhc options --preset NAME [flags]` prints the result.
#[derive(Debug, Args)]
pub struct OptionArgs {
    /// The preset: the option set each stage starts from (`bvhc options --preset NAME` shows it).
    #[arg(long, value_enum, default_value_t = Preset::Balanced, help_heading = "Preset")]
    pub preset: Preset,
    /// The glTF scene to convert, by index or name.
    #[arg(long, value_name = "N|NAME", help_heading = "Import")]
    pub scene: Option<String>,
    /// A glTF scene as it stands SECONDS into animation clip CLIP (index or name): node and morph weight
    /// channels sampled, skins posed by the animated joints; an OpenUSD stage at time code TIME (time samples
    /// interpolated). Default: the default pose (USD: the default time, authored defaults only).
    #[arg(long, value_name = "CLIP@SECONDS|TIME", help_heading = "Import")]
    pub pose: Option<bvhc::import::Pose>,
    /// The USD purposes whose geometry is kept besides `default` (comma-separated: render, proxy, guide).
    #[arg(long, value_name = "LIST", default_value = "render", help_heading = "Import")]
    pub purposes: bvhc::import::Purposes,
    /// Choose the tree for the scene's animation: sample poses across these clips (comma-separated indices or
    /// names; every clip when none is given) and keep the tree, stored in the default pose, whose cost averaged
    /// over the poses after a refit is lowest. Flattens the scene and makes no split references.
    #[arg(long, value_name = "CLIPS", num_args = 0..=1, default_missing_value = "", value_parser = parse_animation_clips, help_heading = "Animation")]
    pub animation: Option<String>,
    /// Poses sampled in each clip with --animation, at the middles of equal parts of its span [default: 8].
    #[arg(long, value_name = "N", requires = "animation", help_heading = "Animation")]
    pub animation_poses: Option<u32>,
    /// Sample only this part of each clip with --animation (seconds, START..END): a tree for the part that
    /// plays, or one of several trees for the parts of a long clip, switched as it plays.
    #[arg(long, value_name = "START..END", requires = "animation", help_heading = "Animation")]
    pub animation_window: Option<bvhc::animation::TimeWindow>,
    /// Keep degenerate triangles instead of dropping them.
    #[arg(long, help_heading = "Import")]
    pub keep_degenerate: bool,
    /// Import limit: bytes of any one file read, after gunzip.
    #[arg(long, value_name = "BYTES", default_value_t = ImportLimits::default().max_input_bytes, help_heading = "Import")]
    pub max_input_bytes: u64,
    /// Import limit: triangles placed (instancing multiplies), degenerate ones included.
    #[arg(long, value_name = "N", default_value_t = ImportLimits::default().max_triangles, help_heading = "Import")]
    pub max_triangles: u64,
    /// Import limit: scalar values decoded (glTF accessors, OBJ and PLY vertex coordinates).
    #[arg(long, value_name = "N", default_value_t = ImportLimits::default().max_decoded_values, help_heading = "Import")]
    pub max_decoded_values: u64,
    /// Import limit: glTF mesh placements (nodes with a mesh times their GPU instances).
    #[arg(long, value_name = "N", default_value_t = ImportLimits::default().max_placements, help_heading = "Import")]
    pub max_placements: u64,
    /// Memory the conversion may use: a size such as 8G or 512M, or `unlimited` (default: what this process
    /// may use, the smallest of available memory, its address-space limit and its cgroup's limit). A scene
    /// whose estimated peak exceeds it is refused before its triangles are held.
    #[arg(long, value_name = "SIZE", value_parser = parse_size, help_heading = "Import")]
    pub max_memory: Option<MemoryLimit>,
    /// Import limit: vertices of one OBJ or PLY polygon.
    #[arg(long, value_name = "N", default_value_t = ImportLimits::default().max_polygon_vertices, help_heading = "Import")]
    pub max_polygon_vertices: u64,
    /// Follow glTF buffer URIs that leave the input's folder (`../`, absolute paths); off by default so that an
    /// untrusted asset cannot copy other files into the output.
    #[arg(long, help_heading = "Import")]
    pub allow_outside_buffers: bool,
    /// Keep glTF meshes placed more than once as instances in a two-level file (format 1.3): auto when their
    /// extra placements add a million triangles or more, or the flattened scene would not fit in memory;
    /// always; or never (every placement flattened) [default: auto].
    #[arg(long, value_enum, help_heading = "Import")]
    pub instancing: Option<Instancing>,
    /// Which triangles the file marks not opaque (format 1.5), so that a renderer's hit filter (alpha testing)
    /// runs on their hits alone: those of glTF materials with alphaMode MASK or BLEND; none; or all
    /// [default: materials].
    #[arg(long, value_enum, help_heading = "Import")]
    pub opacity: Option<bvhc::import::Opacity>,
    /// Initial builder (without split references or with --split-method pre-split) [default: binned-sah].
    #[arg(long, value_enum, help_heading = "Build")]
    pub builder: Option<Builder>,
    /// Cut triangles into split references where that makes the tree cheaper, at most this fraction of the
    /// triangles more [default: the preset's: 0.3 with balanced and max-quality; fast makes none].
    #[arg(long, value_name = "FRACTION", value_parser = parse_split_budget, conflicts_with = "no_splits", help_heading = "Splits")]
    pub split_budget: Option<f64>,
    /// One reference a triangle: no split references, whatever the preset.
    #[arg(long, help_heading = "Splits")]
    pub no_splits: bool,
    /// Where split references are cut: during the build where children overlap, or before it [default: sbvh].
    #[arg(long, value_enum, help_heading = "Splits")]
    pub split_method: Option<SplitMethod>,
    /// Which triangles split references are cut from [default: the preset's: wasteful with balanced, choose
    /// with max-quality].
    #[arg(long, value_enum, help_heading = "Splits")]
    pub split_triangles: Option<SplitTriangles>,
    /// No split references in geometry meant to deform (glTF primitives of skinned nodes or with morph targets),
    /// whose records a refit then boxes tightly; the rest of the scene may still be cut.
    #[arg(long, help_heading = "Splits")]
    pub no_splits_deforming: bool,
    /// Skip the optimizer (the built tree is written as built).
    #[arg(long, help_heading = "Optimize")]
    pub no_optimize: bool,
    /// How the optimizer ranks nodes for reinsertion [default: comb].
    #[arg(long, value_enum, help_heading = "Optimize")]
    pub selection: Option<Selection>,
    /// Stop optimizing after this many seconds (the result then depends on the machine's speed).
    #[arg(long, value_name = "SECONDS", value_parser = parse_seconds, help_heading = "Optimize")]
    pub time_budget: Option<std::time::Duration>,
    /// What reinsertion optimizes over [default: clusters].
    #[arg(long, value_enum, help_heading = "Optimize")]
    pub optimize_over: Option<OptimizeOver>,
    /// Largest merged leaf of the binary tree [default: 8].
    #[arg(long, value_name = "N", help_heading = "Leaf layout")]
    pub max_leaf_size: Option<usize>,
    /// Keep one triangle per leaf in the binary tree (no leaf merging).
    #[arg(long, help_heading = "Leaf layout")]
    pub no_merge: bool,
    /// Omit the wide sections (8-wide nodes and triangle packets for the SIMD kernel): a format 1.0 file.
    #[arg(long, help_heading = "Leaf layout")]
    pub no_wide: bool,
    /// Tune the tree to COUNT sampled training rays (camera, ambient-occlusion and uniform rays made from the
    /// scene; at most one a triangle): the leaf merge and the wide (and GPU) collapses weigh each node by the rays
    /// that reach it instead of by its surface area, and the candidate trees (each build also unoptimized; with
    /// `--split-triangles choose` also without splits) are judged on as many held-out rays. Scenes of fewer than
    /// 1024 triangles are not sampled (the file says so).
    #[arg(long, value_name = "COUNT", help_heading = "Leaf layout")]
    pub tune_rays: Option<usize>,
    /// Tune the tree to your own rays, as --tune-rays does: a ray file of `bvhc trace` (32-byte records; a
    /// renderer can dump a frame's rays), its even-numbered rays for training and its odd-numbered ones held out
    /// to judge the candidates. The file's hash is recorded, so a changed file converts again.
    #[arg(long, value_name = "RAYS.bin", help_heading = "Leaf layout")]
    pub train_rays: Option<PathBuf>,
    /// Also write the GPU sections of format 1.4: compressed 8-wide nodes (80 bytes) and their leaf triangles
    /// with vertices (40 bytes each), which the WGSL kernel of the loader crate traces (`bvhc trace --gpu`).
    /// One-level files only.
    #[arg(long, help_heading = "Output")]
    pub gpu_layout: bool,
    /// Omit the optional triangle_ids and source_table sections (and with them the source vertices).
    #[arg(long, help_heading = "Output")]
    pub no_ids: bool,
    /// Omit the optional source_vertices section (each triangle's vertex indices in its source primitive, for
    /// interpolating the source's normals and texture coordinates; 12 bytes a triangle). Without it and without
    /// the wide sections the file is version 1.0.
    #[arg(long, help_heading = "Output")]
    pub no_source_vertices: bool,
}

impl OptionArgs {
    /// The flags as overrides of the preset: a flag not given leaves the preset's choice. Fails with a message
    /// naming the file when `--train-rays` cannot be read or holds a bad ray.
    pub fn overrides(&self) -> Result<Overrides, String> {
        let given = |flag: bool| flag.then_some(false);
        let train_rays = self.train_rays.as_deref().map(bvhc::sampling::TrainingRays::read).transpose()?;
        Ok(Overrides {
            scene: self.scene.as_ref().map(|scene| match scene.parse::<usize>() {
                Ok(index) => SceneSelector::Index(index),
                Err(_) => SceneSelector::Name(scene.clone()),
            }),
            pose: self.pose.clone(),
            purposes: Some(self.purposes),
            animation: match &self.animation {
                Some(clips) => Some(bvhc::animation::Animation {
                    clips: bvhc::animation::Animation::parse_clips(clips).map_err(|e| format!("--animation: {e}"))?,
                    poses_per_clip: self.animation_poses.unwrap_or(bvhc::animation::DEFAULT_POSES_PER_CLIP),
                    window: self.animation_window,
                }),
                None => None,
            },
            keep_degenerate: self.keep_degenerate.then_some(true),
            limits: Some(ImportLimits {
                max_input_bytes: self.max_input_bytes,
                max_triangles: self.max_triangles,
                max_decoded_values: self.max_decoded_values,
                max_placements: self.max_placements,
                max_polygon_vertices: self.max_polygon_vertices,
                max_memory: self.max_memory.unwrap_or(MemoryLimit::Detect),
            }),
            allow_buffers_outside_input_folder: self.allow_outside_buffers.then_some(true),
            instancing: self.instancing,
            opacity: self.opacity,
            builder: self.builder,
            splits: given(self.no_splits),
            split_budget: self.split_budget,
            split_method: self.split_method,
            split_triangles: self.split_triangles,
            splits_deforming: given(self.no_splits_deforming),
            optimize: given(self.no_optimize),
            selection: self.selection,
            time_budget: self.time_budget,
            optimize_over: self.optimize_over,
            merge_leaves: given(self.no_merge),
            max_leaf_size: self.max_leaf_size,
            wide: given(self.no_wide),
            gpu_layout: self.gpu_layout.then_some(true),
            tune_rays: self.tune_rays,
            train_rays,
            write_ids: given(self.no_ids),
            write_source_vertices: given(self.no_source_vertices),
        })
    }
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

/// `--animation`'s list, checked when the command line is read (an empty name is a usage error) and kept as
/// written (the conversion's options parse it again).
fn parse_animation_clips(text: &str) -> Result<String, String> {
    bvhc::animation::Animation::parse_clips(text)?;
    Ok(text.to_string())
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
