//! Conversion cost as scenes grow: the Stanford dragon (871k triangles) and the kitchen (232k) placed 1, 4, 9
//! and 16 times in a grid of one GLB (`common/grid_scene.rs`, generated into a temporary folder, read by the
//! real importer), each converted with the default options on 1 and on 2 threads (`--instancing auto` keeps the
//! mesh instanced once its extra copies add a million triangles; `BVHC_SCALE_INSTANCING=never` flattens
//! every copy). The table shows the triangles stored and placed and the instances written. Per size and thread count:
//! the stage times the conversion reports (import; initial build; optimization; merge: depth limit, wide
//! collapse and leaf merging; packing; writing), the optimizer's batches, the merged tree's cost, peak resident memory,
//! and per-triangle figures; the files of 1 and 2 threads must be byte-identical (checked).
//!
//! Each conversion runs in a child process of this benchmark (the binary re-runs itself), so that its peak
//! resident memory (`VmHWM`) is its own and the thread count is set for the whole process.
//!
//! `cargo bench --bench scale`; `BVHC_SCALE_SCENES=dragon,kitchen`, `BVHC_SCALE_COPIES=1,4,9,16` and
//! `BVHC_SCALE_THREADS=1,2` narrow the runs; `BVHC_SCENES` overrides the scenes folder; `BVHC_SCALE_KEEP=DIR`
//! writes the generated scenes into `DIR` and keeps them (for `perf` or `bvhc` runs on one size).

#[path = "common/harness.rs"]
mod harness;

#[path = "common/grid_scene.rs"]
mod grid_scene;

use std::ops::ControlFlow;
use std::path::Path;
use std::process::Command;

use bvhc::convert::convert_with;
use bvhc::options::ConvertOptions;

const CHILD_FLAG: &str = "--scale-child";

fn list(variable: &str, default: &str) -> Vec<String> {
    let value = std::env::var(variable).unwrap_or_else(|_| default.to_string());
    value.split(',').filter(|item| !item.is_empty()).map(String::from).collect()
}

/// The peak resident memory of this process in bytes (`VmHWM` of `/proc/self/status`; 0 where absent).
fn peak_resident_bytes() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|line| line.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
        .map_or(0, |kib| kib * 1024)
}

/// The child: converts `input` into `output` on `threads` threads and prints one line of JSON.
fn child(input: &Path, output: &Path, threads: usize) {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build_global().unwrap();
    let mut options = ConvertOptions::default();
    if std::env::var("BVHC_SCALE_INSTANCING").as_deref() == Ok("never") {
        options.import.instancing = bvhc::import::Instancing::Never;
    }
    let report = convert_with(input, output, &options, &mut |_| ControlFlow::Continue(())).unwrap();
    let optimization = report.optimization.as_ref();
    let line = serde_json::json!({
        "triangles": report.triangle_count,
        "placed": report.import.placed_triangles,
        "instances": report.two_level.map_or(0, |t| t.instance_count),
        "file_mb": report.file_byte_len as f64 / 1e6,
        "timings": report.timings,
        "batches": optimization.map_or(0, |o| o.batches),
        "optimized_cost": optimization.map_or(f64::NAN, |o| o.best.cost),
        "merged_cost": report.cost.cost,
        "peak_bytes": peak_resident_bytes(),
        "file_bytes": report.file_byte_len,
        "total_seconds": report.timings.total(),
    });
    println!("{line}");
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if let Some(at) = args.iter().position(|a| a == CHILD_FLAG) {
        let threads = args[at + 3].parse().unwrap();
        child(Path::new(&args[at + 1]), Path::new(&args[at + 2]), threads);
        return;
    }
    if !harness::benchmarking("scale") {
        return;
    }
    let work = tempfile::tempdir().unwrap();
    let keep = std::env::var_os("BVHC_SCALE_KEEP").map(std::path::PathBuf::from);
    let threads = list("BVHC_SCALE_THREADS", "1,2");
    println!(
        "| scene | copies | triangles | placed | instances | threads | import s | build s | optimize s | merge s | pack s | write s | total s | batches | merged cost | peak MB | file MB | bytes / triangle | build ns / triangle | optimize ns / triangle | same bytes |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let scenes = [
        ("dragon", "stanford-dragon/dragon_vrip.ply.gz"),
        ("kitchen", "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz"),
    ];
    for (name, path) in harness::scenes(&scenes, Some("BVHC_SCALE_SCENES")) {
        let soup = bvhc::import::import(&path, &Default::default()).unwrap().soup;
        for copies in list("BVHC_SCALE_COPIES", "1,4,9,16") {
            let copies: usize = copies.parse().unwrap();
            let glb = keep.as_deref().unwrap_or(work.path()).join(format!("{name}-x{copies}.glb"));
            grid_scene::write_grid_glb(&soup.positions, &soup.triangles, copies, &glb).unwrap();
            let mut first_file: Option<Vec<u8>> = None;
            for t in &threads {
                let output = work.path().join(format!("{name}-x{copies}-t{t}.bvh"));
                let result = Command::new(std::env::current_exe().unwrap())
                    .arg(CHILD_FLAG)
                    .arg(&glb)
                    .arg(&output)
                    .arg(t)
                    .output()
                    .unwrap();
                assert!(result.status.success(), "{}", String::from_utf8_lossy(&result.stderr));
                let line: serde_json::Value =
                    serde_json::from_slice(result.stdout.trim_ascii()).expect("the child prints one JSON line");
                let bytes = std::fs::read(&output).unwrap();
                let same = match &first_file {
                    None => {
                        first_file = Some(bytes);
                        "-".to_string()
                    }
                    Some(first) => (first == &bytes).to_string(),
                };
                std::fs::remove_file(&output).unwrap();
                print_row(name, copies, t, &line, &same);
            }
            if keep.is_none() {
                std::fs::remove_file(&glb).unwrap();
            }
        }
    }
}

fn print_row(name: &str, copies: usize, threads: &str, line: &serde_json::Value, same: &str) {
    let f = |key: &str| line["timings"][key].as_f64().unwrap_or(f64::NAN);
    let triangles = line["triangles"].as_f64().unwrap();
    let total = line["total_seconds"].as_f64().unwrap_or(f64::NAN);
    let peak = line["peak_bytes"].as_f64().unwrap();
    println!(
        "| {name} | {copies} | {triangles} | {} | {} | {threads} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {total:.2} | {} | {:.2} | {:.0} | {:.1} | {:.0} | {:.0} | {:.0} | {same} |",
        line["placed"],
        line["instances"],
        f("import"),
        f("build"),
        f("optimize"),
        f("merge"),
        f("pack"),
        f("write"),
        line["batches"],
        line["merged_cost"].as_f64().unwrap(),
        peak / 1e6,
        line["file_mb"].as_f64().unwrap_or(f64::NAN),
        peak / triangles,
        f("build") * 1e9 / triangles,
        f("optimize") * 1e9 / triangles,
    );
}
