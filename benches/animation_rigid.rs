//! Rigid animation, one level or two: each scene converted for its clip's poses twice, `--animation
//! --instancing never` (every moving mesh flattened and refit with the rest) and `--animation --instancing
//! always` (the meshes the clip moves rigidly kept as instances that follow their nodes), then posed at 9 times of
//! the clip (`bvhc::posed::placed_pose`) beside a fresh one-level conversion of each time (`--pose`, no split
//! references). For each: the pose's application to the file (`PlacedPose::apply`: the records refit, the moving
//! instances placed; ms, median of 5, 2 threads) and closest-hit Mrays/s of the three (200,000 uniform rays through
//! the posed scene's box, one thread, median of 5).
//!
//! Scenes: the Cesium milk truck (its wheels turn in place) and a procedural one (`common/carried_glb.rs`): the
//! Stanford bunny standing still, and the Stanford dragon (871k triangles) turned once about the vertical axis
//! while carried one dragon-length each way past it, over 10 s.
//!
//! `cargo bench --bench animation_rigid`; `BVHC_RIGID_SCENES` picks scenes.

#[path = "common/carried_glb.rs"]
mod carried_glb;
#[path = "common/harness.rs"]
mod harness;
#[path = "common/morphing_glb.rs"]
mod morphing_glb;
#[path = "common/rays.rs"]
mod rays;

use std::path::{Path, PathBuf};

use bvhc::animation::Animation;
use bvhc::import::{ClipSelector, Instancing, PoseSelector};
use bvhc::loader::BvhFile;
use bvhc::options::Overrides;

/// Converts `input` to `output`: for the poses of `clip` under `instancing`, or (`None`) at `pose` alone.
fn convert(input: &Path, output: &Path, clip: usize, instancing: Option<Instancing>, pose: &PoseSelector) -> BvhFile {
    let overrides = match instancing {
        Some(instancing) => Overrides {
            animation: Some(Animation { clips: vec![ClipSelector::Index(clip)], ..Animation::default() }),
            instancing: Some(instancing),
            ..Overrides::default()
        },
        None => Overrides {
            splits: Some(false),
            instancing: Some(Instancing::Never),
            pose: Some(bvhc::import::Pose::Clip(pose.clone())),
            ..Overrides::default()
        },
    };
    bvhc::Conversion::new(input, output).overrides(overrides).force(true).run().expect("the scene converts");
    BvhFile::read(output).expect("the conversion reads back")
}

/// `file` posed at `pose` of `asset`, and the median ms of applying the pose to a copy of it.
fn posed(file: &BvhFile, asset: &Path, pose: &PoseSelector) -> (BvhFile, f64) {
    let placed = bvhc::posed::placed_pose(&file.view(), asset, &Default::default(), Some(pose))
        .expect("the posed scene matches the file");
    let mut times = Vec::new();
    let mut moved = None;
    for _ in 0..5 {
        let mut copy = BvhFile::from_bytes(file.as_bytes()).expect("a copy");
        let start = std::time::Instant::now();
        placed.apply(&mut copy, 2).expect("the pose applies");
        times.push(start.elapsed().as_secs_f64() * 1e3);
        moved = Some(copy);
    }
    times.sort_by(f64::total_cmp);
    (moved.expect("five copies"), times[2])
}

/// Closest-hit Mrays/s of `file` over `rays` (one thread, median of 5).
fn speed(file: &BvhFile, rays: &[bvhc::loader::Ray]) -> f64 {
    harness::batch_speed(rays, &file.view().tracer(), true, false, 5)
}

/// The procedural scene's GLB, made in `dir` from the bunny and the dragon (`None` when one is missing).
fn carried(dir: &Path) -> Option<PathBuf> {
    let found = harness::scenes(
        &[("bunny", "stanford-bunny-ply/bun_zipper.ply"), ("dragon", "stanford-dragon/dragon_vrip.ply.gz")],
        None,
    );
    let [(_, bunny), (_, dragon)] = <[_; 2]>::try_from(found).ok()?;
    let import = |path: &Path| bvhc::import::import(path, &Default::default()).expect("the mesh imports").soup;
    let (bunny, dragon) = (import(&bunny), import(&dragon));
    // The bunny scaled to the dragon's height, both standing on y = 0 about the origin.
    let extent = |p: &[[f32; 3]]| {
        p.iter().fold(([f32::MAX; 3], [f32::MIN; 3]), |(lo, hi), v| {
            (std::array::from_fn(|a| lo[a].min(v[a])), std::array::from_fn(|a| hi[a].max(v[a])))
        })
    };
    let ((blo, bhi), (dlo, dhi)) = (extent(&bunny.positions), extent(&dragon.positions));
    let scale = (dhi[1] - dlo[1]) / (bhi[1] - blo[1]);
    let centred = |p: &[[f32; 3]], lo: [f32; 3], hi: [f32; 3], s: f32| -> Vec<[f32; 3]> {
        p.iter()
            .map(|v| [s * (v[0] - 0.5 * (lo[0] + hi[0])), s * (v[1] - lo[1]), s * (v[2] - 0.5 * (lo[2] + hi[2]))])
            .collect()
    };
    let still = centred(&bunny.positions, blo, bhi, scale);
    let moving = centred(&dragon.positions, dlo, dhi, 1.0);
    let path = dir.join("carried-dragon.glb");
    carried_glb::write(&path, (&still, &bunny.triangles), (&moving, &dragon.triangles), dhi[0] - dlo[0]);
    Some(path)
}

fn main() {
    if !harness::benchmarking("animation_rigid") {
        return;
    }
    let dir = tempfile::tempdir().expect("a temporary folder");
    let wanted = harness::wanted_scenes("BVHC_RIGID_SCENES");
    let mut scenes: Vec<(&str, PathBuf)> = Vec::new();
    if wanted.as_ref().is_none_or(|w| w.iter().any(|n| "Truck".starts_with(n.as_str()))) {
        scenes.extend(harness::scenes(&[("Truck", "khr-cesium-milk-truck/CesiumMilkTruck.gltf")], None));
    }
    if wanted.as_ref().is_none_or(|w| w.iter().any(|n| "Carried dragon".starts_with(n.as_str()))) {
        scenes.extend(carried(dir.path()).map(|p| ("Carried dragon", p)));
    }
    println!("Rigid animation: one level (--instancing never) or instances (--instancing always), posed at 9 times:\n");
    println!("| scene | seconds | apply ms one level / instances | Mrays/s one level / instances / fresh |");
    println!("|---|---|---|---|");
    for (name, path) in &scenes {
        let span = bvhc::import::animation_clips(path, &Default::default()).expect("the clips")[0].clone();
        let at = |j: usize| PoseSelector {
            clip: ClipSelector::Index(0),
            seconds: span.start + (span.end - span.start) * j as f64 / 8.0,
        };
        let one = convert(path, &dir.path().join("one.bvh"), 0, Some(Instancing::Never), &at(0));
        let two = convert(path, &dir.path().join("two.bvh"), 0, Some(Instancing::Always), &at(0));
        assert!(one.view().two_level().is_none() && two.view().two_level().is_some(), "{name}: one and two levels");
        let mut ratios = Vec::new();
        for j in 0..=8 {
            let pose = at(j);
            let fresh = convert(path, &dir.path().join("fresh.bvh"), 0, None, &pose);
            let (one_posed, one_ms) = posed(&one, path, &pose);
            let (two_posed, two_ms) = posed(&two, path, &pose);
            let uniform = rays::uniform_rays(&fresh.view().nodes()[0], 200_000, 11);
            let (a, b, c) = (speed(&one_posed, &uniform), speed(&two_posed, &uniform), speed(&fresh, &uniform));
            ratios.push(b / a);
            println!("| {name} | {:.2} | {one_ms:.3} / {two_ms:.3} | {a:.2} / {b:.2} / {c:.2} |", pose.seconds);
        }
        let (lo, hi) = ratios.iter().fold((f64::MAX, 0.0f64), |(lo, hi), &r| (lo.min(r), hi.max(r)));
        println!("| {name} | | | instances / one level: {lo:.2}-{hi:.2}x |");
    }
}
