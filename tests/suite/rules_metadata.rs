//! One test per metadata consistency rule (V36-V39): a max-quality conversion of the teapot optimizing over the
//! chosen of three candidates (wide sections, split references, a `build`, `cost`, `triangles` and `choice` object) rewritten with one metadata value
//! changed must fail exactly that rule; the unchanged file passes, and so does the file with the key removed
//! (every key is optional).

use std::sync::OnceLock;

use bvhc::loader::{BvhFile, Rule, write::BvhWriter};
use bvhc::options::{OptimizeOver, Overrides, Preset};
use serde_json::{Value, json};

/// The converted teapot's bytes, made once for every test here.
pub(crate) fn converted() -> &'static [u8] {
    static BYTES: OnceLock<Vec<u8>> = OnceLock::new();
    BYTES.get_or_init(|| {
        let teapot = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj");
        let dir = tempfile::tempdir().unwrap();
        let output = dir.path().join("teapot.bvh");
        // `--optimize-over choose`: three candidates in the `choice` object (the preset's default keeps two).
        let overrides = Overrides { optimize_over: Some(OptimizeOver::Choose), ..Overrides::default() };
        bvhc::Conversion::new(teapot, &output).preset(Preset::MaxQuality).overrides(overrides).run().unwrap();
        std::fs::read(&output).unwrap()
    })
}

fn metadata() -> Value {
    let file = BvhFile::from_bytes(converted()).unwrap();
    serde_json::from_str(file.view().metadata_str().unwrap().unwrap()).unwrap()
}

/// The converted file's sections written again with `metadata`, with or without the triangle ids (and the
/// source table and source vertices that need them); the rule the writer's verification reports, if any.
fn rewritten_with(metadata: &Value, with_ids: bool) -> Option<Rule> {
    let file = BvhFile::from_bytes(converted()).unwrap();
    let view = file.view();
    let wide = view.wide_sections().unwrap();
    // Without ids there are no source vertices either, so the file is 1.1 and its metadata says so.
    let mut metadata = metadata.clone();
    if !with_ids {
        metadata["format_version"] = json!("1.1");
    }
    let text = metadata.to_string();
    let mut writer = BvhWriter::new(view.nodes(), view.triangles())
        .split_references(view.has_split_references())
        .wide(wide.nodes, wide.packets)
        .metadata(&text);
    if with_ids {
        writer = writer
            .triangle_ids(view.triangle_ids().unwrap())
            .source_table(view.source_table().unwrap())
            .source_vertices(view.source_vertices().unwrap());
    }
    writer.build().err().map(|e| e.rule().unwrap_or_else(|| panic!("not a rule: {e}")))
}

/// `edit` applied to the good metadata breaks `rule`.
fn expect(rule: Rule, edit: impl FnOnce(&mut Value)) {
    let mut metadata = metadata();
    edit(&mut metadata);
    assert_eq!(rewritten_with(&metadata, true), Some(rule), "{metadata}");
}

#[test]
fn the_converted_file_has_every_key_the_rules_check_and_passes_them() {
    let metadata = metadata();
    for key in ["build", "cost", "wide", "triangles", "choice"] {
        assert!(metadata[key].is_object(), "{key}");
    }
    let file = BvhFile::from_bytes(converted()).unwrap();
    assert!(file.view().has_split_references(), "the max-quality teapot has split references");
    assert_eq!(rewritten_with(&metadata, true), None);
    // bvhc writes the costs bit for bit as the spec computes them (one running sum in the stated order).
    let view = file.view();
    let wide = view.wide_sections().unwrap();
    let recomputed = bvhc::loader::format::cost::wide_cost(view.nodes().first(), wide.nodes, 1.0, 1.0);
    assert_eq!(metadata["wide"]["cost"].as_f64().unwrap().to_bits(), recomputed.to_bits());
    let binary = bvhc::loader::format::cost::binary_cost(view.nodes(), 3.0, 2.0);
    assert_eq!(metadata["cost"]["sah_cost"].as_f64().unwrap().to_bits(), binary.sah_cost.to_bits());
    // Every key is optional: without them the rules have nothing to check.
    let mut bare = metadata.clone();
    for key in ["build", "cost", "wide", "triangles", "choice"] {
        bare.as_object_mut().unwrap().remove(key);
    }
    assert_eq!(rewritten_with(&bare, true), None);
}

#[test]
fn v36_metadata_counts() {
    expect(Rule::MetadataCounts, |m| m["wide"]["node_count"] = json!(m["wide"]["node_count"].as_u64().unwrap() + 1));
    expect(Rule::MetadataCounts, |m| m["wide"]["packet_count"] = json!(0));
    expect(Rule::MetadataCounts, |m| m["wide"] = Value::Null);
    expect(Rule::MetadataCounts, |m| {
        m["triangles"]["stored_count"] = json!(m["triangles"]["stored_count"].as_u64().unwrap() - 1)
    });
    expect(Rule::MetadataCounts, |m| m["triangles"]["dropped"]["zero_area"] = json!(1));
    expect(Rule::MetadataCounts, |m| {
        // Source ids must lie below source_triangle_count (and stored + dropped must add up to it).
        m["triangles"]["source_triangle_count"] = json!(10);
        m["triangles"]["stored_count"] = json!(10);
    });
    // Without ids a split file cannot tell repeated references from coinciding source triangles: any count
    // between the distinct vertex triples and the records passes, and one outside fails.
    let mut metadata = metadata();
    metadata["build"]["write_ids"] = json!(false);
    metadata["build"]["write_source_vertices"] = json!(false);
    assert_eq!(rewritten_with(&metadata, false), None);
    let records = BvhFile::from_bytes(converted()).unwrap().view().triangles().len();
    metadata["triangles"]["stored_count"] = json!(records + 1);
    metadata["triangles"]["source_triangle_count"] = json!(records + 1);
    assert_eq!(rewritten_with(&metadata, false), Some(Rule::MetadataCounts));
}

#[test]
fn v37_metadata_cost() {
    let scaled = |value: &Value| json!(value.as_f64().unwrap() * (1.0 + 1e-6));
    expect(Rule::MetadataCost, |m| m["cost"]["sah_cost"] = scaled(&m["cost"]["sah_cost"]));
    expect(Rule::MetadataCost, |m| m["cost"]["inner_area_ratio"] = scaled(&m["cost"]["inner_area_ratio"]));
    expect(Rule::MetadataCost, |m| m["cost"]["leaf_area_ratio"] = scaled(&m["cost"]["leaf_area_ratio"]));
    // The constants are part of the check: the same sums under other constants are another cost.
    expect(Rule::MetadataCost, |m| m["cost"]["c_t"] = json!(1.0));
    expect(Rule::MetadataCost, |m| {
        m["wide"]["cost"] = scaled(&m["wide"]["cost"]);
        m["choice"]["candidates"][2]["cost"] = m["wide"]["cost"].clone();
    });
    expect(Rule::MetadataCost, |m| m["build"]["wide"]["packet_test"] = json!(2.0));
    // Within the tolerance (another summation order): accepted.
    let mut metadata = metadata();
    metadata["cost"]["sah_cost"] = json!(metadata["cost"]["sah_cost"].as_f64().unwrap() * (1.0 + 1e-12));
    assert_eq!(rewritten_with(&metadata, true), None);
}

#[test]
fn v38_metadata_build() {
    expect(Rule::MetadataBuild, |m| m["build"]["wide"] = Value::Null);
    expect(Rule::MetadataBuild, |m| m["build"]["wide"]["width"] = json!(4));
    expect(Rule::MetadataBuild, |m| m["build"]["wide"]["packet_width"] = json!(8));
    expect(Rule::MetadataBuild, |m| m["build"]["write_ids"] = json!(false));
    // Leaves of the teapot hold up to 8 distinct triangles; a limit of 1 is broken by the binary leaves, and a
    // wide limit of 1 by the wide leaves.
    expect(Rule::MetadataBuild, |m| m["build"]["max_leaf_size"] = json!(1));
    expect(Rule::MetadataBuild, |m| m["build"]["wide"]["max_leaf_size"] = json!(1));
    expect(Rule::MetadataBuild, |m| m["build"]["write_source_vertices"] = json!(false));
    let mut metadata = metadata();
    metadata["build"]["write_source_vertices"] = json!(false);
    assert_eq!(rewritten_with(&metadata, false), Some(Rule::MetadataBuild), "ids promised, none written");
    metadata["build"]["write_ids"] = json!(false);
    metadata["build"]["write_source_vertices"] = json!(true);
    assert_eq!(rewritten_with(&metadata, false), Some(Rule::MetadataBuild), "source vertices promised, none written");
    // A file written before 1.2 records no write_source_vertices: not checked.
    metadata["build"].as_object_mut().unwrap().remove("write_source_vertices");
    assert_eq!(rewritten_with(&metadata, false), None);
}

#[test]
fn v39_metadata_choice() {
    expect(Rule::MetadataChoice, |m| m["choice"]["kept"] = json!(0));
    expect(Rule::MetadataChoice, |m| m["choice"]["kept"] = json!(4));
    expect(Rule::MetadataChoice, |m| m["choice"]["kept"] = json!("2"));
    expect(Rule::MetadataChoice, |m| {
        // A tie goes to the first candidate.
        m["choice"]["candidates"][0]["cost"] = m["choice"]["candidates"][2]["cost"].clone()
    });
    expect(Rule::MetadataChoice, |m| m["choice"]["measure"] = json!("sah_cost"));
}
