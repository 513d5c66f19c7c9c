//! `bvhc refit FILE --positions MESH -o OUTPUT`: a converted file refit to a moved pose of its asset
//! ([`bvhc::posed::placed_pose`]: its records refit and, in a two-level file, the instances a glTF node places
//! moved to the node's transform in that pose), its costs recomputed and the pose recorded as the metadata key
//! `refit` (`PlacedPose::rewritten`, so that `bvhc verify` passes and the file says what its records hold) and
//! written atomically.

use std::time::Instant;

use bvhc::import::{ErrorKind, ImportLimits};
use bvhc::loader::RebuildPolicy;
use bvhc::posed::{PosedError, placed_pose};

use super::args::RefitArgs;
use super::info::read_verified;
use super::output::{outln, print};
use super::{Exit, fail, loader_exit};

/// Runs the refit; prints a summary (or JSON) on stdout unless `--quiet`.
pub fn refit(args: &RefitArgs, threads: Option<u16>) -> Exit {
    let policy = match RebuildPolicy::new(args.max_cost_ratio) {
        Ok(policy) => policy,
        Err(why) => return fail(Exit::Usage, format!("--{}", why.replace('_', "-"))),
    };
    let file = match read_verified(&args.file) {
        Ok(file) => file,
        Err(exit) => return exit,
    };
    let pose = match placed_pose(&file.view(), &args.positions, &ImportLimits::default(), args.pose.as_ref()) {
        Ok(pose) => pose,
        Err(PosedError::Import(error)) => {
            let exit = if error.kind == ErrorKind::Unreadable { Exit::Io } else { Exit::InvalidInput };
            return fail(exit, error);
        }
        Err(error) => {
            return fail(Exit::InvalidInput, format!("{}: {error}", args.positions.display()));
        }
    };
    // The output may be FILE itself (a refit in place), never the asset or a buffer it read.
    if let Err(error) = bvhc::convert::files::refuse_output_among(&args.output, &pose.files_read) {
        return fail(Exit::Io, error);
    }
    let threads = threads.map_or_else(|| std::thread::available_parallelism().map_or(1, usize::from), usize::from);
    let mut refit = file;
    let start = Instant::now();
    let report = match pose.apply(&mut refit, threads) {
        Ok(report) => report,
        Err(error) => return fail(loader_exit(&error), format!("{}: {error}", args.file.display())),
    };
    let refit_ms = start.elapsed().as_secs_f64() * 1e3;
    let shipped = match pose.rewritten(&refit.view()) {
        Ok(shipped) => shipped,
        Err(error) => return fail(loader_exit(&error), format!("{}: {error}", args.output.display())),
    };
    if let Err(error) = bvhc::loader::write::write_atomic(&args.output, shipped.as_bytes()) {
        return fail(Exit::Io, error);
    }
    let rebuild = policy.should_rebuild(&report);
    let mut out = String::new();
    if args.json {
        let json = serde_json::json!({
            "output": args.output,
            "triangle_records": pose.positions.len(),
            "instances_placed": pose.instances.len(),
            "refit_ms": refit_ms,
            "threads": threads,
            "cost": report.cost,
            "file_cost": report.file_cost,
            "wide_cost": report.wide_cost,
            "file_wide_cost": report.file_wide_cost,
            "cost_ratio": report.cost_ratio(),
            "planned_cost_ratio": report.planned_cost_ratio,
            "rebuild_recommended": rebuild,
        });
        outln!(out, "{json:#}");
    } else if !args.quiet {
        outln!(
            out,
            "{}: {} triangle records{} refit to {} in {refit_ms:.1} ms on {threads} threads",
            args.output.display(),
            pose.positions.len(),
            match pose.instances.len() {
                0 => String::new(),
                1 => " and 1 instance".to_string(),
                n => format!(" and {n} instances"),
            },
            args.positions.display()
        );
        let costs = |now: Option<f64>, then: Option<f64>| match (now, then) {
            (Some(now), Some(then)) => format!("{then:.3} -> {now:.3}"),
            _ => "not stated".to_string(),
        };
        let planned = report
            .planned_cost_ratio
            .map_or(String::new(), |p| format!("; the animation's sampled poses reach {p:.3}"));
        outln!(
            out,
            "cost ratio {:.3} (SAH cost {}, wide cost {}{planned})",
            report.cost_ratio(),
            costs(report.cost, report.file_cost),
            costs(report.wide_cost, report.file_wide_cost)
        );
        if rebuild {
            let of = match report.planned_cost_ratio {
                Some(p) if p > 1.0 => format!("{} times the ratio the animation's poses reach", args.max_cost_ratio),
                _ => format!("{} times the converted one's", args.max_cost_ratio),
            };
            outln!(
                out,
                "note: the refit tree costs more than {of}; converting {} anew would trace faster",
                args.positions.display()
            );
        }
    }
    print(&out, Exit::Success)
}
