//! `bvhc INPUT -o OUTPUT`: the conversion, with a progress display on a terminal.

use std::io::IsTerminal;
use std::ops::ControlFlow;
use std::time::Duration;

use bvhc::Conversion;
use bvhc::convert::{ConvertError, Event, Stage};
use bvhc::import::ErrorKind;
use indicatif::{ProgressBar, ProgressStyle};

use super::args::ConvertArgs;
use super::output::{outln, print};
use super::{Exit, fail, loader_exit};

/// Runs the conversion; prints a summary (or JSON) on stdout unless `--quiet`.
pub fn convert(args: &ConvertArgs) -> Exit {
    let (Some(input), Some(output)) = (&args.input, &args.output) else {
        return fail(Exit::Usage, "INPUT and -o OUTPUT are required");
    };
    let settings = match args.options.settings() {
        Ok(settings) => settings,
        Err(message) => return fail(Exit::InvalidInput, message),
    };
    let keep_degenerate = settings.overrides.keep_degenerate == Some(true);
    let conversion = Conversion::new(input, output).settings(settings).force(args.force);
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
        Err(ConvertError::Options(error)) => return fail(Exit::Usage, error),
        Err(ConvertError::Import(error)) => {
            let exit = if error.kind == ErrorKind::Unreadable { Exit::Io } else { Exit::InvalidInput };
            return fail(exit, error);
        }
        Err(error @ ConvertError::OutputIsInput { .. }) => return fail(Exit::Io, error),
        Err(ConvertError::Write(error)) => return fail(loader_exit(&error).max_io(), error),
        Err(error @ ConvertError::OutOfMemory { .. }) => return fail(Exit::InvalidInput, error),
        Err(ConvertError::TooLarge { path, count }) => {
            return fail(Exit::InvalidInput, format!("{}: {count} triangles exceed the .bvh limit", path.display()));
        }
        Err(error) => return fail(Exit::Internal, error),
    };
    let output = args.output.as_deref().unwrap_or(std::path::Path::new(""));
    if !args.quiet && !args.json {
        for note in outcome.report.iter().flat_map(|r| &r.notes) {
            eprintln!("note: {note}");
        }
    }
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
                let verdict = if keep_degenerate { "kept" } else { "dropped" };
                let optimized = r.optimization.as_ref().map_or(String::new(), |o| {
                    format!(", optimized {:.2} -> {:.2} in {} batches", o.initial.cost, o.best.cost, o.batches)
                });
                // A two-level file has no cost of its own: its largest mesh's is shown, and says so.
                let (cost_of, levels) = match &r.two_level {
                    None => ("SAH cost", String::new()),
                    Some(t) => (
                        "largest mesh's SAH cost",
                        format!(
                            " in {} meshes placed by {} instances ({} triangles placed)",
                            t.mesh_count, t.instance_count, t.placed_triangle_count
                        ),
                    ),
                };
                // An animation's tree: its poses, and how far the costliest refit strays from the stored cost.
                let animation = r.animation.as_ref().map_or(String::new(), |a| {
                    let clips =
                        if a.clips.len() == 1 { "1 clip".to_string() } else { format!("{} clips", a.clips.len()) };
                    let moving = match a.moving_instances.len() {
                        0 => String::new(),
                        1 => ", 1 instance moving".to_string(),
                        n => format!(", {n} instances moving"),
                    };
                    let Some(costs) = &a.costs else {
                        return format!(", animation of {clips}{moving}");
                    };
                    let (expected, of) = match costs.expected_wide_cost {
                        Some(wide) => (wide, "wide cost"),
                        None => (costs.expected_sah_cost, "SAH cost"),
                    };
                    let deformed = if a.moving_instances.is_empty() { "" } else { " of mesh 0" };
                    format!(
                        ", {} poses of {clips}{moving}: mean refit {of}{deformed} {expected:.2}, worst {:.2}x the stored",
                        costs.poses.len(),
                        costs.worst_cost_ratio
                    )
                });
                outln!(
                    out,
                    "{}: {} triangles{levels} ({degenerate} degenerate {verdict}), {} nodes, {cost_of} {:.2}{optimized}{animation}, {} bytes, {:.2} s",
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
