//! Point queries through the C API (`tests/c/capi_points.c`): the records `bvhc_closest_point`,
//! `bvhc_closest_points` and `bvhc_closest_points_filtered` write equal the Rust tracer's, one- and two-level,
//! bounded or not, and bad arguments get named errors. SKIPPED without a C compiler or the static library.

use std::path::Path;
use std::process::Command;

use bvhc::loader::{BvhFile, ClosestPoint};

use crate::capi::c_program;
use crate::cli::bvhc;
use crate::common::*;
use crate::convert::teapot;

/// The line `capi_points.c` prints for `found`.
fn line(found: Option<ClosestPoint>) -> String {
    match found {
        None => "none".to_string(),
        Some(c) => format!(
            "near {:08x} {} {} {:08x} {:08x} {:08x}",
            c.distance.to_bits(),
            c.triangle_index,
            c.instance_index.map_or(-1, |i| i as i64),
            c.point[0].to_bits(),
            c.point[1].to_bits(),
            c.point[2].to_bits()
        ),
    }
}

fn same_points_in_c_and_rust(binary: &Path, bvh: &Path, points: &[[f32; 3]], max: f32, dir: &Path) -> usize {
    let file = BvhFile::read(bvh).unwrap();
    let tracer = file.view().tracer();
    let input = dir.join("points.bin");
    std::fs::write(&input, points.iter().flatten().flat_map(|c| c.to_le_bytes()).collect::<Vec<u8>>()).unwrap();
    let bound = if max.is_infinite() { "inf".to_string() } else { format!("{max:e}") };
    let output = Command::new(binary).arg(bvh).arg(&input).arg(&bound).output().unwrap();
    assert!(output.status.success(), "capi_points failed: {}", String::from_utf8_lossy(&output.stderr));
    let text = String::from_utf8(output.stdout).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.last(), Some(&"checks ok"));
    let max: f32 = bound.parse().unwrap();
    let mut near = 0;
    for (k, (c_line, point)) in lines.iter().zip(points).enumerate() {
        let found = tracer.closest_point(*point, max);
        near += usize::from(found.is_some());
        assert_eq!(*c_line, line(found), "point {k} {point:?}");
    }
    let winding = tracer.winding_numbers().unwrap();
    for (k, (c_line, point)) in lines[points.len()..].iter().zip(points).enumerate() {
        let expected = format!(
            "signed {:08x} winding {:016x}",
            winding.signed_distance(*point).to_bits(),
            winding.winding_number(*point).to_bits()
        );
        assert_eq!(*c_line, expected, "point {k} {point:?}");
    }
    let odd = |c: &bvhc::loader::PointCandidate| c.triangle_index % 2 == 1;
    for (k, (c_line, point)) in lines[2 * points.len()..].iter().zip(points).enumerate() {
        assert_eq!(*c_line, line(tracer.closest_point_filtered(*point, max, &odd)), "filtered point {k} {point:?}");
    }
    assert_eq!(lines.len(), 3 * points.len() + 1);
    near
}

#[test]
fn c_point_queries_give_the_rust_tracers_records() {
    let dir = tempfile::tempdir().unwrap();
    let Some(binary) = c_program(dir.path(), "capi_points") else { return };
    let bvh = dir.path().join("teapot.bvh");
    assert!(bvhc(&[&teapot(), &"-o", &bvh, &"-q"]).status.success());
    let mut rng = rng(71);
    let points: Vec<[f32; 3]> = (0..2000).map(|_| random_point(&mut rng, 4.0)).collect();
    assert_eq!(same_points_in_c_and_rust(&binary, &bvh, &points, f32::INFINITY, dir.path()), points.len());
    let bounded = same_points_in_c_and_rust(&binary, &bvh, &points, 0.5, dir.path());
    assert!(bounded > 100 && bounded < points.len(), "{bounded}");
    let (scene, sources) =
        crate::instances::two_level(&crate::instances::test_meshes(), &crate::instances::test_placements(), true);
    let two_level = dir.path().join("instances.bvh");
    std::fs::write(&two_level, crate::instances::write_two_level(&scene, &sources).unwrap().as_bytes()).unwrap();
    assert_eq!(same_points_in_c_and_rust(&binary, &two_level, &points, f32::INFINITY, dir.path()), points.len());
}
