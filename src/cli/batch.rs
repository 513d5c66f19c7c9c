//! `bvhc batch SOURCE`: the jobs of a manifest, a directory or a glob converted in this process
//! (`bvhc::batch`), with a progress bar on a terminal (jobs done, triangles a second, the slowest job running),
//! a JSON line a job with `--json`, and on Ctrl-C no partial output (the finished outputs stay, the temporary
//! files of the running ones are removed).

use std::collections::BTreeMap;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use bvhc::batch::{self, BatchEvent, BatchOptions, Job, JobReport, JobStatus, jobs};
use bvhc::options::Settings;
use indicatif::{ProgressBar, ProgressStyle};

use super::args::BatchArgs;
use super::output::{outln, print};
use super::{Exit, fail, signals};

/// Runs the batch; exit 0 when every job converted or was up to date, 1 when any failed.
pub fn batch(args: &BatchArgs, threads: Option<u16>) -> Exit {
    let base = match args.options.settings() {
        Ok(settings) => settings,
        Err(error) => return fail(Exit::InvalidInput, error),
    };
    let entries = match read_jobs(args, &base) {
        Ok(found) => found,
        Err((exit, message)) => return fail(exit, message),
    };
    let jobs: Vec<Job> = entries.iter().filter_map(|e| e.as_ref().ok()).cloned().collect();
    let outputs: Vec<PathBuf> = jobs.iter().map(|j| j.output.clone()).collect();
    signals::clean_up_on_signal_in(&outputs);
    let start = Instant::now();
    let display = (std::io::stderr().is_terminal() && !args.quiet).then(|| Display::new(&jobs));
    let observe = |event: BatchEvent<'_>| {
        if let Some(display) = &display {
            display.hear(event);
        }
    };
    let options = BatchOptions { threads: threads.map_or(0, usize::from), force: args.force };
    let cancel = AtomicBool::new(false);
    let ticking = AtomicBool::new(true);
    let reports = std::thread::scope(|scope| {
        if let Some(display) = &display {
            scope.spawn(|| display.tick_while(&ticking));
        }
        let reports = batch::run(&jobs, options, &observe, &cancel);
        ticking.store(false, std::sync::atomic::Ordering::Relaxed);
        reports
    });
    if let Some(display) = &display {
        display.bar.finish_and_clear();
    }
    // In the source's order, the lines that are not jobs among them.
    let mut ran = reports.into_iter();
    let reports: Vec<JobReport> = entries
        .iter()
        .filter_map(|e| e.as_ref().map_or_else(|b| Some(JobReport::of_bad_job(b)), |_| ran.next()))
        .collect();
    report(args, &reports, start.elapsed())
}

/// The jobs of SOURCE: a manifest's lines, or a directory's or glob's scenes with outputs by the pattern.
fn read_jobs(args: &BatchArgs, base: &Settings) -> Result<Vec<Result<Job, batch::BadJob>>, (Exit, String)> {
    let source = Path::new(&args.source);
    let io = |e: std::io::Error| (Exit::Io, format!("{}: {e}", args.source));
    let (inputs, root) = if jobs::is_glob(&args.source) {
        jobs::scenes_matching(&args.source).map_err(|e| (Exit::Usage, e))?
    } else if source.is_dir() {
        (jobs::scenes_below(source).map_err(io)?, source.to_path_buf())
    } else {
        if args.output.is_some() {
            return Err((Exit::Usage, "--output is for a directory or a glob; a manifest names each output".into()));
        }
        return batch::read_manifest(source, base).map_err(io);
    };
    let default = root.join("{dir}").join("{stem}.bvh").to_string_lossy().into_owned();
    let pattern = args.output.as_deref().unwrap_or(&default);
    if !pattern.contains("{stem}") && !pattern.contains("{name}") && inputs.len() > 1 {
        return Err((Exit::Usage, format!("--output {pattern}: name each output with {{stem}} or {{name}}")));
    }
    let jobs = inputs.into_iter().map(|input| {
        let output = jobs::output_for(&input, &root, pattern);
        Ok(Job { source: input.display().to_string(), output, input, settings: base.clone() })
    });
    Ok(jobs.collect())
}

/// Prints the JSON lines or the summary and each failure; the exit code.
fn report(args: &BatchArgs, reports: &[JobReport], elapsed: Duration) -> Exit {
    let count = |status| reports.iter().filter(|r| r.status == status).count();
    let failed = count(JobStatus::Failed) + count(JobStatus::Cancelled);
    let exit = if failed > 0 { Exit::InvalidInput } else { Exit::Success };
    let mut out = String::new();
    if args.json {
        for report in reports {
            outln!(out, "{}", serde_json::to_string(report).unwrap_or_default());
        }
    } else if !args.quiet {
        let triangles: u64 =
            reports.iter().filter(|r| r.status == JobStatus::Converted).filter_map(|r| r.triangles).sum();
        outln!(
            out,
            "{} jobs in {:.2} s: {} converted ({triangles} triangles), {} up to date, {failed} failed",
            reports.len(),
            elapsed.as_secs_f64(),
            count(JobStatus::Converted),
            count(JobStatus::UpToDate)
        );
    }
    for report in reports.iter().filter(|r| r.status == JobStatus::Failed) {
        eprintln!("bvhc: error: {}: {}", report.source, report.error.as_deref().unwrap_or("failed"));
    }
    print(&out, exit)
}

/// The progress bar and what it shows.
struct Display {
    bar: ProgressBar,
    names: Vec<String>,
    start: Instant,
    /// Triangles of the jobs finished, and the jobs running with their start.
    state: Mutex<(u64, BTreeMap<usize, Instant>)>,
}

impl Display {
    fn new(jobs: &[Job]) -> Display {
        let bar = ProgressBar::new(jobs.len() as u64);
        let style = ProgressStyle::with_template("[{elapsed_precise}] {bar:30} {pos}/{len} jobs {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar());
        bar.set_style(style);
        let names = jobs.iter().map(|j| j.input.file_name().unwrap_or_default().to_string_lossy().into_owned());
        Display { bar, names: names.collect(), start: Instant::now(), state: Mutex::new((0, BTreeMap::new())) }
    }

    fn hear(&self, event: BatchEvent<'_>) {
        let mut state = self.state.lock().unwrap_or_else(|e| e.into_inner());
        match event {
            BatchEvent::Started { index, .. } => {
                state.1.insert(index, Instant::now());
            }
            BatchEvent::Finished { index, report } => {
                state.1.remove(&index);
                state.0 += report.triangles.filter(|_| report.status == JobStatus::Converted).unwrap_or(0);
                self.bar.inc(1);
            }
        }
    }

    /// Redraws the message (triangles a second, the slowest job running) until `ticking` is cleared.
    fn tick_while(&self, ticking: &AtomicBool) {
        while ticking.load(std::sync::atomic::Ordering::Relaxed) {
            let message = {
                let state = self.state.lock().unwrap_or_else(|e| e.into_inner());
                let rate = state.0 as f64 / self.start.elapsed().as_secs_f64().max(1e-3);
                let slowest = state.1.iter().min_by_key(|(_, started)| **started).map_or(String::new(), |(i, s)| {
                    format!(", slowest running: {} ({:.0} s)", self.names[*i], s.elapsed().as_secs_f64())
                });
                format!("{rate:.0} triangles/s{slowest}")
            };
            self.bar.set_message(message);
            std::thread::sleep(Duration::from_millis(200));
        }
    }
}
