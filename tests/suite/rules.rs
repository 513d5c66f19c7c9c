//! One test per validity rule of the header and section table (V1-V13): corrupt a good file in one way and
//! expect exactly that rule. The tree and content rules are in `rules_tree.rs`, the wide sections' in
//! `rules_wide.rs`.

use bvhc::loader::{BvhFile, Rule, write::BvhWriter};

use crate::common::*;
use crate::corrupt::*;
#[test]
fn v1_magic() {
    expect(Rule::Magic, |b| b[3] = b'X', false);
    expect(Rule::Magic, |b| b.truncate(40), false);
    let error =
        BvhFile::from_bytes(b"HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0 0\n}\nMOTION\nFrames: 0\nFrame Time: 0.1\n\n\n")
            .unwrap_err();
    assert!(error.to_string().contains("Biovision"), "{error}");
}

#[test]
fn v2_major_version() {
    expect(Rule::MajorVersion, |b| b[8] = 2, false);
}

#[test]
fn v3_file_byte_len() {
    expect(Rule::FileByteLen, |b| b.push(0), false);
    expect(Rule::FileByteLen, |b| b.truncate(b.len() - 1), false);
}

#[test]
fn v4_section_table() {
    expect(Rule::SectionTable, |b| write_u32(b, 24, 1_000_000), false);
    expect(Rule::SectionTable, |b| write_u32(b, 28, 40), false);
}

#[test]
fn v5_section_placement() {
    expect(
        Rule::SectionPlacement,
        |b| {
            let at = entry(NODES) + 8;
            let v = read_u64(b, at);
            write_u64(b, at, v + 4)
        },
        false,
    );
    expect(Rule::SectionPlacement, |b| write_u64(b, entry(METADATA_SECTION) + 16, u64::MAX - 3), false);
    expect(Rule::SectionPlacement, |b| write_u64(b, entry(TRIANGLES) + 8, 0), false);
}

#[test]
fn v6_section_size() {
    expect(
        Rule::SectionSize,
        |b| {
            let at = entry(NODES) + 24;
            let v = read_u64(b, at);
            write_u64(b, at, v + 1)
        },
        false,
    );
    expect(Rule::SectionSize, |b| write_u32(b, entry(METADATA_SECTION) + 32, 0), false);
}

#[test]
fn v7_unknown_required_section() {
    expect(
        Rule::UnknownRequiredSection,
        |b| {
            write_u32(b, entry(METADATA_SECTION), 999);
            write_u32(b, entry(METADATA_SECTION) + 4, 1)
        },
        false,
    );
}

#[test]
fn v8_section_multiplicity() {
    // The nodes section becomes an unknown optional kind: the file has no nodes section.
    expect(
        Rule::SectionMultiplicity,
        |b| {
            write_u32(b, entry(NODES), 999);
            write_u32(b, entry(NODES) + 4, 0)
        },
        false,
    );
    let id_bytes = 0u32.to_le_bytes();
    let one = packed_tree(&random_triangles(71, 1, 1.0), 1);
    let bytes = BvhWriter::new(&one.nodes, &one.triangles)
        .triangle_ids(&one.triangle_ids)
        .extra_section(3, false, 4, &id_bytes)
        .build();
    assert_eq!(bytes.unwrap_err().rule(), Some(Rule::SectionMultiplicity), "a second triangle_ids section");
}

#[test]
fn v9_section_kind_layout() {
    expect(Rule::SectionKindLayout, |b| write_u32(b, entry(NODES) + 4, 0), false);
    expect(Rule::SectionKindLayout, |b| write_u32(b, entry(IDS) + 4, 1), false);
    expect(Rule::SectionKindLayout, |b| write_u32(b, entry(NODES) + 4, 1 | 4), false);
    // The ids section claims 8-byte elements (with a consistent length).
    expect(
        Rule::SectionKindLayout,
        |b| {
            let count = read_u64(b, entry(IDS) + 24);
            write_u64(b, entry(IDS) + 24, count / 2);
            write_u64(b, entry(IDS) + 16, count / 2 * 8);
            write_u32(b, entry(IDS) + 32, 8);
        },
        false,
    );
}

#[test]
fn v10_counts() {
    expect(
        Rule::Counts,
        |b| {
            let count = read_u64(b, entry(IDS) + 24);
            write_u64(b, entry(IDS) + 24, count - 1);
            write_u64(b, entry(IDS) + 16, (count - 1) * 4);
        },
        false,
    );
    expect(
        Rule::Counts,
        |b| {
            let count = read_u64(b, entry(NODES) + 24);
            write_u64(b, entry(NODES) + 24, count - 1);
            write_u64(b, entry(NODES) + 16, (count - 1) * 32);
        },
        false,
    );
    // A source table without ids.
    expect(Rule::Counts, |b| write_u32(b, entry(IDS), 999), false);
}

#[test]
fn v11_header_checksum() {
    expect(Rule::HeaderChecksum, |b| b[40] = 1, false);
}

#[test]
fn v12_section_checksum() {
    expect(
        Rule::SectionChecksum,
        |b| {
            let at = data(b, TRIANGLES);
            b[at] ^= 1
        },
        false,
    );
}

#[test]
fn v13_reserved_zero() {
    expect(Rule::ReservedZero, |b| b[44] = 1, true);
    expect(Rule::ReservedZero, |b| b[12] = 1, true);
    expect(Rule::ReservedZero, |b| b[entry(TRIANGLES) + 36] = 1, true);
    expect(
        Rule::ReservedZero,
        |b| {
            let at = data(b, NODES) - 1;
            b[at] = 7
        },
        true,
    );
    expect(
        Rule::ReservedZero,
        |b| {
            let at = data(b, SOURCES) + 28;
            b[at] = 7
        },
        true,
    );
}

#[test]
fn v51_the_version_is_the_lowest_the_sections_need() {
    // The good file has no section of 1.1-1.4: labelled 1.2 or 1.4 (the metadata following, V28), it claims
    // features it does not use.
    for minor in [2, 4] {
        let mut bytes = good_bytes();
        relabel_minor(&mut bytes, 0, minor);
        assert_eq!(broken_rule(&bytes), Some(Rule::LowestMinor), "labelled 1.{minor}");
    }
    // A minor this reader does not know may need the label for features it cannot see: not judged.
    let mut bytes = good_bytes();
    relabel_minor(&mut bytes, 0, 9);
    assert_eq!(broken_rule(&bytes), None);
}
