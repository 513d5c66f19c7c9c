//! Moving geometry through the C API (`tests/c/capi_refit.c` and `capi_frame.c` against the static library): a refit to bent
//! positions on two threads, per record, gives the hits and the cost ratio Rust's refit gives and writes the
//! bytes Rust's `rewritten` writes; moved instances trace as Rust's `move_instances` makes them, and their top
//! trees rebuilt as Rust's `rebuilt_top_trees` builds them, with the same costs; refusals name the record or the
//! call. SKIPPED without a C compiler or without the library.

use bvhc_loader::Trace;
use std::process::Command;

use bvhc::loader::format::Affine3x4;
use bvhc::loader::{BvhFile, Ray, RefitPositions};

use crate::capi::c_program;
use crate::cli::{bvhc, teapot};
use crate::common::random_rays;
use crate::instances::{affine, test_meshes, test_placements, two_level, write_two_level};

fn floats(values: impl Iterator<Item = f32>) -> Vec<u8> {
    values.flat_map(f32::to_le_bytes).collect()
}

/// The lines `capi_refit.c`'s `trace` prints for `file` and `rays`.
fn traced_lines(file: &BvhFile, rays: &[Ray]) -> Vec<String> {
    let tracer = file.view().tracer();
    rays.iter()
        .map(|ray| match tracer.closest_hit(ray) {
            Some(hit) => format!(
                "hit {:08x} {} {}",
                hit.t.to_bits(),
                hit.triangle_index,
                hit.instance_index.map_or(-1, |i| i as i64)
            ),
            None => "miss".to_string(),
        })
        .collect()
}

#[test]
fn a_c_program_refits_and_moves_instances_as_rust_does() {
    let dir = tempfile::tempdir().unwrap();
    let Some(binary) = c_program(dir.path(), "capi_refit") else { return };
    let one = dir.path().join("teapot.bvh");
    assert!(bvhc(&[&teapot(), &"-o", &one, &"-q", &"--no-splits"]).status.success());
    let original = BvhFile::read(&one).unwrap();
    let bend = |[x, y, z]: [f32; 3]| [x + 0.2 * y * y, y, z + 0.1 * x * y];
    let bent: Vec<[[f32; 3]; 3]> = original.view().triangles().iter().map(|t| t.vertices.map(bend)).collect();
    std::fs::write(dir.path().join("positions.bin"), floats(bent.iter().flatten().flatten().copied())).unwrap();
    let (scene, sources) = two_level(&test_meshes(), &test_placements(), true);
    let two = dir.path().join("instances.bvh");
    let two_file = write_two_level(&scene, &sources).unwrap();
    std::fs::write(&two, two_file.as_bytes()).unwrap();
    let turn = |k: usize| {
        let (s, c) = (0.2 * k as f32).sin_cos();
        affine([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]], [0.3 * k as f32, 0.0, -0.1])
    };
    let maps: Vec<Affine3x4> = (0..test_placements().len()).map(turn).collect();
    std::fs::write(dir.path().join("transforms.bin"), floats(maps.iter().flatten().flatten().copied())).unwrap();
    let rays = random_rays(63, 2000, 4.0);
    let ray_bytes = floats(rays.iter().flat_map(|r| r.origin.into_iter().chain(r.direction).chain([r.t_min, r.t_max])));
    std::fs::write(dir.path().join("rays.bin"), ray_bytes).unwrap();
    let out = dir.path().join("out.bvh");
    let run = Command::new(&binary)
        .arg(&one)
        .arg(dir.path().join("positions.bin"))
        .arg(dir.path().join("rays.bin"))
        .arg(&out)
        .arg(&two)
        .arg(dir.path().join("transforms.bin"))
        .output()
        .unwrap();
    assert!(run.status.success(), "capi_refit exit {:?}: {}", run.status.code(), String::from_utf8_lossy(&run.stderr));
    let stdout = String::from_utf8(run.stdout).unwrap();
    let mut lines = stdout.lines();
    let records = bent.len();
    let refusals = [
        format!("{} positions for {records} triangle records", records - 1),
        "triangle record 0: a coordinate that is not finite".to_string(),
        "bvhc_move_instances: cannot refit .bvh file: a one-level file has no instances to move".to_string(),
    ];
    for expected in &refusals {
        let line = lines.next().unwrap();
        assert!(line.starts_with("refused: ") && line.contains(expected.as_str()), "{line:?} lacks {expected:?}");
    }
    // Rust's refit of the same positions.
    let mut refit = BvhFile::from_bytes(original.as_bytes()).unwrap();
    let report = refit.refit(RefitPositions::Triangles(&bent), 2).unwrap();
    // A file converted without --animation plans no ratio: NaN in C, None in Rust.
    let ratio = lines.next().unwrap().strip_prefix("ratio ").unwrap().strip_suffix(" planned none").unwrap();
    let ratio: f64 = ratio.parse().unwrap();
    assert_eq!(report.planned_cost_ratio, None);
    assert_eq!(ratio.to_bits(), report.cost_ratio().to_bits(), "{ratio} vs {}", report.cost_ratio());
    let line = lines.next().unwrap();
    assert!(line.contains("positions for 2 source ranges, but the file has 1"), "{line}");
    let lines: Vec<&str> = lines.collect();
    assert_eq!(lines.len(), 3 * rays.len() + 1);
    assert_eq!(lines[..rays.len()], traced_lines(&refit, &rays)[..], "the refit file's hits");
    assert!(std::fs::read(&out).unwrap() == refit.rewritten().unwrap().as_bytes(), "bvhc_write's bytes");
    BvhFile::read(&out).unwrap().view().verify().unwrap();
    // Rust's move of the same instances.
    let mut moved = BvhFile::from_bytes(two_file.as_bytes()).unwrap();
    let moves: Vec<(u32, Affine3x4)> = maps.iter().enumerate().map(|(k, m)| (k as u32, *m)).collect();
    moved.move_instances(&moves).unwrap();
    assert_eq!(lines[rays.len()..2 * rays.len()], traced_lines(&moved, &rays)[..], "the moved instances' hits");
    // Rust's rebuild of the moved file's top trees.
    let rebuilt = moved.rebuilt_top_trees().unwrap();
    let costs = [moved.view().top_tree_cost().unwrap(), rebuilt.view().top_tree_cost().unwrap()];
    let top: Vec<f64> =
        lines[2 * rays.len()].strip_prefix("top ").unwrap().split(' ').map(|v| v.parse().unwrap()).collect();
    assert_eq!(top.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), costs.map(f64::to_bits), "{top:?} vs {costs:?}");
    assert!(costs[1] < costs[0], "the rebuilt top tree costs less: {costs:?}");
    assert_eq!(lines[2 * rays.len() + 1..], traced_lines(&rebuilt, &rays)[..], "the rebuilt top trees' hits");
    let hits = lines.iter().filter(|l| l.starts_with("hit")).count();
    assert!(hits > 200, "{hits} hits");
}

#[test]
fn a_c_program_refits_one_mesh_and_moves_instances_in_a_frame_as_rust_does() {
    let dir = tempfile::tempdir().unwrap();
    let Some(binary) = c_program(dir.path(), "capi_frame") else { return };
    let (scene, sources) = two_level(&test_meshes(), &test_placements(), true);
    let two_file = write_two_level(&scene, &sources).unwrap();
    let two = dir.path().join("instances.bvh");
    std::fs::write(&two, two_file.as_bytes()).unwrap();
    let one = dir.path().join("teapot.bvh");
    assert!(bvhc(&[&teapot(), &"-o", &one, &"-q", &"--no-splits"]).status.success());
    // Mesh 0 (the sphere) bent in its own space; every instance turned and carried.
    let mesh = two_file.view().two_level().unwrap().meshes[0];
    let range = mesh.first_triangle as usize..(mesh.first_triangle + mesh.triangle_count) as usize;
    let bend = |[x, y, z]: [f32; 3]| [x + 0.3 * y * y, y, z - 0.2 * x * y];
    let bent: Vec<[[f32; 3]; 3]> = two_file.view().triangles()[range].iter().map(|t| t.vertices.map(bend)).collect();
    std::fs::write(dir.path().join("positions.bin"), floats(bent.iter().flatten().flatten().copied())).unwrap();
    let turn = |k: usize| {
        let (s, c) = (0.3 * k as f32 + 0.1).sin_cos();
        affine([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]], [-0.2 * k as f32, 0.1, 0.4])
    };
    let maps: Vec<Affine3x4> = (0..test_placements().len()).map(turn).collect();
    std::fs::write(dir.path().join("transforms.bin"), floats(maps.iter().flatten().flatten().copied())).unwrap();
    let rays = random_rays(64, 2000, 4.0);
    let ray_bytes = floats(rays.iter().flat_map(|r| r.origin.into_iter().chain(r.direction).chain([r.t_min, r.t_max])));
    std::fs::write(dir.path().join("rays.bin"), ray_bytes).unwrap();
    let out = dir.path().join("out.bvh");
    let files = ["positions.bin", "transforms.bin", "rays.bin"].map(|f| dir.path().join(f));
    let run = Command::new(&binary).arg(&two).args(&files).arg(&out).arg(&one).output().unwrap();
    assert!(run.status.success(), "capi_frame exit {:?}: {}", run.status.code(), String::from_utf8_lossy(&run.stderr));
    let stdout = String::from_utf8(run.stdout).unwrap();
    let mut lines = stdout.lines();
    let records = bent.len();
    let refusals = [
        "bvhc_refit_mesh: cannot refit .bvh file: a one-level file has no meshes".to_string(),
        "bvhc_refit_mesh: cannot refit .bvh file: mesh 7: the file has 2 meshes".to_string(),
        format!("mesh 0: {} positions for {records} triangle records", records - 1),
        "bvhc_move_instances_in_frame: cannot refit .bvh file: a one-level file has no instances to move".to_string(),
    ];
    for expected in &refusals {
        let line = lines.next().unwrap();
        assert!(line.starts_with("refused: ") && line.contains(expected.as_str()), "{line:?} lacks {expected:?}");
    }
    // The checksums are stale until bvhc_write, as Rust's in-frame calls leave them.
    assert_eq!(lines.next(), Some("verify fails"));
    let mut moved = BvhFile::from_bytes(two_file.as_bytes()).unwrap();
    moved.refit_mesh(0, &bent, 2).unwrap();
    let moves: Vec<(u32, Affine3x4)> = maps.iter().enumerate().map(|(k, m)| (k as u32, *m)).collect();
    moved.move_instances_in_frame(&moves).unwrap();
    assert!(moved.view().verify().is_err());
    let lines: Vec<&str> = lines.collect();
    assert_eq!(lines, traced_lines(&moved, &rays), "the frame's hits");
    let hits = lines.iter().filter(|l| l.starts_with("hit")).count();
    assert!(hits > 200, "{hits} hits");
    // The mesh moved: its records are the bent ones, and the written file verifies as Rust's rewritten copy.
    let written = BvhFile::read(&out).unwrap();
    written.view().verify().unwrap();
    assert!(written.as_bytes() == moved.rewritten().unwrap().as_bytes(), "bvhc_write's bytes");
    assert_ne!(written.as_bytes(), two_file.as_bytes());
}
