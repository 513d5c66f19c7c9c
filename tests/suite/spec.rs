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
    for kind in SectionKind::ALL {
        let row = format!("| {} | `{}` |", kind.code(), kind.name());
        assert!(SPEC.contains(&row), "{row}");
    }
}
