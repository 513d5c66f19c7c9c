//! Trees across an animation (issue 47's evidence, the rest pose's column): each skinned scene is converted once
//! in its default pose (one-level, without split references), then, at evenly spaced times of one of its clips,
//! refit to the scene as it stands then (`bvhc::posed::record_positions` with the pose, `BvhFile::refit`) and
//! compared with a fresh conversion of that pose (`--pose`): the refit wide tree's cost over the fresh tree's
//! (section 6.1's cost; what an animation-aware tree should keep near 1), the cost ratio a `RebuildPolicy` reads
//! (refit over the file's own), and closest-hit Mrays/s of both (uniform rays through the fresh scene's box, one
//! thread, median of 5). Prints a Markdown table and each scene's worst and mean.
//!
//! `cargo bench --bench animation`; `BVHC_ANIMATION_POSES` (default 8) poses a clip, `BVHC_ANIMATION_SCENES`
//! picks scenes.

#[path = "common/harness.rs"]
mod harness;
#[path = "common/rays.rs"]
mod rays;

use std::path::Path;

use bvhc::import::{ClipSelector, Instancing, PoseSelector};
use bvhc::loader::{BvhFile, RefitPositions};
use bvhc::options::Overrides;

/// Scene, file, and the clip sampled.
const SCENES: [(&str, &str, usize); 3] = [
    ("BrainStem", "khr-brainstem/BrainStem.gltf", 0),
    ("Fox", "khr-fox/Fox.gltf", 2),
    ("CesiumMan", "khr-cesium-man/CesiumMan.gltf", 0),
];

/// One-level, no split references, at `pose` (default pose for `None`).
fn convert(input: &Path, output: &Path, pose: Option<PoseSelector>) -> BvhFile {
    let overrides =
        Overrides { splits: Some(false), instancing: Some(Instancing::Never), pose, ..Overrides::default() };
    bvhc::Conversion::new(input, output).overrides(overrides).run().expect("the scene converts");
    BvhFile::read(output).expect("the conversion reads back")
}

/// The wide tree's cost the file's metadata states.
fn wide_cost(file: &BvhFile) -> f64 {
    let text = file.view().metadata_str().expect("metadata").expect("UTF-8");
    let metadata: serde_json::Value = serde_json::from_str(text).expect("JSON");
    metadata["wide"]["cost"].as_f64().expect("a wide cost")
}

/// The length of clip `clip` of the glTF at `path`: the largest `max` of its samplers' input accessors.
fn clip_seconds(path: &Path, clip: usize) -> f64 {
    let gltf: serde_json::Value = serde_json::from_slice(&std::fs::read(path).expect("the glTF")).expect("JSON");
    let samplers = gltf["animations"][clip]["samplers"].as_array().expect("the clip's samplers");
    samplers
        .iter()
        .filter_map(|s| gltf["accessors"][s["input"].as_u64()? as usize]["max"][0].as_f64())
        .fold(0.0, f64::max)
}

/// Closest-hit Mrays/s of `file` over `rays` (one thread, median of 5).
fn speed(file: &BvhFile, rays: &[bvhc::loader::Ray]) -> f64 {
    harness::batch_speed(rays, &file.view().tracer(), true, false, 5)
}

fn main() {
    if !harness::benchmarking("animation") {
        return;
    }
    let poses: usize = std::env::var("BVHC_ANIMATION_POSES").ok().and_then(|v| v.parse().ok()).unwrap_or(8).max(2);
    let dir = tempfile::tempdir().expect("a temporary folder");
    let list: Vec<(&str, &str)> = SCENES.iter().map(|&(name, path, _)| (name, path)).collect();
    let scenes = harness::scenes(&list, Some("BVHC_ANIMATION_SCENES"));
    println!("The default pose's tree refit to {poses} poses of a clip, against a fresh conversion of each pose:\n");
    println!(
        "| scene | clip | seconds | refit cost / fresh cost | cost ratio (refit / file's own) | Mrays/s refit / fresh |"
    );
    println!("|---|---|---|---|---|---|");
    let mut summaries = Vec::new();
    for (name, path) in &scenes {
        let clip = SCENES.iter().find(|s| s.0 == *name).map_or(0, |s| s.2);
        let rest = convert(path, &dir.path().join(format!("{name}.bvh")), None);
        let duration = clip_seconds(path, clip);
        let mut against_fresh = Vec::new();
        for k in 0..poses {
            let seconds = duration * k as f64 / (poses - 1) as f64;
            let pose = PoseSelector { clip: ClipSelector::Index(clip), seconds };
            let positions = bvhc::posed::record_positions(&rest.view(), path, &Default::default(), Some(&pose))
                .expect("the posed scene matches the file");
            let mut refit = BvhFile::from_bytes(rest.as_bytes()).expect("a copy");
            let report = refit.refit(RefitPositions::Triangles(&positions), 2).expect("the pose refits");
            let fresh = convert(path, &dir.path().join(format!("{name}-{k}.bvh")), Some(pose));
            let ratio = report.wide_cost.expect("a wide cost") / wide_cost(&fresh);
            let uniform = rays::uniform_rays(&fresh.view().nodes()[0], 200_000, 11);
            println!(
                "| {name} | {clip} | {seconds:.2} | {ratio:.3} | {:.3} | {:.2} / {:.2} |",
                report.cost_ratio(),
                speed(&refit, &uniform),
                speed(&fresh, &uniform)
            );
            against_fresh.push(ratio);
        }
        let worst = against_fresh.iter().copied().fold(0.0, f64::max);
        let mean = against_fresh.iter().sum::<f64>() / against_fresh.len() as f64;
        summaries.push(format!("{name}: refit cost over fresh, worst {worst:.3}, mean {mean:.3}"));
    }
    println!();
    for summary in summaries {
        println!("{summary}");
    }
}
