//! Converting a library: many jobs ([`jobs`]: a manifest, a directory or a glob) in one process, on all cores.
//! A pool of workers, one a core, takes the jobs largest input first; each job converts on its own rayon pool of
//! one thread while enough jobs remain to keep every worker busy, and the last ones split the cores between
//! them, so that small assets pay neither a process nor a thread pool of their own and a large one at the end
//! does not run on one core. A job's output folder is made where missing; an up-to-date output is skipped by the
//! conversion's own check; a failing job is reported and the others finish. The outputs are the bytes `bvhc INPUT -o OUTPUT` writes, whatever the split
//! (a conversion's output does not depend on its thread count).

pub mod jobs;

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::PathBuf;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Instant;

pub use jobs::{BadJob, Job, job_of_line, options_of, options_over, read_manifest};

use crate::convert::{Conversion, ConvertError};

/// How a batch runs.
#[derive(Clone, Copy, Debug, Default)]
pub struct BatchOptions {
    /// Threads in all; 0: every core.
    pub threads: usize,
    /// Convert even where the output is up to date.
    pub force: bool,
}

/// What became of a job.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum JobStatus {
    /// Converted and written.
    Converted,
    /// The output was up to date; nothing was done.
    UpToDate,
    /// Not converted: `error` says why.
    Failed,
    /// Not started: the batch was cancelled first.
    Cancelled,
}

/// A job's summary (one line of `bvhc batch --json`, one report of Python's `convert_many`).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct JobReport {
    /// Where the job came from (`manifest.jsonl:3`, or the input's path).
    pub source: String,
    /// The scene.
    pub input: PathBuf,
    /// The `.bvh` file.
    pub output: PathBuf,
    /// What became of it.
    pub status: JobStatus,
    /// Seconds the job took (the up-to-date check included).
    pub seconds: f64,
    /// Threads the job converted on.
    pub threads: usize,
    /// The source triangles the file holds (its metadata's `triangles.source_triangle_count`).
    pub triangles: Option<u64>,
    /// The binary tree's SAH cost (its metadata's `cost.sah_cost`; a two-level file has none).
    pub cost: Option<f64>,
    /// `xxh3-64:<16 hex digits>` of the output's bytes.
    pub output_hash: Option<String>,
    /// Why it failed.
    pub error: Option<String>,
    /// The kind of failure: `options`, `input`, `unreadable` (a file that cannot be read or written) or
    /// `internal`.
    pub error_kind: Option<&'static str>,
}

impl JobReport {
    /// A job that did not run or failed before converting.
    pub fn failed(source: String, input: PathBuf, output: PathBuf, error: String, kind: &'static str) -> JobReport {
        JobReport {
            source,
            input,
            output,
            status: JobStatus::Failed,
            seconds: 0.0,
            threads: 0,
            triangles: None,
            cost: None,
            output_hash: None,
            error: Some(error),
            error_kind: Some(kind),
        }
    }

    /// The report of a manifest line that is not a job.
    pub fn of_bad_job(bad: &BadJob) -> JobReport {
        JobReport::failed(bad.source.clone(), PathBuf::new(), PathBuf::new(), bad.error.clone(), "options")
    }
}

/// What a batch reports as it runs.
#[derive(Clone, Copy, Debug)]
pub enum BatchEvent<'a> {
    /// A job started.
    Started {
        /// Its index in the jobs.
        index: usize,
        /// The threads it converts on.
        threads: usize,
    },
    /// A job finished.
    Finished {
        /// Its index in the jobs.
        index: usize,
        /// What became of it.
        report: &'a JobReport,
    },
}

/// Runs `jobs`; returns one report a job, in the jobs' order. `observe` hears each start and finish (from the
/// workers' threads); once `cancel` is set no further job starts (those report [`JobStatus::Cancelled`]).
pub fn run(
    jobs: &[Job],
    options: BatchOptions,
    observe: &(dyn Fn(BatchEvent<'_>) + Sync),
    cancel: &AtomicBool,
) -> Vec<JobReport> {
    let threads = match options.threads {
        0 => std::thread::available_parallelism().map_or(1, usize::from),
        n => n,
    };
    let workers = threads.min(jobs.len()).max(1);
    // Largest inputs first, so that the long jobs do not start last; ties in the jobs' order.
    let mut order: Vec<usize> = (0..jobs.len()).collect();
    let sizes: Vec<u64> = jobs.iter().map(|j| std::fs::metadata(&j.input).map_or(0, |m| m.len())).collect();
    order.sort_by_key(|&i| std::cmp::Reverse(sizes[i]));
    let next = AtomicUsize::new(0);
    let reports: Vec<Mutex<Option<JobReport>>> = jobs.iter().map(|_| Mutex::new(None)).collect();
    // Two jobs writing one file would race: the later one is refused before anything runs.
    let mut first_writer = std::collections::HashMap::new();
    for (index, job) in jobs.iter().enumerate() {
        if let Some(earlier) = first_writer.insert(job.output.as_path(), index) {
            first_writer.insert(job.output.as_path(), earlier);
            let error = format!("{}: also the output of {}", job.output.display(), jobs[earlier].source);
            *reports[index].lock().unwrap_or_else(|e| e.into_inner()) = Some(failed(job, error, "options"));
        }
    }
    order.retain(|&i| reports[i].lock().map_or(true, |r| r.is_none()));
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| {
                let mut pools: Vec<Option<rayon::ThreadPool>> = Vec::new();
                loop {
                    let position = next.fetch_add(1, Ordering::Relaxed);
                    if position >= order.len() || cancel.load(Ordering::Relaxed) {
                        break;
                    }
                    let index = order[position];
                    // One thread a job while every worker has one to run; the last jobs share the cores.
                    let sharing = workers.min(order.len() - position);
                    let job_threads = (threads / sharing).max(1);
                    observe(BatchEvent::Started { index, threads: job_threads });
                    let report = match pool(&mut pools, job_threads) {
                        Ok(pool) => pool.install(|| run_job(&jobs[index], options.force, job_threads)),
                        Err(error) => failed(&jobs[index], format!("cannot start threads: {error}"), "internal"),
                    };
                    observe(BatchEvent::Finished { index, report: &report });
                    *reports[index].lock().unwrap_or_else(|e| e.into_inner()) = Some(report);
                }
            });
        }
    });
    reports
        .into_iter()
        .zip(jobs)
        .map(|(report, job)| {
            report.into_inner().unwrap_or_else(|e| e.into_inner()).unwrap_or_else(|| JobReport {
                status: JobStatus::Cancelled,
                error: Some("the batch was cancelled before the job started".into()),
                error_kind: None,
                ..failed(job, String::new(), "internal")
            })
        })
        .collect()
}

/// A pool of `threads` threads, made once a worker and size.
fn pool(pools: &mut Vec<Option<rayon::ThreadPool>>, threads: usize) -> Result<&rayon::ThreadPool, String> {
    if pools.len() <= threads {
        pools.resize_with(threads + 1, || None);
    }
    if pools[threads].is_none() {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().map_err(|e| e.to_string())?;
        pools[threads] = Some(pool);
    }
    Ok(pools[threads].as_ref().expect("made above"))
}

fn failed(job: &Job, error: String, kind: &'static str) -> JobReport {
    JobReport::failed(job.source.clone(), job.input.clone(), job.output.clone(), error, kind)
}

/// Converts one job on `threads` threads (0: every core), as a batch converts each of its jobs: what Python's
/// `convert_many` runs on each worker.
pub fn run_one(job: &Job, force: bool, threads: usize) -> JobReport {
    let threads = match threads {
        0 => std::thread::available_parallelism().map_or(1, usize::from),
        n => n,
    };
    match rayon::ThreadPoolBuilder::new().num_threads(threads).build() {
        Ok(pool) => pool.install(|| run_job(job, force, threads)),
        Err(error) => failed(job, format!("cannot start threads: {error}"), "internal"),
    }
}

/// Converts one job (a panic is the job's internal error, never the batch's end) and summarizes its output.
fn run_job(job: &Job, force: bool, threads: usize) -> JobReport {
    let start = Instant::now();
    // A library's outputs mirror its folders: a job's output folder is made (a single conversion refuses one
    // that is missing).
    let folder = bvhc_loader::write::directory_of(&job.output);
    if let Err(error) = std::fs::create_dir_all(folder) {
        let message =
            format!("{}: cannot create the output's folder {}: {error}", job.output.display(), folder.display());
        return failed(job, message, "unreadable");
    }
    let conversion = Conversion::new(&job.input, &job.output).settings(job.settings.clone()).force(force);
    let outcome = match catch_unwind(AssertUnwindSafe(|| conversion.run())) {
        Ok(outcome) => outcome,
        Err(_) => return failed(job, "internal error: the conversion panicked".into(), "internal"),
    };
    let mut report = match outcome {
        Ok(outcome) => {
            let status = if outcome.up_to_date { JobStatus::UpToDate } else { JobStatus::Converted };
            summarize(job, status)
        }
        Err(error) => failed(job, error.to_string(), error_kind(&error)),
    };
    report.seconds = start.elapsed().as_secs_f64();
    report.threads = threads;
    report
}

/// The kind of a conversion's failure, as the command line's exit codes divide them.
pub fn error_kind(error: &ConvertError) -> &'static str {
    match error {
        ConvertError::Options(_) => "options",
        ConvertError::Import(e) if e.kind == crate::import::ErrorKind::Unreadable => "unreadable",
        ConvertError::Import(_) | ConvertError::OutOfMemory { .. } | ConvertError::TooLarge { .. } => "input",
        ConvertError::OutputIsInput { .. } | ConvertError::Write(_) => "unreadable",
        _ => "internal",
    }
}

/// A finished job's report from its output file: hash, triangles, cost.
fn summarize(job: &Job, status: JobStatus) -> JobReport {
    let mut report = failed(job, String::new(), "internal");
    (report.status, report.error, report.error_kind) = (status, None, None);
    let Ok(bytes) = std::fs::read(&job.output) else { return report };
    report.output_hash = Some(crate::import::inputs::content_hash(&bytes));
    if let Ok(file) = bvhc_loader::BvhFile::from_bytes(&bytes) {
        let metadata = crate::inspect::metadata(&file.view());
        report.triangles = metadata["triangles"]["source_triangle_count"].as_u64();
        report.cost = metadata["cost"]["sah_cost"].as_f64();
    }
    report
}
