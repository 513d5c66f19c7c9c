//! Compatibility rules: higher minor versions are read, unknown optional sections are skipped, unknown
//! required ones are refused.

use bvhc::loader::{BvhFile, Rule, format::SectionKind, write::BvhWriter};

use crate::common::*;
use crate::corrupt::{good_bytes, refresh_checksums};

#[test]
fn a_higher_minor_version_is_read_and_its_reserved_fields_are_not_judged() {
    let mut bytes = good_bytes();
    bytes[10] = 7; // version_minor 7
    bytes[40] = 1; // a reserved header field that minor 7 may use
    bytes[12] = 1; // a header flag that minor 7 may define
    // The metadata's format_version follows the header (V28): "1.0" -> "1.7".
    let at = bytes.windows(5).position(|w| w == b"\"1.0\"").unwrap() + 3;
    bytes[at] = b'7';
    refresh_checksums(&mut bytes);
    let file = BvhFile::from_bytes(&bytes).unwrap();
    assert_eq!(file.view().version(), (1, 7));
    file.view().verify().unwrap();
}

#[test]
fn unknown_optional_sections_are_listed_checked_and_skipped() {
    let tree = packed_tree(&random_triangles(80, 100, 1.0), 2);
    let payload = [1u8, 2, 3, 4, 5, 6, 7, 8];
    let file = BvhWriter::new(&tree.nodes, &tree.triangles).extra_section(4242, false, 2, &payload).build().unwrap();
    let view = file.view();
    let kinds: Vec<_> = view.sections().map(|s| (s.entry.kind, s.kind)).collect();
    assert_eq!(kinds, [(1, Some(SectionKind::Nodes)), (2, Some(SectionKind::Triangles)), (4242, None)]);
    assert_eq!(view.nodes(), &tree.nodes[..]);
    view.verify().unwrap();
    // Its checksum still counts.
    let mut bytes = file.as_bytes().to_vec();
    let last = bytes.len() - 1;
    bytes[last] ^= 0xFF;
    let damaged = BvhFile::from_bytes(&bytes).unwrap();
    assert_eq!(damaged.view().verify().unwrap_err().rule, Rule::SectionChecksum);
}

#[test]
fn unknown_required_sections_are_refused() {
    let tree = packed_tree(&random_triangles(81, 10, 1.0), 2);
    let error = BvhWriter::new(&tree.nodes, &tree.triangles).extra_section(4243, true, 1, b"x").build().unwrap_err();
    assert_eq!(error.rule(), Some(Rule::UnknownRequiredSection));
}

#[test]
fn source_ranges_resolve_ids_to_their_part_of_the_input() {
    let tree = packed_tree(&random_triangles(82, 30, 1.0), 1);
    let mut ranges = single_source_range(0);
    ranges[0].source_triangle_count = 10;
    let mut second = ranges[0];
    second.first_source_triangle = 10;
    second.source_triangle_count = 20;
    second.mesh_index = 1;
    ranges.push(second);
    let file = BvhWriter::new(&tree.nodes, &tree.triangles)
        .triangle_ids(&tree.triangle_ids)
        .source_table(&ranges)
        .build()
        .unwrap();
    let view = file.view();
    for (t, &id) in view.triangle_ids().unwrap().iter().enumerate() {
        let range = view.source_range_of(id).unwrap();
        assert_eq!(range.mesh_index, u32::from(id >= 10), "triangle {t}");
    }
    assert!(view.source_range_of(30).is_none());
}
