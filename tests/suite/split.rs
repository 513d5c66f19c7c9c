//! Split references (`bvhc::split`): exact pieces whose boxes contain them, references inside their triangles'
//! boxes within the budget, the same references for any thread count, and conversions with splits that pass
//! every rule of the format (V25 and V35 check that the leaves holding a triangle's records cover it), trace
//! like brute force and give the same bytes on 1 and 2 threads.

use std::io::Write;
use std::path::Path;

use bvhc::builders::{References, split_triangles};
use bvhc::convert::convert_with;
use bvhc::geometry::Aabb;
use bvhc::geometry::clip::polygon_area;
use bvhc::geometry::clip::{Piece, triangle_area};
use bvhc::optimize::{OptTree, optimize};
use bvhc::options::Preset;
use bvhc::options::{ConvertOptions, SplitMethod, SplitOptions, SplitTriangles};
use rand::RngExt;

use crate::common::{in_pool, random_point, random_triangles, rng};
use crate::convert::{check_conversion_against_brute_force, convert_in_pool, teapot};

type Triangle = [[f32; 3]; 3];

/// Long, thin, tilted triangles, like the planks and pipes of architectural scenes: the ones splitting is for.
pub fn long_triangles(seed: u64, count: usize) -> Vec<Triangle> {
    let mut rng = rng(seed);
    (0..count)
        .map(|_| {
            let a: [f32; 3] = std::array::from_fn(|_| rng.random_range(-10.0..10.0));
            let along: [f32; 3] = std::array::from_fn(|_| rng.random_range(-8.0..8.0));
            let side: [f32; 3] = std::array::from_fn(|_| rng.random_range(-0.3..0.3));
            [a, std::array::from_fn(|k| a[k] + along[k]), std::array::from_fn(|k| a[k] + along[k] + side[k])]
        })
        .collect()
}

pub fn box_contains_point(aabb: &Aabb, p: [f64; 3]) -> bool {
    (0..3).all(|a| f64::from(aabb.min[a]) <= p[a] && p[a] <= f64::from(aabb.max[a]))
}

/// Cuts every triangle by random planes strictly inside each piece's box, six levels deep: every piece's box
/// contains its corners and lies inside its triangle's box, and the pieces' areas add up to the triangle's.
#[test]
fn cut_pieces_are_inside_their_boxes_and_tile_the_triangle() {
    let mut rng = rng(7);
    let mut triangles = long_triangles(3, 200);
    triangles.extend(random_triangles(4, 200, 10.0));
    for (t, vertices) in triangles.iter().enumerate() {
        let whole = Piece::of_triangle(vertices);
        let triangle_box = whole.aabb;
        let mut pieces = vec![whole];
        for _ in 0..6 {
            let mut next = Vec::new();
            for piece in pieces {
                let axis = rng.random_range(0..3);
                let (low, high) = (piece.aabb.min[axis], piece.aabb.max[axis]);
                let plane = low + rng.random_range(0.01f32..0.99) * (high - low);
                if !(low < plane && plane < high) {
                    next.push(piece);
                    continue;
                }
                let (below, above) = piece.cut(axis, plane);
                assert!(below.aabb.max[axis] <= plane && above.aabb.min[axis] >= plane, "triangle {t}: cut overlap");
                next.extend([below, above].into_iter().filter(|p| !p.corners.is_empty()));
            }
            pieces = next;
        }
        let mut total = 0.0;
        for piece in &pieces {
            assert!(triangle_box.contains(&piece.aabb), "triangle {t}: a piece's box leaves the triangle's");
            for &corner in &piece.corners {
                assert!(box_contains_point(&piece.aabb, corner), "triangle {t}: corner {corner:?} outside its box");
            }
            total += polygon_area(&piece.corners);
        }
        let area = triangle_area(vertices);
        assert!((total - area).abs() <= 1e-9 * area.max(1e-30), "triangle {t}: pieces {total} vs triangle {area}");
    }
}

fn check_references(triangles: &[Triangle], references: &References, budget: f64) {
    assert!(references.len() as f64 <= triangles.len() as f64 * (1.0 + budget), "over budget");
    assert!(references.triangle.windows(2).all(|w| w[0] <= w[1]), "ordered by triangle");
    let mut count = vec![0usize; triangles.len()];
    for (&t, aabb) in references.triangle.iter().zip(&references.aabb) {
        count[t as usize] += 1;
        let triangle_box = Aabb::of_triangle(&triangles[t as usize]);
        assert!(triangle_box.contains(aabb), "triangle {t}: reference box outside the triangle's");
        assert!((0..3).all(|a| aabb.min[a] <= aabb.max[a]), "triangle {t}: empty reference box");
    }
    assert!(count.iter().all(|&c| c >= 1), "a triangle lost");
}

#[test]
fn references_stay_in_budget_and_inside_their_triangles_and_do_not_depend_on_threads() {
    let triangles = long_triangles(11, 3000);
    for budget in [0.0, 0.1, 0.5, 2.0] {
        let split = || split_triangles(&triangles, budget);
        let one = in_pool(1, split);
        check_references(&triangles, &one, budget);
        assert_eq!(one, in_pool(2, split), "budget {budget}: 1 and 2 threads differ");
        if budget == 0.0 {
            assert_eq!(one.len(), triangles.len());
        } else {
            assert!(one.len() as f64 > triangles.len() as f64 * (1.0 + 0.5 * budget), "budget {budget} unused");
        }
    }
    // Budgets out of range: NaN and negative split nothing, a huge one stops at five references a triangle.
    assert_eq!(split_triangles(&triangles, f64::NAN).len(), triangles.len());
    assert_eq!(split_triangles(&triangles, -1.0).len(), triangles.len());
    check_references(&triangles, &split_triangles(&triangles, 1e12), bvhc::builders::MAX_BUDGET);
    // Degenerate input: no triangles, one point-like triangle.
    assert!(split_triangles(&[], 0.3).is_empty());
    let point = [[1.0f32, 1.0, 1.0]; 3];
    assert_eq!(split_triangles(&[point], 0.3).len(), 1);
}

#[test]
fn the_optimizer_keeps_every_reference_in_one_leaf() {
    let triangles = long_triangles(12, 1500);
    let references = split_triangles(&triangles, 0.5);
    let mut tree = OptTree::from_build(bvhc::builders::Builder::BinnedSah.build_references(&references), &triangles);
    tree.check_reference_invariants(&references).unwrap();
    optimize(&mut tree, &Preset::Fast.optimize_params(), &mut |_| std::ops::ControlFlow::Continue(()));
    tree.check_reference_invariants(&references).unwrap();
    // And the check notices a reference lost.
    let fewer = References { triangle: references.triangle[1..].to_vec(), aabb: references.aabb[1..].to_vec() };
    assert!(tree.check_reference_invariants(&fewer).is_err());
}

fn write_obj(path: &Path, triangles: &[Triangle]) {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    for t in triangles {
        for v in t {
            writeln!(out, "v {} {} {}", v[0], v[1], v[2]).unwrap();
        }
    }
    for i in 0..triangles.len() {
        writeln!(out, "f {} {} {}", 3 * i + 1, 3 * i + 2, 3 * i + 3).unwrap();
    }
}

/// Axis-aligned rectangles, each as its two triangles (each fills half of its box's face: the case where
/// cutting is worth it on some scenes and not on others), spread over a few planes at random sizes.
fn rectangles(seed: u64, count: usize) -> Vec<Triangle> {
    let mut rng = rng(seed);
    let mut triangles = Vec::new();
    for i in 0..count {
        let [x, y, _] = random_point(&mut rng, 20.0);
        let [w, h, _] = random_point(&mut rng, 6.0).map(|c| c.abs() + 0.05);
        let z = (i % 5) as f32 * 2.0;
        let (a, b, c, d) = ([x, y, z], [x + w, y, z], [x + w, y + h, z], [x, y + h, z]);
        let rotate = |p: [f32; 3]| if i % 3 == 0 { [p[2], p[0], p[1]] } else { p };
        triangles.push([a, b, c].map(rotate));
        triangles.push([a, c, d].map(rotate));
    }
    triangles
}

/// The six faces of `boxes` random axis-aligned boxes (a room and its furniture), each face tiled by a grid of
/// rectangles as two triangles each, like floors and walls of architectural scenes.
fn tiled_boxes(seed: u64, boxes: usize) -> Vec<Triangle> {
    let mut rng = rng(seed);
    let mut triangles = Vec::new();
    for b in 0..boxes {
        let (min, size) = if b == 0 {
            ([-20.0f32; 3], [40.0f32; 3])
        } else {
            (random_point(&mut rng, 15.0), random_point(&mut rng, 4.0).map(|c| c.abs() + 0.5))
        };
        for axis in 0..3 {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for side in [0.0, 1.0] {
                let tiles = 8;
                for i in 0..tiles {
                    for j in 0..tiles {
                        let corner = |di: f32, dj: f32| {
                            let mut p = [0.0f32; 3];
                            p[axis] = min[axis] + side * size[axis];
                            p[u] = min[u] + (i as f32 + di) / tiles as f32 * size[u];
                            p[v] = min[v] + (j as f32 + dj) / tiles as f32 * size[v];
                            p
                        };
                        let (a, b, c, d) = (corner(0.0, 0.0), corner(1.0, 0.0), corner(1.0, 1.0), corner(0.0, 1.0));
                        triangles.push([a, b, c]);
                        triangles.push([a, c, d]);
                    }
                }
            }
        }
    }
    triangles
}

/// `SplitTriangles::Choose` writes the tree of whichever of `Wasteful` and `Any` has the lower wide cost: its
/// nodes, triangles and wide sections are that conversion's byte for byte, the costs it records are the two
/// conversions' own, it gives the same bytes on 1 and 2 threads and traces like brute force. On these scenes `Any` cuts triangles that
/// `Wasteful` leaves whole, and each choice is made on some scene (rectangles scattered at random sizes: `Any`;
/// tiled walls: `Wasteful`, as on the kitchen).
#[test]
fn choosing_which_triangles_to_cut_keeps_the_cheaper_of_both_conversions() {
    let dir = tempfile::tempdir().unwrap();
    let quads = dir.path().join("quads.obj");
    let mut triangles = rectangles(21, 700);
    triangles.extend(long_triangles(22, 100));
    write_obj(&quads, &triangles);
    let mixed = dir.path().join("mixed.obj");
    let mut triangles = rectangles(23, 300);
    triangles.extend(random_triangles(24, 2000, 10.0));
    write_obj(&mixed, &triangles);
    let room = dir.path().join("room.obj");
    write_obj(&room, &tiled_boxes(25, 12));
    let sections = |file: &bvhc::loader::BvhFile| {
        let view = file.view();
        let wide = view.wide_sections().unwrap();
        let bytes: [Vec<u8>; 4] = [
            bytemuck::cast_slice(view.nodes()).to_vec(),
            bytemuck::cast_slice(view.triangles()).to_vec(),
            bytemuck::cast_slice(wide.nodes).to_vec(),
            bytemuck::cast_slice(wide.packets).to_vec(),
        ];
        bytes
    };
    // The expected choice is this data's (seeded), so that both ways of choosing are exercised.
    for (input, expected) in
        [(quads, SplitTriangles::Any), (mixed, SplitTriangles::Any), (room, SplitTriangles::Wasteful)]
    {
        let convert = |triangles: SplitTriangles| {
            let options = ConvertOptions {
                splits: Some(SplitOptions { triangles, ..SplitOptions::with_budget(0.3) }),
                // One reference a leaf, for which the expected choices below were found.
                reinsertion: Some(bvhc::options::OptimizeOver::References),
                ..ConvertOptions::default()
            };
            let output = dir.path().join(format!("{}.bvh", triangles.name()));
            let report = convert_with(&input, &output, &options, &mut |_| std::ops::ControlFlow::Continue(())).unwrap();
            (report, bvhc::loader::BvhFile::read(&output).unwrap(), options)
        };
        let (wasteful, wasteful_file, _) = convert(SplitTriangles::Wasteful);
        let (any, any_file, _) = convert(SplitTriangles::Any);
        let (chosen, chosen_file, options) = convert(SplitTriangles::Choose);
        assert!(any.reference_count > wasteful.reference_count, "{input:?}: Any cut nothing more");
        let choice = chosen.choice.expect("a choice was made");
        let (wasteful_cost, any_cost) = (wasteful.wide.unwrap().cost, any.wide.unwrap().cost);
        let costs: Vec<(&str, f64)> = choice.candidates.iter().map(|c| (c.split_triangles, c.cost)).collect();
        assert_eq!(costs, [("wasteful", wasteful_cost), ("any", any_cost)]);
        let (kept, kept_file) = if any_cost < wasteful_cost {
            (SplitTriangles::Any, &any_file)
        } else {
            (SplitTriangles::Wasteful, &wasteful_file)
        };
        assert_eq!(kept, expected, "{input:?}: wasteful {wasteful_cost}, any {any_cost}");
        assert_eq!(choice.candidates[choice.kept].split_triangles, kept.name());
        assert!(sections(&chosen_file) == sections(kept_file), "{input:?}: not the kept conversion's tree");
        assert_eq!(chosen.wide.unwrap().cost, wasteful_cost.min(any_cost));
        let one = convert_in_pool(1, &input, &dir.path().join("one.bvh"), &options);
        let two = convert_in_pool(2, &input, &dir.path().join("two.bvh"), &options);
        assert!(one == two, "{input:?}: 1 and 2 threads differ");
        check_conversion_against_brute_force(&input, &options);
        // Cancelling the first candidate's optimization writes that candidate, with no choice recorded.
        let cancelled = dir.path().join("cancelled.bvh");
        let mut stop = |event: bvhc::convert::Event<'_>| match event {
            bvhc::convert::Event::Batch(_) => std::ops::ControlFlow::Break(()),
            _ => std::ops::ControlFlow::Continue(()),
        };
        let report = convert_with(&input, &cancelled, &options, &mut stop).unwrap();
        assert!(report.choice.is_none());
        assert_eq!(report.reference_count, wasteful.reference_count, "{input:?}: not the first candidate");
        let file = bvhc::loader::BvhFile::read(&cancelled).unwrap();
        file.view().verify().unwrap();
        let metadata: serde_json::Value = serde_json::from_str(file.view().metadata_str().unwrap().unwrap()).unwrap();
        assert!(metadata.get("choice").is_none());
    }
}

/// Conversions that optimize over clusters, or choose between that and references, with and without split
/// references, verify, trace like brute force and give the same bytes on 1 and 2 threads.
#[test]
fn conversions_over_clusters_trace_like_brute_force_and_do_not_depend_on_threads() {
    use bvhc::options::OptimizeOver;
    let dir = tempfile::tempdir().unwrap();
    let mixed = dir.path().join("mixed.obj");
    let mut triangles = rectangles(31, 300);
    triangles.extend(random_triangles(32, 2000, 10.0));
    write_obj(&mixed, &triangles);
    for input in [teapot(), mixed] {
        for (over, splits) in [
            (OptimizeOver::Clusters, Preset::Balanced.splits()),
            (OptimizeOver::Clusters, None),
            (OptimizeOver::Choose, Preset::Balanced.splits()),
        ] {
            let options = ConvertOptions { reinsertion: Some(over), splits, ..ConvertOptions::default() };
            let (report, _) = check_conversion_against_brute_force(&input, &options);
            assert_eq!(report.choice.is_some(), over == OptimizeOver::Choose);
            let one = convert_in_pool(1, &input, &dir.path().join("one.bvh"), &options);
            let two = convert_in_pool(2, &input, &dir.path().join("two.bvh"), &options);
            assert!(one == two, "{input:?} {over:?}: 1 and 2 threads differ");
        }
        // Without optimization there is nothing to choose between.
        let options = ConvertOptions { reinsertion: None, ..ConvertOptions::default() };
        let output = dir.path().join("unoptimized.bvh");
        let report = convert_with(&input, &output, &options, &mut |_| std::ops::ControlFlow::Continue(())).unwrap();
        assert!(report.choice.is_none() && report.optimization.is_none());
    }
}

#[test]
fn conversions_with_splits_verify_trace_like_brute_force_and_do_not_depend_on_threads() {
    let dir = tempfile::tempdir().unwrap();
    let long = dir.path().join("long.obj");
    write_obj(&long, &long_triangles(13, 2000));
    let mixed = dir.path().join("mixed.obj");
    let mut triangles = long_triangles(15, 300);
    triangles.extend(random_triangles(16, 3000, 10.0));
    write_obj(&mixed, &triangles);
    let (pre_split, sbvh) = (SplitMethod::PreSplit, SplitMethod::Sbvh);
    for (input, preset, method) in [
        (teapot(), Preset::Balanced, pre_split),
        (long.clone(), Preset::Fast, pre_split),
        (long, Preset::MaxQuality, pre_split),
        (mixed.clone(), Preset::Balanced, sbvh),
        (mixed, Preset::Fast, sbvh),
    ] {
        let options = ConvertOptions {
            splits: Some(SplitOptions { method, ..SplitOptions::with_budget(0.5) }),
            ..ConvertOptions::preset(preset)
        };
        let (report, file) = check_conversion_against_brute_force(&input, &options);
        assert!(report.reference_count > report.triangle_count, "{input:?}: nothing split");
        assert!(report.stored_triangle_count <= report.reference_count);
        assert_eq!(report.stored_triangle_count, file.view().triangles().len());
        let repeated = report.stored_triangle_count > report.triangle_count;
        assert_eq!(file.view().has_split_references(), repeated, "{input:?}: SPLIT_REFERENCES iff a repeat");
        let metadata: serde_json::Value = serde_json::from_str(file.view().metadata_str().unwrap().unwrap()).unwrap();
        assert_eq!(metadata["build"]["splits"]["budget"], 0.5);
        let one = convert_in_pool(1, &input, &dir.path().join("one.bvh"), &options);
        let two = convert_in_pool(2, &input, &dir.path().join("two.bvh"), &options);
        assert!(one == two, "{input:?} {preset:?} {method:?}: 1 and 2 threads differ");
    }
    // Without splits nothing is recorded, so files keep the bytes they had; the fast preset does not split.
    let metadata_of = |file: &bvhc::loader::BvhFile| -> serde_json::Value {
        serde_json::from_str(file.view().metadata_str().unwrap().unwrap()).unwrap()
    };
    for options in [ConvertOptions { splits: None, ..ConvertOptions::default() }, ConvertOptions::preset(Preset::Fast)]
    {
        let (_, file) = check_conversion_against_brute_force(&teapot(), &options);
        assert!(metadata_of(&file)["build"].get("splits").is_none());
        assert!(!file.view().has_split_references());
    }
    // The default (balanced) and max-quality presets allow the SBVH 30% more references.
    for preset in [Preset::Balanced, Preset::MaxQuality] {
        let (report, file) = check_conversion_against_brute_force(&teapot(), &ConvertOptions::preset(preset));
        let splits = &metadata_of(&file)["build"]["splits"];
        assert_eq!((splits["budget"].as_f64(), splits["method"].as_str()), (Some(0.3), Some("sbvh")));
        assert!(report.reference_count as f64 <= 1.3 * report.triangle_count as f64);
    }
}

/// `bvhc --split-budget` converts with splits; `bvhc info` counts records and distinct triangles.
#[test]
fn the_cli_splits_on_request_and_info_counts_references() {
    let dir = tempfile::tempdir().unwrap();
    let long = dir.path().join("long.obj");
    write_obj(&long, &long_triangles(14, 500));
    let output = dir.path().join("long.bvh");
    let run = crate::cli::bvhc(&[&long, &"-o", &output, &"--split-budget", &"0.5", &"--json", &"--quiet"]);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let report: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let stored = report["report"]["stored_triangle_count"].as_u64().unwrap();
    assert!(stored > 500 && report["report"]["reference_count"].as_u64().unwrap() >= stored);
    let info = crate::cli::bvhc(&[&"info", &output, &"--json"]);
    let info: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    assert_eq!(info["reference_count"].as_u64(), Some(stored));
    assert_eq!(info["unique_triangle_count"], 500);
    assert_eq!(info["split_references"], true);
    let text = String::from_utf8(crate::cli::bvhc(&[&"info", &output]).stdout).unwrap();
    assert!(text.contains(&format!("split references: {stored} records of 500 triangles")), "{text}");
    // Either method, recorded in the metadata (the SBVH unless told).
    for (flags, method) in [(vec![], "sbvh"), (vec!["--split-method", "pre-split"], "pre_split")] {
        let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> =
            vec![&long, &"-o", &output, &"--split-budget", &"0.5", &"--force", &"--quiet"];
        args.extend(flags.iter().map(|f| f as &dyn AsRef<std::ffi::OsStr>));
        let run = crate::cli::bvhc(&args);
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        let file = bvhc::loader::BvhFile::read(&output).unwrap();
        let metadata: serde_json::Value = serde_json::from_str(file.view().metadata_str().unwrap().unwrap()).unwrap();
        assert_eq!(metadata["build"]["splits"]["method"], method);
    }
    // --split-triangles and --optimize-over, recorded; the max-quality preset chooses the triangles unless told,
    // and records the choice (two candidates; four when also told to choose the optimizer's leaves).
    for (flags, triangles, candidates) in [
        (vec!["--split-triangles", "any"], Some("any"), 0),
        (vec!["--preset", "max-quality"], Some("choose"), 2),
        (vec!["--preset", "max-quality", "--optimize-over", "choose"], Some("choose"), 4),
        (vec!["--preset", "max-quality", "--split-triangles", "wasteful", "--optimize-over", "references"], None, 0),
        (vec!["--optimize-over", "choose"], None, 2),
    ] {
        let mut args: Vec<&dyn AsRef<std::ffi::OsStr>> = vec![&long, &"-o", &output, &"--force", &"--quiet"];
        args.extend(flags.iter().map(|f| f as &dyn AsRef<std::ffi::OsStr>));
        let run = crate::cli::bvhc(&args);
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        let file = bvhc::loader::BvhFile::read(&output).unwrap();
        let metadata: serde_json::Value = serde_json::from_str(file.view().metadata_str().unwrap().unwrap()).unwrap();
        assert_eq!(metadata["build"]["splits"]["triangles"].as_str(), triangles, "{flags:?}");
        let made = metadata["choice"]["candidates"].as_array().map_or(0, |c| c.len());
        assert_eq!(made, candidates, "{flags:?}");
        let info = String::from_utf8(crate::cli::bvhc(&[&"info", &output]).stdout).unwrap();
        assert_eq!(info.contains("choice by wide_cost: kept "), candidates > 0, "{info}");
    }
    let both = crate::cli::bvhc(&[&long, &"-o", &output, &"--no-splits", &"--split-triangles", &"any"]);
    assert!(!both.status.success(), "--no-splits with --split-triangles accepted");
    // --no-splits: one reference a triangle even with a preset that splits.
    let run = crate::cli::bvhc(&[&long, &"-o", &output, &"--no-splits", &"--force", &"--json", &"--quiet"]);
    let report: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    assert_eq!(report["report"]["reference_count"], 500);
    let both = crate::cli::bvhc(&[&long, &"-o", &output, &"--no-splits", &"--split-budget", &"0.1"]);
    assert!(!both.status.success(), "--no-splits with --split-budget accepted");
    // A budget out of range is refused before any work.
    let refused = crate::cli::bvhc(&[&long, &"-o", &output, &"--split-budget", &"9"]);
    assert!(!refused.status.success() && String::from_utf8_lossy(&refused.stderr).contains("fraction from 0 to 4"));
}
