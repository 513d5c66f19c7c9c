//! Import speed against its floor: for each scene, the median time of a full import and of a bare read (plus
//! gunzip for `.gz` files) of the same bytes, which no importer can beat.
//!
//! `cargo bench --bench import` prints a Markdown table (medians of this run). `BVHC_SCENES` overrides the
//! scenes folder.

#[path = "common/harness.rs"]
mod harness;

use std::io::Read;
use std::path::{Path, PathBuf};

use bvhc::import::{ImportOptions, import};

const SCENES: &[&str] = &[
    "stanford-dragon/dragon_vrip.ply.gz",
    "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz",
    "khr-2cylinder-engine/2CylinderEngine.gltf",
];

/// Reads every file the import read, gunzipping `.gz` ones: the floor of an import.
fn bare_read(files: &[PathBuf]) -> usize {
    files
        .iter()
        .map(|path| {
            let raw = std::fs::read(path).unwrap();
            if path.extension().is_some_and(|e| e == "gz") {
                let mut out = Vec::new();
                flate2::read::MultiGzDecoder::new(raw.as_slice()).read_to_end(&mut out).unwrap();
                out.len()
            } else {
                raw.len()
            }
        })
        .sum()
}

fn main() {
    if !harness::benchmarking("import") {
        return;
    }
    println!("| scene | triangles | bytes parsed | floor: read (+gunzip) | import | import / floor |");
    println!("|---|---|---|---|---|---|");
    let list: Vec<(&str, &str)> = SCENES.iter().map(|&relative| (relative, relative)).collect();
    for (relative, path) in harness::scenes(&list, None) {
        let options = ImportOptions::default();
        let first = import(Path::new(&path), &options).unwrap();
        let files = first.files_read.clone();
        let mut parsed = 0;
        let floor = harness::median_time(5, || parsed = bare_read(&files));
        let full = harness::median_time(5, || {
            std::hint::black_box(import(&path, &options).unwrap());
        });
        println!(
            "| {relative} | {} | {:.1} MB | {:.0} ms | {:.0} ms | {:.1} |",
            first.soup.triangles.len(),
            parsed as f64 / 1e6,
            floor.as_secs_f64() * 1e3,
            full.as_secs_f64() * 1e3,
            full.as_secs_f64() / floor.as_secs_f64()
        );
    }
}
