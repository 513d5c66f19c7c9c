//! The spec and the code agree: every rule is listed in the spec with its number, and every field name of the
//! on-disk structs appears in the spec.

use bvhc::loader::Rule;

const SPEC: &str = include_str!("../../format-spec/bvh-1.md");

#[test]
fn every_rule_is_in_the_spec_table_and_no_other() {
    for rule in Rule::ALL {
        assert!(SPEC.contains(&format!("| {rule} | {} |", if rule.is_structural() { "yes" } else { "no" })), "{rule}");
    }
    assert!(!SPEC.contains(&format!("| V{} |", Rule::ALL.len() + 1)));
}

#[test]
fn every_field_name_is_in_the_spec() {
    let fields = [
        "magic",
        "version_major",
        "version_minor",
        "header_flags",
        "file_byte_len",
        "section_count",
        "section_entry_byte_len",
        "header_checksum",
        "kind",
        "section_flags",
        "section_byte_offset",
        "section_byte_len",
        "element_count",
        "element_byte_len",
        "section_checksum",
        "min",
        "max",
        "index",
        "count",
        "vertices",
        "first_source_triangle",
        "source_triangle_count",
        "file_index",
        "node_index",
        "mesh_index",
        "primitive_index",
        "instance_index",
        "reserved",
        "child",
        "triangle_index",
        "first_node",
        "node_count",
        "first_triangle",
        "triangle_count",
        "first_wide_node",
        "wide_node_count",
        "first_packet",
        "packet_count",
        "object_to_world",
        "world_to_object",
        "gpu_instance_index",
    ];
    for field in fields {
        assert!(SPEC.contains(&format!("`{field}`")), "{field}");
    }
}

#[test]
fn the_spec_constants_match_the_code() {
    use bvhc::loader::format::*;
    assert_eq!(MAGIC, [0x89, 0x42, 0x56, 0x48, 0x43, 0x0D, 0x0A, 0x1A]);
    assert!(SPEC.contains("`89 42 56 48 43 0D 0A 1A`"));
    assert!(SPEC.contains(&format!("`MAX_DEPTH = {MAX_DEPTH}`")));
    assert!(SPEC.contains(&format!("`EMPTY_SLOT = {EMPTY_SLOT:#010X}`").replace("0X", "0x")));
    assert!(SPEC.contains(&format!("`LEAF_BIT = {LEAF_BIT:#010X}`").replace("0X", "0x")));
    assert!(SPEC.contains(&format!("`UNUSED_LANE = {UNUSED_LANE:#010X}`").replace("0X", "0x")));
    assert!(SPEC.contains(&format!("the quiet NaN `{UNUSED_LANE_COORDINATE_BITS:#010X}`").replace("0X", "0x")));
    assert!(SPEC.contains(&format!("`packet_count <= 2^{}`", MAX_PACKET_COUNT.trailing_zeros())));
    assert_eq!(size_of::<WideNode8>(), 256);
    assert_eq!(size_of::<TrianglePacket4>(), 160);
    assert_eq!((size_of::<MeshRecord>(), size_of::<InstanceRecord>()), (32, 112));
    assert_eq!(
        (INVERSE_TOLERANCE, MIN_ORTHOGONALITY, INSTANCE_BOX_PADDING),
        (2f64.powi(-13), 2f64.powi(-20), 2f64.powi(-20))
    );
    assert!(SPEC.contains("within `2^-13` of each entry's own scale") && SPEC.contains("`|det L| >= 2^-20 *"));
    assert!(SPEC.contains("outward by `2^-20` of their magnitude"));
    for kind in SectionKind::ALL {
        let row = format!("| {} | `{}` |", kind.code(), kind.name());
        assert!(SPEC.contains(&row), "{row}");
    }
}

/// The cost of section 5.6, computed from the spec's text alone over a file's nodes: (A_I, A_L).
fn cost_as_specified(nodes: &[bvhc::loader::format::PackedNode]) -> (f64, f64) {
    let area = |n: &bvhc::loader::format::PackedNode| {
        let e: Vec<f64> = (0..3).map(|a| (f64::from(n.max[a]) - f64::from(n.min[a])).max(0.0)).collect();
        2.0 * (e[0] * e[1] + e[1] * e[2] + e[2] * e[0])
    };
    let Some(root) = nodes.first().map(area).filter(|&a| a > 0.0) else { return (0.0, 0.0) };
    let inner: f64 = nodes.iter().filter(|n| !n.is_leaf()).map(area).sum();
    let leaves: f64 = nodes.iter().filter(|n| n.is_leaf()).map(|n| f64::from(n.count) * area(n)).sum();
    (inner / root, leaves / root)
}

#[test]
fn bvhc_info_reports_the_cost_exactly_as_the_spec_defines_it() {
    let dir = tempfile::tempdir().unwrap();
    let teapot = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj");
    let huge = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("fixtures/repro/sah-cost-nan-huge-extent.obj");
    for (input, extra) in [(&teapot, None), (&teapot, Some("--no-merge")), (&huge, None)] {
        let output = dir.path().join("x.bvh");
        let mut args = vec![
            input.as_os_str().to_owned(),
            "-o".into(),
            output.as_os_str().to_owned(),
            "-q".into(),
            "--force".into(),
        ];
        args.extend(extra.map(std::ffi::OsString::from));
        assert!(std::process::Command::new(env!("CARGO_BIN_EXE_bvhc")).args(&args).status().unwrap().success());
        let info = std::process::Command::new(env!("CARGO_BIN_EXE_bvhc"))
            .arg("info")
            .arg(&output)
            .arg("--json")
            .output()
            .unwrap();
        let report: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
        let file = bvhc::loader::BvhFile::read(&output).unwrap();
        let (a_i, a_l) = cost_as_specified(file.view().nodes());
        let (c_t, c_i) =
            (report["metadata"]["cost"]["c_t"].as_f64().unwrap(), report["metadata"]["cost"]["c_i"].as_f64().unwrap());
        assert_eq!(report["inner_area_ratio"].as_f64(), Some(a_i), "{input:?} {extra:?}");
        assert_eq!(report["leaf_area_ratio"].as_f64(), Some(a_l));
        assert_eq!(report["sah_cost"].as_f64(), Some(c_t * a_i + c_i * a_l));
        assert_eq!(
            report["metadata"]["cost"]["sah_cost"], report["sah_cost"],
            "the file's own cost is the same figure"
        );
        assert!(a_i.is_finite() && a_l.is_finite());
    }
}
