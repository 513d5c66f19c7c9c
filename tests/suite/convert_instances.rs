//! Conversions that keep glTF meshes instanced (format 1.3): a generated grid of one mesh and the real scenes
//! that place meshes more than once. The two-level file traces like the flattened conversion of the same scene
//! (same placement and source triangle, `t` within the documented tolerance), its bytes do not depend on the
//! thread count, `auto` flattens what saves little, and the options refuse what would do nothing.

use bvhc_loader::Trace;
use std::path::{Path, PathBuf};

use bvhc::import::Instancing;
use bvhc::loader::{BvhFile, Ray};

use crate::common::*;

#[path = "../../benches/common/grid_scene.rs"]
mod grid_scene;

/// The teapot placed `copies` times in a grid of one GLB, written into `dir`.
pub fn teapot_grid(dir: &Path, copies: usize) -> PathBuf {
    let soup = bvhc::import::import(&crate::convert::teapot(), &Default::default()).unwrap().soup;
    let glb = dir.join(format!("teapots-x{copies}.glb"));
    grid_scene::write_grid_glb(&soup.positions, &soup.triangles, copies, &glb).unwrap();
    glb
}

fn convert(input: &Path, output: &Path, instancing: Instancing) -> bvhc::convert::ConvertReport {
    bvhc::Conversion::new(input, output).instancing(instancing).force(true).run().unwrap().report.unwrap()
}

/// Where a hit lies in the scene, comparable between a flattened and a two-level file of one glTF scene: the
/// placing node, and the triangle's index within its glTF primitive.
fn placed_source(file: &BvhFile, hit: &bvhc::loader::Hit) -> (u32, u32, u32) {
    // A mesh placed by instances is stored once, so its source ranges name no node: `node_index` takes the hit
    // instance's, which must be the node the flattened file's range names.
    let corners = file.view().source_corners(hit).expect("the file has source vertices");
    (
        corners.node_index(),
        corners.range.primitive_index,
        corners.source_triangle_id - corners.range.first_source_triangle,
    )
}

#[test]
fn a_grid_of_instances_traces_like_its_flattened_conversion() {
    let dir = tempfile::tempdir().unwrap();
    let glb = teapot_grid(dir.path(), 9);
    let (flat_path, instanced_path) = (dir.path().join("flat.bvh"), dir.path().join("instanced.bvh"));
    let flat_report = convert(&glb, &flat_path, Instancing::Never);
    let report = convert(&glb, &instanced_path, Instancing::Always);
    assert!(flat_report.two_level.is_none());
    let summary = report.two_level.expect("a two-level file");
    assert_eq!((summary.mesh_count, summary.instance_count, summary.flattened_triangle_count), (1, 9, 0));
    assert_eq!(summary.placed_triangle_count, 9 * report.triangle_count as u64);
    assert!(
        report.file_byte_len * 5 < flat_report.file_byte_len,
        "{} vs {}",
        report.file_byte_len,
        flat_report.file_byte_len
    );
    let (flat, instanced) = (BvhFile::read(&flat_path).unwrap(), BvhFile::read(&instanced_path).unwrap());
    assert_eq!(instanced.view().version(), (1, 3));
    let metadata = assert_metadata_matches_schema(&instanced);
    assert_eq!(metadata["two_level"]["instanced_meshes"], serde_json::json!([0]));
    assert_eq!(metadata["build"]["instancing"], "always");
    let (flat_tracer, tracer) = (flat.view().tracer(), instanced.view().tracer());
    let (mut compared, mut differ) = (0, 0);
    for ray in random_rays(501, 8000, 12.0)
        .iter()
        .map(|r| Ray { origin: [r.origin[0] + 8.0, r.origin[1], r.origin[2] + 8.0], ..*r })
    {
        let (expected, got) = (flat_tracer.closest_hit(&ray), tracer.closest_hit(&ray));
        assert_eq!(tracer.any_hit(&ray), got.is_some(), "{ray:?}");
        match (expected, got) {
            (None, None) => {}
            (Some(e), Some(g)) => {
                compared += 1;
                let scale = e.t.abs() + ray.origin.iter().fold(0f32, |m, c| m.max(c.abs())) / 12.0;
                assert!((e.t - g.t).abs() <= scale / 65_536.0, "{ray:?}: t {} against {}", g.t, e.t);
                differ += usize::from(placed_source(&flat, &e) != placed_source(&instanced, &g));
            }
            // A ray grazing a silhouette can meet one file's rounding of the placed triangles and not the other's.
            _ => differ += 1,
        }
    }
    assert!(compared > 1000, "{compared} of 8000 rays hit");
    // Grazing rays and ties at shared edges may name another triangle; all others agree.
    assert!(differ * 200 < compared, "{differ} of {compared} rays disagree");
}

#[test]
fn instanced_conversions_are_the_same_bytes_on_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let glb = teapot_grid(dir.path(), 4);
    let bytes = |threads: usize| {
        let output = dir.path().join(format!("t{threads}.bvh"));
        in_pool(threads, || convert(&glb, &output, Instancing::Always));
        std::fs::read(&output).unwrap()
    };
    assert_eq!(bytes(1), bytes(2));
}

#[test]
fn auto_flattens_a_mesh_whose_placements_add_few_triangles() {
    // 4 teapots add 3 x 6,320 triangles, far below a million: auto writes the flattened one-level file, byte
    // for byte what `never` writes but for the recorded option.
    let dir = tempfile::tempdir().unwrap();
    let glb = teapot_grid(dir.path(), 4);
    let output = dir.path().join("auto.bvh");
    let report = convert(&glb, &output, Instancing::Auto);
    assert!(report.two_level.is_none());
    let file = BvhFile::read(&output).unwrap();
    assert_eq!(file.view().version(), (1, 2));
    let metadata = assert_metadata_matches_schema(&file);
    assert!(metadata["build"]["instancing"].is_null() && metadata["two_level"].is_null());
}

#[test]
fn an_instancing_setting_an_obj_satisfies_by_its_nature_is_accepted_with_a_note() {
    // A build script passes one set of options to a list of mixed assets: an OBJ places each model once, so it
    // satisfies `always` and `never` alike; the conversion says so, and writes the file `auto` would.
    let dir = tempfile::tempdir().unwrap();
    let plain = dir.path().join("plain.bvh");
    bvhc::Conversion::new(crate::convert::teapot(), &plain).run().unwrap();
    for mode in [Instancing::Always, Instancing::Never] {
        let output = dir.path().join(format!("{}.bvh", mode.name()));
        let outcome = bvhc::Conversion::new(crate::convert::teapot(), &output).instancing(mode).run().unwrap();
        let notes = outcome.report.unwrap().notes;
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(
            notes[0].contains(&format!("--instancing {}", mode.name())) && notes[0].contains("nothing is instanced")
        );
        let view_of = |path: &Path| BvhFile::read(path).unwrap();
        assert_eq!(view_of(&output).view().triangles(), view_of(&plain).view().triangles(), "{}", mode.name());
    }
    // The command line prints the note on stderr and succeeds.
    let run =
        crate::cli::bvhc(&[&crate::convert::teapot(), &"-o", &dir.path().join("cli.bvh"), &"--instancing", &"never"]);
    assert!(run.status.success(), "{}", crate::cli::stderr(&run));
    assert!(crate::cli::stderr(&run).contains("note: --instancing never"), "{}", crate::cli::stderr(&run));
}

#[test]
fn real_scenes_that_place_meshes_more_than_once_convert_instanced_and_trace() {
    let scenes = [
        "khr-simple-instancing/SimpleInstancing.gltf",
        "khr-2cylinder-engine/2CylinderEngine.gltf",
        "khr-negative-scale-test/NegativeScaleTest.gltf",
        "khr-cesium-milk-truck/CesiumMilkTruck.gltf",
    ];
    let dir = tempfile::tempdir().unwrap();
    for relative in scenes {
        let Some(path) = scene(relative) else {
            crate::skips::skipped(crate::skips::Needs::Scenes, format!("{relative} (instanced conversion)"));
            continue;
        };
        let (flat_path, instanced_path) = (dir.path().join("flat.bvh"), dir.path().join("instanced.bvh"));
        let flat_report = convert(&path, &flat_path, Instancing::Never);
        let report = convert(&path, &instanced_path, Instancing::Always);
        let summary = report.two_level.expect("the scene places a mesh more than once");
        // The same triangles are placed (each placement's degenerate ones dropped the same way, except those
        // that only a placement's rounding flattens, which instancing keeps in object space).
        let flat_placed = flat_report.import.placed_triangles;
        assert!(summary.placed_triangle_count >= flat_placed, "{relative}");
        assert!(summary.placed_triangle_count <= flat_placed + flat_report.import.degenerate_zero_area_after_placement);
        let (flat, instanced) = (BvhFile::read(&flat_path).unwrap(), BvhFile::read(&instanced_path).unwrap());
        assert_metadata_matches_schema(&instanced);
        let (flat_tracer, tracer) = (flat.view().tracer(), instanced.view().tracer());
        let extent =
            flat.view().nodes()[0].max.iter().chain(&flat.view().nodes()[0].min).fold(0f32, |m, c| m.max(c.abs()));
        let (mut hits, mut differ) = (0, 0);
        for ray in random_rays(502, 3000, extent) {
            match (flat_tracer.closest_hit(&ray), tracer.closest_hit(&ray)) {
                (Some(e), Some(g)) => {
                    hits += 1;
                    let agree = placed_source(&flat, &e) == placed_source(&instanced, &g)
                        && (e.t - g.t).abs()
                            <= (e.t.abs() + 1.5 * extent / ray.direction.iter().fold(0f32, |m, c| m.max(c.abs())))
                                / 65_536.0;
                    differ += usize::from(!agree);
                }
                (None, None) => {}
                _ => differ += 1,
            }
        }
        eprintln!(
            "{relative}: {} meshes, {} instances; {hits} hits, {differ} differ",
            summary.mesh_count, summary.instance_count
        );
        assert!(hits > 100 && differ * 50 < hits, "{relative}: {differ} of {hits} rays disagree");
    }
}
