//! The whole pipeline: optimized and merged trees trace like brute force, and the bytes do not depend on the
//! number of threads.

use std::path::{Path, PathBuf};

use bvhc::convert::convert_with;
use bvhc::import::{ImportOptions, import};
use bvhc::loader::{BvhFile, format::SectionKind};
use bvhc::options::ConvertOptions;
use bvhc::options::Preset;

use crate::common::{assert_matches_brute_force, every_kernel, random_rays, scene};

pub fn teapot() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj")
}

pub fn convert_in_pool(threads: usize, input: &Path, output: &Path, options: &ConvertOptions) -> Vec<u8> {
    crate::common::in_pool(threads, || {
        convert_with(input, output, options, &mut |_| std::ops::ControlFlow::Continue(())).unwrap();
    });
    std::fs::read(output).unwrap()
}

#[test]
fn output_bytes_do_not_depend_on_the_thread_count_or_the_run() {
    let dir = tempfile::tempdir().unwrap();
    for preset in Preset::ALL {
        let options = ConvertOptions::preset(preset);
        let one = convert_in_pool(1, &teapot(), &dir.path().join("one.bvh"), &options);
        let two = convert_in_pool(2, &teapot(), &dir.path().join("two.bvh"), &options);
        let again = convert_in_pool(2, &teapot(), &dir.path().join("again.bvh"), &options);
        assert!(one == two && two == again, "{preset:?}");
    }
}

fn check_scene_against_brute_force(path: &Path, preset: Preset) {
    check_conversion_against_brute_force(path, &ConvertOptions::preset(preset));
}

/// Converts `path` with `options`, verifies the file (every rule, the metadata schema) and traces random rays
/// through every kernel against brute force over the input triangles; returns the report and the file.
pub fn check_conversion_against_brute_force(
    path: &Path,
    options: &ConvertOptions,
) -> (bvhc::convert::ConvertReport, BvhFile) {
    let preset = options.preset;
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("scene.bvh");
    let report = convert_with(path, &output, options, &mut |_| std::ops::ControlFlow::Continue(())).unwrap();
    let optimization = report.optimization.as_ref().unwrap();
    assert!(optimization.best.cost <= optimization.initial.cost);
    let file = BvhFile::read(&output).unwrap();
    file.view().verify().unwrap();
    crate::common::assert_metadata_matches_schema(&file);
    let soup = import(path, &ImportOptions::default()).unwrap().soup;
    let triangles = soup.triangle_vertices();
    // The ids in the file are source ids; map them back to soup indices for the brute-force comparison.
    let index_of: std::collections::HashMap<u32, u32> =
        soup.source_ids.iter().enumerate().map(|(i, &id)| (id, i as u32)).collect();
    let ids: Vec<u32> = file.view().triangle_ids().unwrap().iter().map(|id| index_of[id]).collect();
    let root = file.view().nodes()[0];
    let center: [f32; 3] = std::array::from_fn(|a| 0.5 * (root.min[a] + root.max[a]));
    let extent = (0..3).map(|a| root.max[a] - root.min[a]).fold(0.0, f32::max);
    let rays: Vec<_> = random_rays(5, 300, 0.5 * extent)
        .into_iter()
        .map(|mut r| {
            r.origin = std::array::from_fn(|a| r.origin[a] + center[a]);
            r
        })
        .collect();
    assert!(file.view().wide_sections().is_some(), "the default conversion writes the wide sections");
    for tracer in every_kernel(&file.view()) {
        let hits = assert_matches_brute_force(&tracer, &triangles, &rays, &ids);
        assert!(hits > 30, "{:?}: {hits}", tracer.kernel());
    }
    let metadata: serde_json::Value = serde_json::from_str(file.view().metadata_str().unwrap().unwrap()).unwrap();
    let recorded = metadata["cost"]["sah_cost"].as_f64().unwrap();
    assert_eq!(recorded, report.cost.cost);
    assert_eq!(metadata["build"]["preset"], serde_json::json!(preset));
    (report, file)
}

#[test]
fn optimized_teapot_traces_like_brute_force_for_every_preset() {
    for preset in Preset::ALL {
        check_scene_against_brute_force(&teapot(), preset);
    }
}

#[test]
fn optimized_real_scenes_trace_like_brute_force() {
    for relative in ["khr-2cylinder-engine/2CylinderEngine.gltf", "stanford-bunny-ply/bun_zipper.ply"] {
        if let Some(path) = scene(relative) {
            check_scene_against_brute_force(&path, Preset::Balanced);
        }
    }
}

#[test]
fn each_conversion_writes_the_lowest_version_its_sections_need() {
    // Default: wide sections (1.1) and source vertices (1.2); without source vertices 1.1; without wide sections
    // and source vertices 1.0.
    let dir = tempfile::tempdir().unwrap();
    let (wide_path, plain_path) = (dir.path().join("wide.bvh"), dir.path().join("plain.bvh"));
    let default_options = ConvertOptions::default();
    let wide_options = ConvertOptions { write_source_vertices: false, ..ConvertOptions::default() };
    let plain_options = ConvertOptions { wide: None, ..wide_options.clone() };
    let default_bytes = convert_in_pool(1, &teapot(), &dir.path().join("default.bvh"), &default_options);
    let wide_bytes = convert_in_pool(1, &teapot(), &wide_path, &wide_options);
    let plain_bytes = convert_in_pool(1, &teapot(), &plain_path, &plain_options);
    let default = BvhFile::from_bytes(&default_bytes).unwrap();
    let (wide, plain) = (BvhFile::from_bytes(&wide_bytes).unwrap(), BvhFile::from_bytes(&plain_bytes).unwrap());
    let versions = [&default, &wide, &plain].map(|file| file.view().version());
    assert_eq!(versions, [(1, 2), (1, 1), (1, 0)]);
    assert!(default.view().source_vertices().is_some() && wide.view().source_vertices().is_none());
    assert!(wide.view().wide_sections().is_some() && plain.view().wide_sections().is_none());
    // The binary sections are the same tree either way, and the wide ones with or without source vertices.
    for other in [&wide, &plain] {
        assert_eq!(default.view().nodes(), other.view().nodes());
        assert_eq!(default.view().triangles(), other.view().triangles());
    }
    let checksums = |file: &BvhFile, kinds: [SectionKind; 2]| -> Vec<u64> {
        let view = file.view();
        view.sections()
            .filter(|s| s.kind.is_some_and(|k| kinds.contains(&k)))
            .map(|s| s.entry.section_checksum)
            .collect()
    };
    let wide_kinds = [SectionKind::WideNodes, SectionKind::TrianglePackets];
    assert_eq!(checksums(&default, wide_kinds), checksums(&wide, wide_kinds));
    assert_eq!(crate::common::assert_metadata_matches_schema(&default)["format_version"], "1.2");
    let metadata = crate::common::assert_metadata_matches_schema(&wide);
    assert_eq!(metadata["format_version"], "1.1");
    assert_eq!(metadata["build"]["wide"]["width"], 8);
    let sections = wide.view().wide_sections().unwrap();
    assert_eq!(metadata["wide"]["packet_count"], sections.packets.len());
    assert_eq!(crate::common::assert_metadata_matches_schema(&plain)["format_version"], "1.0");
    // Wide sections within 1.3x the bytes of the binary nodes and triangles they accompany.
    let binary_bytes = 32 * wide.view().nodes().len() + 36 * wide.view().triangles().len();
    let wide_bytes = 256 * sections.nodes.len() + 160 * sections.packets.len();
    assert!(wide_bytes as f64 <= 1.3 * binary_bytes as f64, "{wide_bytes} wide bytes for {binary_bytes}");
    // A file written without wide sections or source vertices is not up to date for options that want them.
    for (options, version) in [(&wide_options, (1, 1)), (&default_options, (1, 2))] {
        let report = convert_with(&teapot(), &plain_path, options, &mut |_| std::ops::ControlFlow::Continue(()));
        assert!(report.is_ok());
        assert_eq!(BvhFile::read(&plain_path).unwrap().view().version(), version);
    }
}
