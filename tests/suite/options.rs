//! Options resolved in one place: every combination that would do nothing is refused (exit 2 on the command line,
//! a typed error in the library) naming both settings; `bvhc options` prints what a conversion records, valid
//! against the metadata schema's `build` object.

use std::process::Command;

use bvhc::convert::ConvertError;
use bvhc::loader::BvhFile;
use bvhc::options::{LeafMerge, OptionsError, Overrides, Preset, SplitMethod, SplitTriangles, resolve};

fn bvhc(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_bvhc")).args(args).output().expect("bvhc runs")
}

fn teapot() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj")
}

/// Each refused combination: the flags, and the two settings the message must name.
const REFUSED: &[(&[&str], &str, &str)] = &[
    (&["--no-merge", "--max-leaf-size", "4"], "--max-leaf-size", "--no-merge"),
    (&["--no-optimize", "--optimize-over", "clusters"], "--optimize-over", "--no-optimize"),
    (&["--no-optimize", "--selection", "sum"], "--selection", "--no-optimize"),
    (&["--no-optimize", "--time-budget", "3"], "--time-budget", "--no-optimize"),
    (&["--no-splits", "--split-method", "pre-split"], "--split-method", "--no-splits"),
    (&["--no-splits", "--split-triangles", "any"], "--split-triangles", "--no-splits"),
    (&["--no-splits", "--no-splits-deforming"], "--no-splits-deforming", "--no-splits"),
    (&["--preset", "fast", "--no-splits-deforming"], "--no-splits-deforming", "fast preset"),
    (&["--preset", "fast", "--split-triangles", "any"], "--split-triangles", "fast preset"),
    (&["--preset", "fast", "--split-method", "pre-split"], "--split-method", "fast preset"),
    (&["--builder", "spatial-median"], "--builder spatial-median", "SBVH"),
    (&["--builder", "spatial-median", "--split-method", "sbvh"], "--builder spatial-median", "--split-method sbvh"),
    (&["--no-ids", "--no-source-vertices"], "--no-source-vertices", "--no-ids"),
];

#[test]
fn every_inert_combination_is_a_usage_error_naming_both_settings() {
    for (flags, setting, because) in REFUSED {
        for command in [&["options"][..], &[]] {
            let output = std::env::temp_dir().join(format!("bvhc-refused-{}.bvh", std::process::id()));
            let teapot = teapot();
            let mut args: Vec<&str> = command.to_vec();
            if command.is_empty() {
                args.extend([teapot.to_str().unwrap(), "-o", output.to_str().unwrap()]);
            }
            args.extend(flags.iter());
            let run = bvhc(&args);
            let stderr = String::from_utf8_lossy(&run.stderr);
            assert_eq!(run.status.code(), Some(2), "{args:?}: {stderr}");
            assert!(stderr.contains(setting) && stderr.contains(because), "{args:?}: {stderr}");
            assert!(!output.exists(), "{args:?} wrote an output");
        }
    }
}

#[test]
fn values_out_of_range_are_refused() {
    for flags in [&["--max-leaf-size", "0"][..], &["--split-budget", "5"], &["--split-budget", "nan"]] {
        let run = bvhc(&[&["options"][..], flags].concat());
        assert_eq!(run.status.code(), Some(2), "{flags:?}: {}", String::from_utf8_lossy(&run.stderr));
    }
}

#[test]
fn the_library_refuses_the_same_combinations_with_typed_errors() {
    let inert = |preset: Preset, overrides: Overrides, setting: &str| match resolve(preset, &overrides) {
        Err(OptionsError::Inert { setting: got, .. }) => assert!(got.contains(setting), "{got} for {setting}"),
        other => panic!("{overrides:?}: expected {setting} refused, got {other:?}"),
    };
    inert(
        Preset::Balanced,
        Overrides { merge_leaves: Some(false), max_leaf_size: Some(4), ..Default::default() },
        "--max-leaf-size",
    );
    // Source vertices asked for without the ids they need; without ids and not asked for, they are left out.
    inert(
        Preset::Balanced,
        Overrides { write_ids: Some(false), write_source_vertices: Some(true), ..Default::default() },
        "source vertices",
    );
    let no_ids = resolve(Preset::Balanced, &Overrides { write_ids: Some(false), ..Default::default() }).unwrap();
    assert!(!no_ids.write_ids && !no_ids.write_source_vertices);
    inert(
        Preset::MaxQuality,
        Overrides { optimize: Some(false), selection: Some(bvhc::optimize::Selection::Sum), ..Default::default() },
        "--selection",
    );
    inert(
        Preset::Fast,
        Overrides { split_triangles: Some(SplitTriangles::Any), ..Default::default() },
        "--split-triangles",
    );
    inert(
        Preset::Balanced,
        Overrides { splits: Some(false), split_method: Some(SplitMethod::PreSplit), ..Default::default() },
        "--split-method",
    );
    inert(
        Preset::Balanced,
        Overrides { builder: Some(bvhc::builders::Builder::SpatialMedian), ..Default::default() },
        "--builder",
    );
    assert!(matches!(
        resolve(Preset::Balanced, &Overrides { max_leaf_size: Some(0), ..Default::default() }),
        Err(OptionsError::Invalid { .. })
    ));
    // The build-script API resolves the same way and writes nothing.
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("x.bvh");
    let refused = bvhc::Conversion::new(teapot(), &output).merge_leaves(false).max_leaf_size(4).run();
    assert!(matches!(refused, Err(ConvertError::Options(OptionsError::Inert { .. }))), "{refused:?}");
    assert!(!output.exists());
    // What the flags turn on takes effect.
    let options = resolve(
        Preset::Fast,
        &Overrides { split_budget: Some(0.2), split_triangles: Some(SplitTriangles::Any), ..Default::default() },
    )
    .unwrap();
    assert_eq!(options.splits.map(|s| (s.budget, s.triangles)), Some((0.2, SplitTriangles::Any)));
    let options = resolve(Preset::Balanced, &Overrides { merge_leaves: Some(false), ..Default::default() }).unwrap();
    assert_eq!(options.leaves, LeafMerge::Off);
}

/// The schema's `build` object, as a schema of its own.
fn build_schema() -> jsonschema::Validator {
    let text = include_str!("../../format-spec/metadata.schema.json");
    let schema: serde_json::Value = serde_json::from_str(text).unwrap();
    let build = serde_json::json!({ "$defs": schema["$defs"], "$ref": "#/$defs/build" });
    jsonschema::validator_for(&build).unwrap()
}

#[test]
fn bvhc_options_prints_what_a_conversion_records_and_the_schema_accepts_it() {
    let schema = build_schema();
    let dir = tempfile::tempdir().unwrap();
    let output = dir.path().join("teapot.bvh");
    for flags in [
        &["--preset", "fast"][..],
        &["--preset", "balanced"],
        &["--preset", "max-quality"],
        &["--preset", "fast", "--split-budget", "0.2", "--split-triangles", "any", "--selection", "area"],
        &["--no-splits", "--no-merge", "--no-wide", "--no-ids", "--keep-degenerate"],
        &["--no-optimize", "--max-leaf-size", "4", "--split-method", "pre-split", "--builder", "spatial-median"],
        &["--optimize-over", "choose", "--time-budget", "60"],
        &["--no-splits-deforming", "--split-triangles", "any"],
    ] {
        let printed = bvhc(&[&["options"][..], flags].concat());
        assert!(printed.status.success(), "{flags:?}: {}", String::from_utf8_lossy(&printed.stderr));
        let build: serde_json::Value = serde_json::from_slice(&printed.stdout).unwrap();
        let errors: Vec<String> = schema.iter_errors(&build).map(|e| e.to_string()).collect();
        assert!(errors.is_empty(), "{flags:?}: {errors:?}\n{build:#}");
        let teapot = teapot();
        let convert = bvhc(
            &[&[teapot.to_str().unwrap(), "-o", output.to_str().unwrap(), "--force", "--quiet"][..], flags].concat(),
        );
        assert!(convert.status.success(), "{flags:?}: {}", String::from_utf8_lossy(&convert.stderr));
        let file = BvhFile::read(&output).unwrap();
        let metadata: serde_json::Value = serde_json::from_str(file.view().metadata_str().unwrap().unwrap()).unwrap();
        assert_eq!(metadata["build"], build, "{flags:?}: the file records other options than `bvhc options` printed");
    }
}

#[test]
fn every_preset_resolves_to_valid_options_and_help_groups_options_by_stage() {
    for preset in Preset::ALL {
        let options = resolve(preset, &Overrides::default()).unwrap();
        assert_eq!(options, preset.options());
        options.validate().unwrap();
    }
    let help = String::from_utf8(bvhc(&["--help"]).stdout).unwrap();
    let headings: Vec<&str> = help.lines().filter(|l| !l.starts_with(' ') && l.ends_with(':')).collect();
    let stages = ["Preset:", "Import:", "Build:", "Splits:", "Optimize:", "Leaf layout:", "Output:"];
    let found: Vec<&str> = headings.iter().copied().filter(|h| stages.contains(h)).collect();
    assert_eq!(found, stages, "help headings: {headings:?}");
}
