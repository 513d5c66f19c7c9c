//! `bvhc batch` against one `bvhc` process a job, on a library of small assets: the shared scenes' files under
//! 50,000 triangles (`../shared/scenes/README.md`'s counts; not the Draco-compressed ones, which bvhc refuses),
//! each with four option sets, repeated to 1,000 jobs
//! (each its own output). Measures, in one run: the 1,000 jobs as sequential processes, the same through
//! `bvhc batch` (fresh outputs), `bvhc batch` again with every output up to date, and checks every batch output
//! is byte-identical to its process's. Writes the library's manifest to `target/batch-bench/library.jsonl`
//! for `crates/bvhc-py/bench/convert_many.py` (the Dask comparison).
//!
//! `cargo bench --bench batch` (`BATCH_JOBS=N` for another count).

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// The option sets each asset is converted with: as a manifest's options, and as the command line's flags.
const OPTION_SETS: [(&str, &[&str]); 4] = [
    ("{}", &[]),
    (r#"{"preset": "fast"}"#, &["--preset", "fast"]),
    (
        r#"{"preset": "fast", "no_splits": true, "max_leaf_size": 4}"#,
        &["--preset", "fast", "--no-splits", "--max-leaf-size", "4"],
    ),
    (r#"{"split_budget": 0.1, "selection": "sum"}"#, &["--split-budget", "0.1", "--selection", "sum"]),
];

fn scenes_dir() -> PathBuf {
    std::env::var_os("BVHC_SCENES")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes"))
}

/// The README's scene files under 50,000 triangles.
fn small_scenes(dir: &Path) -> Vec<PathBuf> {
    let readme = std::fs::read_to_string(dir.join("README.md")).unwrap_or_default();
    let mut found = Vec::new();
    for line in readme.lines().filter(|l| l.starts_with("| ")) {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        let (Some(file), Some(count)) = (cells.get(1), cells.get(3)) else { continue };
        // Draco-compressed geometry is refused (bvhc does not decode it): not a job of a library.
        if cells.get(4).is_some_and(|notes| notes.contains("draco")) {
            continue;
        }
        let triangles: Option<u64> = count.split_whitespace().next().and_then(|n| n.parse().ok());
        if triangles.is_some_and(|t| t > 0 && t < 50_000) && dir.join(file).is_file() {
            found.push(dir.join(file));
        }
    }
    found
}

fn main() {
    let bvhc = env!("CARGO_BIN_EXE_bvhc");
    let dir = scenes_dir();
    let scenes = small_scenes(&dir);
    if scenes.is_empty() {
        println!("SKIPPED: no scenes under 50,000 triangles in {} (set BVHC_SCENES)", dir.display());
        return;
    }
    let count: usize = std::env::var("BATCH_JOBS").ok().and_then(|n| n.parse().ok()).unwrap_or(1000);
    let work = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/batch-bench");
    let _ = std::fs::remove_dir_all(&work);
    for sub in ["processes", "batch"] {
        std::fs::create_dir_all(work.join(sub)).unwrap();
    }
    let mut manifest = String::new();
    let mut commands = Vec::new();
    for job in 0..count {
        let scene = &scenes[job % scenes.len()];
        let (options, flags) = OPTION_SETS[(job / scenes.len()) % OPTION_SETS.len()];
        let output = format!("batch/{job:04}.bvh");
        manifest.push_str(&format!(
            "{{\"input\": {}, \"output\": \"{output}\", \"options\": {options}}}\n",
            serde_json::to_string(&scene.to_string_lossy()).unwrap()
        ));
        commands.push((scene.clone(), work.join(format!("processes/{job:04}.bvh")), flags));
    }
    std::fs::write(work.join("library.jsonl"), &manifest).unwrap();
    println!(
        "library: {count} jobs over {} scenes under 50,000 triangles x {} option sets",
        scenes.len(),
        OPTION_SETS.len()
    );

    let start = Instant::now();
    let mut failed = 0;
    for (input, output, flags) in &commands {
        let status = Command::new(bvhc).arg(input).arg("-o").arg(output).args(*flags).arg("-q").status().unwrap();
        failed += usize::from(!status.success());
    }
    let processes = start.elapsed().as_secs_f64();
    println!("sequential processes: {processes:.2} s ({:.1} jobs/s; {failed} failed)", count as f64 / processes);

    let run_batch = || {
        let start = Instant::now();
        let status = Command::new(bvhc).arg("batch").arg(work.join("library.jsonl")).arg("-q").status().unwrap();
        (start.elapsed().as_secs_f64(), status.code())
    };
    let (batch, code) = run_batch();
    println!(
        "bvhc batch: {batch:.2} s ({:.1} jobs/s, exit {code:?}); {:.2}x the processes' throughput",
        count as f64 / batch,
        processes / batch
    );
    let (again, _) = run_batch();
    println!("bvhc batch, all up to date: {again:.2} s");

    let mut differ = 0;
    for job in 0..count {
        let a = std::fs::read(work.join(format!("processes/{job:04}.bvh"))).ok();
        let b = std::fs::read(work.join(format!("batch/{job:04}.bvh"))).ok();
        differ += usize::from(a != b);
    }
    println!("outputs differing between a process and the batch: {differ} of {count}");
}
