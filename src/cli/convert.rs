//! `bvhc INPUT -o OUTPUT`: the conversion, with a progress display on a terminal.

use std::io::IsTerminal;
use std::ops::ControlFlow;
use std::time::Duration;

use bvhc::Conversion;
use bvhc::builders::Builder;
use bvhc::convert::{ConvertError, Event, OptimizeOver, SplitMethod, SplitTriangles, Stage};
use bvhc::import::{ErrorKind, ImportLimits, SceneSelector};
use bvhc::optimize::{Preset, Selection};
use indicatif::{ProgressBar, ProgressStyle};

use super::args::{
    BuilderArg, ConvertArgs, OptimizeOverArg, PresetArg, SelectionArg, SplitMethodArg, SplitTrianglesArg,
};
use super::output::{outln, print};
use super::{Exit, fail, loader_exit};

fn conversion(args: &ConvertArgs) -> Result<Conversion, String> {
    let (Some(input), Some(output)) = (&args.input, &args.output) else {
        return Err("INPUT and -o OUTPUT are required".to_string());
    };
    let preset = match args.preset {
        PresetArg::Fast => Preset::Fast,
        PresetArg::Balanced => Preset::Balanced,
        PresetArg::MaxQuality => Preset::MaxQuality,
    };
    let builder = match args.builder {
        BuilderArg::BinnedSah => Builder::BinnedSah,
        BuilderArg::SpatialMedian => Builder::SpatialMedian,
    };
    let selection = match args.selection {
        SelectionArg::Comb => Selection::Comb,
        SelectionArg::Sum => Selection::Sum,
        SelectionArg::Min => Selection::Min,
        SelectionArg::Area => Selection::Area,
        SelectionArg::Random => Selection::Random,
    };
    let mut conversion = Conversion::new(input, output)
        .preset(preset)
        .builder(builder)
        .selection(selection)
        .max_leaf_size(args.max_leaf_size)
        .merge_leaves(!args.no_merge)
        .keep_degenerate(args.keep_degenerate)
        .write_ids(!args.no_ids)
        .write_wide(!args.no_wide)
        .force(args.force);
    if args.no_splits {
        conversion = conversion.splits(None);
    } else if let Some(budget) = args.split_budget {
        conversion = conversion.splits(Some(budget));
    }
    conversion = conversion.split_method(match args.split_method {
        SplitMethodArg::Sbvh => SplitMethod::Sbvh,
        SplitMethodArg::PreSplit => SplitMethod::PreSplit,
    });
    if let Some(triangles) = args.split_triangles {
        conversion = conversion.split_triangles(match triangles {
            SplitTrianglesArg::Wasteful => SplitTriangles::Wasteful,
            SplitTrianglesArg::Any => SplitTriangles::Any,
            SplitTrianglesArg::Choose => SplitTriangles::Choose,
        });
    }
    if let Some(over) = args.optimize_over {
        conversion = conversion.optimize_over(match over {
            OptimizeOverArg::References => OptimizeOver::References,
            OptimizeOverArg::Clusters => OptimizeOver::Clusters,
            OptimizeOverArg::Choose => OptimizeOver::Choose,
        });
    }
    if let Some(budget) = args.time_budget {
        conversion = conversion.time_budget(budget);
    }
    if let Some(scene) = &args.scene {
        conversion = conversion.scene(match scene.parse::<usize>() {
            Ok(index) => SceneSelector::Index(index),
            Err(_) => SceneSelector::Name(scene.clone()),
        });
    }
    conversion = conversion
        .import_limits(ImportLimits {
            max_input_bytes: args.max_input_bytes,
            max_triangles: args.max_triangles,
            max_decoded_values: args.max_decoded_values,
            max_placements: args.max_placements,
            max_polygon_vertices: args.max_polygon_vertices,
        })
        .allow_buffers_outside_input_folder(args.allow_outside_buffers);
    let mut options = conversion.current_options().clone();
    options.skip_optimization = args.no_optimize;
    conversion = conversion.options(options);
    Ok(conversion)
}

/// Runs the conversion; prints a summary (or JSON) on stdout unless `--quiet`.
pub fn convert(args: &ConvertArgs) -> Exit {
    let conversion = match conversion(args) {
        Ok(conversion) => conversion,
        Err(message) => return fail(Exit::Usage, message),
    };
    let bar = (std::io::stderr().is_terminal() && !args.quiet).then(|| {
        let bar = ProgressBar::new_spinner();
        bar.set_style(
            ProgressStyle::with_template("{spinner} [{elapsed}] {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        bar.enable_steady_tick(Duration::from_millis(100));
        bar
    });
    let mut observe = |event: Event<'_>| {
        if let Some(bar) = &bar {
            match event {
                Event::Stage(Stage::Import) => bar.set_message("importing"),
                Event::Stage(Stage::Build) => bar.set_message("building"),
                Event::Stage(Stage::Optimize) => bar.set_message("optimizing"),
                Event::Stage(Stage::Write) => bar.set_message("merging leaves, writing"),
                Event::Batch(p) => bar.set_message(format!(
                    "optimizing: batch {}, cost {:.3} (best {:.3})",
                    p.batch, p.cost, p.best_cost
                )),
            }
        }
        ControlFlow::Continue(())
    };
    let result = conversion.run_with_progress(&mut observe);
    if let Some(bar) = bar {
        bar.finish_and_clear();
    }
    let outcome = match result {
        Ok(outcome) => outcome,
        Err(ConvertError::Import(error)) => {
            let exit = if error.kind == ErrorKind::Unreadable { Exit::Io } else { Exit::InvalidInput };
            return fail(exit, error);
        }
        Err(error @ ConvertError::OutputIsInput { .. }) => return fail(Exit::Io, error),
        Err(ConvertError::Write(error)) => return fail(loader_exit(&error).max_io(), error),
        Err(ConvertError::TooLarge { path, count }) => {
            return fail(Exit::InvalidInput, format!("{}: {count} triangles exceed the .bvh limit", path.display()));
        }
        Err(error) => return fail(Exit::Internal, error),
    };
    let output = args.output.as_deref().unwrap_or(std::path::Path::new(""));
    let mut out = String::new();
    if args.json {
        let json = serde_json::json!({
            "output": output,
            "up_to_date": outcome.up_to_date,
            "files_read": outcome.files_read,
            "report": outcome.report,
        });
        outln!(out, "{json:#}");
    } else if !args.quiet {
        match &outcome.report {
            None => {
                outln!(out, "{} is up to date (same inputs, options and format); --force rebuilds it", output.display())
            }
            Some(r) => {
                let degenerate = r.import.degenerate();
                let verdict = if args.keep_degenerate { "kept" } else { "dropped" };
                let optimized = r.optimization.as_ref().map_or(String::new(), |o| {
                    format!(", optimized {:.2} -> {:.2} in {} batches", o.initial.cost, o.best.cost, o.batches)
                });
                outln!(
                    out,
                    "{}: {} triangles ({degenerate} degenerate {verdict}), {} nodes, SAH cost {:.2}{optimized}, {} bytes, {:.2} s",
                    output.display(),
                    r.triangle_count,
                    r.node_count,
                    r.cost.cost,
                    r.file_byte_len,
                    r.timings.total()
                );
            }
        }
    }
    print(&out, Exit::Success)
}

trait WriteExit {
    fn max_io(self) -> Exit;
}

impl WriteExit for Exit {
    /// A write failure is an I/O error unless the tree itself broke a rule (a bug).
    fn max_io(self) -> Exit {
        if self == Exit::InvalidInput { Exit::Internal } else { Exit::Io }
    }
}
