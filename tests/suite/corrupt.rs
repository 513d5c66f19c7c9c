//! Shared tools of the corruption tests: a good file as plain bytes, byte access by section, checksum repair,
//! and the rule a corrupted file breaks.

use bvhc::loader::{BvhFile, Rule, format::PackedNode, format::header_checksum, format::section_checksum};

use crate::common::*;

/// Where the section table starts, and the size of one entry (format-spec: header).
pub const TABLE: usize = 64;
pub const ENTRY: usize = 48;
/// Section table positions of the good file's sections.
pub const NODES: usize = 0;
pub const TRIANGLES: usize = 1;
pub const IDS: usize = 2;
pub const SOURCES: usize = 3;
pub const METADATA_SECTION: usize = 4;

/// A good file with every section kind, as plain bytes.
pub fn good_bytes() -> Vec<u8> {
    write_file(&packed_tree(&random_triangles(70, 60, 1.0), 2)).as_bytes().to_vec()
}

pub fn read_u32(bytes: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap())
}
pub fn write_u32(bytes: &mut [u8], at: usize, value: u32) {
    bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
}
pub fn read_u64(bytes: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap())
}
pub fn write_u64(bytes: &mut [u8], at: usize, value: u64) {
    bytes[at..at + 8].copy_from_slice(&value.to_le_bytes());
}
pub fn write_f32(bytes: &mut [u8], at: usize, value: f32) {
    bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
}
/// Byte offset of a section's table entry.
pub fn entry(section: usize) -> usize {
    TABLE + section * ENTRY
}
/// Byte offset of a section's data.
pub fn data(bytes: &[u8], section: usize) -> usize {
    read_u64(bytes, entry(section) + 8) as usize
}

/// Relabels a good file of minor version `from` as `to`: the header's `version_minor` and the metadata's
/// `format_version` (the metadata at table position 4, as every writer of these tests puts it), checksums
/// repaired.
pub fn relabel_minor(bytes: &mut [u8], from: u16, to: u16) {
    assert_eq!(u16::from_le_bytes([bytes[10], bytes[11]]), from);
    bytes[10..12].copy_from_slice(&to.to_le_bytes());
    let (at, len) = (data(bytes, METADATA_SECTION), read_u64(bytes, entry(METADATA_SECTION) + 16) as usize);
    let text = String::from_utf8(bytes[at..at + len].to_vec()).unwrap();
    let relabelled =
        text.replace(&format!("\"format_version\":\"1.{from}\""), &format!("\"format_version\":\"1.{to}\""));
    assert_ne!(text, relabelled, "{text}");
    bytes[at..at + len].copy_from_slice(relabelled.as_bytes());
    refresh_checksums(bytes);
}

/// Recomputes every checksum, so that a corruption reaches the rules behind V11 and V12.
pub fn refresh_checksums(bytes: &mut [u8]) {
    try_refresh_checksums(bytes).expect("the section table lies inside the file");
}

/// [`refresh_checksums`], or `None` when the table or a section lies outside the file.
pub fn try_refresh_checksums(bytes: &mut [u8]) -> Option<()> {
    let count = read_u32(bytes.get(..64)?, 24) as usize;
    let stride = read_u32(bytes, 28) as usize;
    let table_end = TABLE.checked_add(count.checked_mul(stride)?)?;
    if stride < ENTRY || table_end > bytes.len() {
        return None;
    }
    for i in 0..count {
        let at = TABLE + i * stride;
        let offset = usize::try_from(read_u64(bytes, at + 8)).ok()?;
        let len = usize::try_from(read_u64(bytes, at + 16)).ok()?;
        let sum = section_checksum(bytes.get(offset..offset.checked_add(len)?)?);
        write_u64(bytes, at + 40, sum);
    }
    let sum = header_checksum(&bytes[..table_end]);
    write_u64(bytes, 32, sum);
    Some(())
}

/// Opens (in an aligned copy) and verifies; returns the broken rule.
pub fn broken_rule(bytes: &[u8]) -> Option<Rule> {
    let file = match BvhFile::from_bytes(bytes) {
        Ok(file) => file,
        Err(error) => return Some(error.rule().unwrap_or_else(|| panic!("not a rule: {error}"))),
    };
    file.view().verify().err().map(|v| v.rule)
}

/// Corrupts the good file with `corrupt` (then repairs the checksums when `refresh`) and expects `rule`.
pub fn expect(rule: Rule, corrupt: impl FnOnce(&mut Vec<u8>), refresh: bool) {
    let mut bytes = good_bytes();
    assert_eq!(broken_rule(&bytes), None);
    corrupt(&mut bytes);
    if refresh {
        refresh_checksums(&mut bytes);
    }
    let got = broken_rule(&bytes);
    assert_eq!(got, Some(rule), "expected {rule}");
    assert_eq!(rule.is_structural(), BvhFile::from_bytes(&bytes).is_err(), "{rule} is structural iff open fails");
}

/// Byte offset of the first node that satisfies `predicate`.
pub fn first_node_where(bytes: &[u8], predicate: impl Fn(&PackedNode) -> bool) -> usize {
    let file = BvhFile::from_bytes(bytes).unwrap();
    let view = file.view();
    data(bytes, NODES) + 32 * view.nodes().iter().position(predicate).unwrap()
}
