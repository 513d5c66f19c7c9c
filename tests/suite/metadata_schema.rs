//! Every kind of file bvhc writes validates against `format-spec/metadata.schema.json`: every preset, builder,
//! leaf setting, id setting, degenerate handling and input format; and the schema is strict enough to reject
//! what it should.

use std::ops::ControlFlow;
use std::path::PathBuf;

use bvhc::builders::Builder;
use bvhc::convert::convert_with;
use bvhc::import::SceneSelector;
use bvhc::loader::BvhFile;
use bvhc::options::Preset;
use bvhc::options::{ConvertOptions, LeafMerge, OptimizeOver, SplitMethod, SplitOptions, SplitTriangles};

use crate::common::{assert_metadata_matches_schema, scene};
use crate::hardening::repro;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures").join(name)
}

fn convert_and_check(input: &std::path::Path, options: &ConvertOptions) -> serde_json::Value {
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("out.bvh");
    convert_with(input, &output, options, &mut |_| ControlFlow::Continue(())).unwrap();
    assert_metadata_matches_schema(&BvhFile::read(&output).unwrap())
}

#[test]
fn every_written_file_matches_the_metadata_schema() {
    let teapot = fixture("scenes/teapot.obj");
    for preset in Preset::ALL {
        convert_and_check(&teapot, &ConvertOptions::preset(preset));
    }
    // The GPU sections of 1.4 and their `build.gpu` key.
    let gpu = ConvertOptions { gpu: Some(bvhc::layout::GpuCosts::default()), ..ConvertOptions::default() };
    let metadata = convert_and_check(&teapot, &gpu);
    assert_eq!(metadata["format_version"], "1.4");
    assert_eq!(metadata["build"]["gpu"]["max_leaf_size"], 3);
    let mut options = ConvertOptions::preset(Preset::Fast);
    options.builder = Builder::SpatialMedian;
    options.leaves = LeafMerge::Off;
    let metadata = convert_and_check(&teapot, &options);
    assert_eq!(metadata["build"]["max_leaf_size"], 1, "one triangle per leaf is recorded as such");
    // Without ids, and so without source vertices (which name vertices of the primitive an id leads to).
    options.write_ids = false;
    options.write_source_vertices = false;
    options.reinsertion = None;
    options.optimize.time_budget = Some(std::time::Duration::from_millis(1500));
    let metadata = convert_and_check(&teapot, &options);
    assert_eq!(metadata["build"]["write_source_vertices"], false);
    // Split references, by either method.
    for method in [SplitMethod::Sbvh, SplitMethod::PreSplit] {
        let split = ConvertOptions {
            splits: Some(SplitOptions { method, ..SplitOptions::with_budget(0.3) }),
            ..ConvertOptions::default()
        };
        let metadata = convert_and_check(&teapot, &split);
        assert_eq!(metadata["build"]["splits"]["method"], serde_json::to_value(method).unwrap());
        assert!(metadata["build"]["splits"].get("triangles").is_none(), "the default is not recorded");
        assert!(metadata.get("choice").is_none());
        assert_eq!(metadata["build"]["optimize_over"], "clusters", "the balanced preset's");
        // Which triangles, what the optimizer's leaves are, and the choice among candidates (with and without
        // wide sections).
        for (triangles, over, wide) in [
            (SplitTriangles::Any, OptimizeOver::Clusters, true),
            (SplitTriangles::Choose, OptimizeOver::References, true),
            (SplitTriangles::Choose, OptimizeOver::Choose, false),
            (SplitTriangles::Wasteful, OptimizeOver::Choose, true),
        ] {
            let mut options = split.clone();
            options.splits = options.splits.map(|s| SplitOptions { triangles, ..s });
            options.reinsertion = Some(over);
            options.wide = options.wide.filter(|_| wide);
            let metadata = convert_and_check(&teapot, &options);
            let recorded = |value: &serde_json::Value, default: &str| value.as_str().unwrap_or(default).to_string();
            assert_eq!(recorded(&metadata["build"]["splits"]["triangles"], "wasteful"), triangles.name());
            assert_eq!(recorded(&metadata["build"]["optimize_over"], "references"), over.name());
            let choice = &metadata["choice"];
            let chose = triangles == SplitTriangles::Choose || over == OptimizeOver::Choose;
            assert_eq!(choice.is_object(), chose, "{choice}");
            if chose {
                assert_eq!(choice["measure"], if wide { "wide_cost" } else { "sah_cost" });
                let candidates = choice["candidates"].as_array().unwrap();
                let made = if triangles == SplitTriangles::Choose { 2 } else { 1 }
                    * if over == OptimizeOver::Choose { 2 } else { 1 };
                assert_eq!(candidates.len(), made);
                let written = if wide { &metadata["wide"]["cost"] } else { &metadata["cost"]["sah_cost"] };
                let kept = &candidates[choice["kept"].as_u64().unwrap() as usize];
                assert_eq!(&kept["cost"], written, "the kept candidate's cost is the written tree's");
                let lowest = candidates.iter().map(|c| c["cost"].as_f64().unwrap()).fold(f64::INFINITY, f64::min);
                assert_eq!(kept["cost"].as_f64(), Some(lowest));
            }
        }
    }
    // Dropped and kept degenerate triangles are counted by kind.
    let degenerate = repro("keep-degenerate-message.obj");
    let dropped = convert_and_check(&degenerate, &ConvertOptions::preset(Preset::Fast));
    assert_eq!(dropped["triangles"]["source_triangle_count"], 2);
    assert_eq!(dropped["triangles"]["stored_count"], 1);
    assert_eq!(dropped["triangles"]["dropped"]["zero_area"], 1);
    let mut keep = ConvertOptions::preset(Preset::Fast);
    keep.import.keep_degenerate = true;
    let kept = convert_and_check(&degenerate, &keep);
    assert_eq!(
        (kept["triangles"]["stored_count"].as_u64(), kept["triangles"]["degenerate_kept"].as_u64()),
        (Some(2), Some(1))
    );
    assert_eq!(kept["triangles"]["dropped"]["zero_area"], 0);
    // glTF with buffers, a chosen scene, PLY, gzip: from the shared scenes when present.
    let mut with_scene = ConvertOptions::preset(Preset::Fast);
    with_scene.import.scene = Some(SceneSelector::Index(0));
    for (relative, options) in [
        ("khr-2cylinder-engine/2CylinderEngine.gltf", with_scene),
        ("stanford-bunny-ply/bun_zipper.ply", ConvertOptions::preset(Preset::Fast)),
        ("bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz", ConvertOptions::preset(Preset::Fast)),
    ] {
        match scene(relative) {
            Some(path) => {
                let metadata = convert_and_check(&path, &options);
                assert!(metadata["inputs"].as_array().is_some_and(|i| !i.is_empty()));
            }
            None => {
                crate::skips::skipped(crate::skips::Needs::Scenes, format!("{relative} (schema of its conversion)"))
            }
        }
    }
}

#[test]
fn the_schema_rejects_what_the_spec_forbids() {
    let text = include_str!("../../format-spec/metadata.schema.json");
    let schema: serde_json::Value = serde_json::from_str(text).unwrap();
    let validator = jsonschema::validator_for(&schema).unwrap();
    let good = serde_json::json!({"generator": "x", "format_version": "1.0", "inputs": [{"file_name": "a.obj", "content_hash": "xxh3-64:0123456789abcdef"}]});
    assert!(validator.is_valid(&good));
    for bad in [
        serde_json::json!({"inputs": [{"file_name": "/etc/passwd"}]}),
        serde_json::json!({"inputs": [{"file_name": "C:/scene.gltf"}]}),
        serde_json::json!({"format_version": "2.0"}),
        serde_json::json!({"inputs": [{"file_name": "a.obj", "content_hash": "md5:00"}]}),
        serde_json::json!({"cost": {"sah_cost": -1, "c_t": 3, "c_i": 2, "inner_area_ratio": 1, "leaf_area_ratio": 1}}),
        serde_json::json!({"build": {"builder": "octree"}}),
        serde_json::json!([]),
    ] {
        assert!(!validator.is_valid(&bad), "{bad}");
    }
}
