//! The rules of the `triangle_flags` section (format 1.5): V52, V53, and its clauses of V8, V9, V10, V38 and V51.
//! Each test changes one thing in a converted file (the max-quality teapot with every triangle marked: split
//! references, so ids shared by several records) and expects exactly that rule.

use std::sync::OnceLock;

use bvhc::import::Opacity;
use bvhc::loader::format::{SECTION_FLAG_REQUIRED, SectionKind};
use bvhc::loader::{BvhFile, Rule};
use bvhc::options::Preset;

use crate::corrupt::{
    broken_rule, data, entry, read_u32, read_u64, refresh_checksums, relabel_minor, write_u32, write_u64,
};

/// The teapot converted with `--opacity filtered`: every triangle marked not opaque.
fn filtered_teapot() -> &'static [u8] {
    static BYTES: OnceLock<Vec<u8>> = OnceLock::new();
    BYTES.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let output = dir.path().join("teapot.bvh");
        bvhc::Conversion::new(crate::convert::teapot(), &output)
            .preset(Preset::MaxQuality)
            .opacity(Opacity::Filtered)
            .run()
            .unwrap();
        std::fs::read(&output).unwrap()
    })
}

/// The table position of the `triangle_flags` section.
fn flags_entry(bytes: &[u8]) -> usize {
    let count = read_u32(bytes, 24) as usize;
    (0..count)
        .find(|&i| read_u32(bytes, entry(i)) == SectionKind::TriangleFlags.code())
        .expect("a triangle_flags section")
}

/// The filtered teapot with `edit` applied to its bytes (given the ids and the flags' offset), checksums
/// repaired: the rule it breaks.
fn edited(edit: impl FnOnce(&mut Vec<u8>, &[u32], usize)) -> Option<Rule> {
    let mut bytes = filtered_teapot().to_vec();
    assert_eq!(broken_rule(&bytes), None, "the file as written");
    let file = BvhFile::from_bytes(&bytes).unwrap();
    let ids = file.view().triangle_ids().unwrap().to_vec();
    let at = data(&bytes, flags_entry(&bytes));
    edit(&mut bytes, &ids, at);
    refresh_checksums(&mut bytes);
    broken_rule(&bytes)
}

#[test]
fn v52_triangle_flag_bits() {
    let file = BvhFile::from_bytes(filtered_teapot()).unwrap();
    assert_eq!(file.view().version(), (1, 5));
    assert!(file.view().triangle_flags().unwrap().iter().all(|&f| f == 1));
    assert_eq!(edited(|bytes, _, at| bytes[at + 7] = 0x03), Some(Rule::TriangleFlagBits));
    assert_eq!(edited(|bytes, _, at| bytes[at] = 0x81), Some(Rule::TriangleFlagBits));
    // A file of a later minor version may define the bit: a 1.5 reader does not judge it.
    let mut bytes = filtered_teapot().to_vec();
    let at = data(&bytes, flags_entry(&bytes));
    bytes[at + 7] = 0x03;
    relabel_minor(&mut bytes, 5, 6);
    assert_eq!(broken_rule(&bytes), None);
}

#[test]
fn v53_triangle_flags_agree() {
    // Two records of one id (a split triangle's references) with different flags.
    let rule = edited(|bytes, ids, at| {
        let split = (0..ids.len()).find(|&t| ids.iter().filter(|&&id| id == ids[t]).count() > 1).unwrap();
        bytes[at + split] = 0;
    });
    assert_eq!(rule, Some(Rule::TriangleFlagsAgree));
}

#[test]
fn v8_v9_v10_v38_v51_clauses_of_the_triangle_flags() {
    // V8: the section in a file labelled 1.4.
    let mut bytes = filtered_teapot().to_vec();
    relabel_minor(&mut bytes, 5, 4);
    assert_eq!(broken_rule(&bytes), Some(Rule::SectionMultiplicity));
    // V9: the section marked REQUIRED.
    let rule = edited(|bytes, _, _| {
        let e = entry(flags_entry(bytes));
        write_u32(bytes, e + 4, SECTION_FLAG_REQUIRED);
    });
    assert_eq!(rule, Some(Rule::SectionKindLayout));
    // V10: one flag fewer than triangles.
    let rule = edited(|bytes, _, _| {
        let e = entry(flags_entry(bytes));
        let count = read_u64(bytes, e + 24);
        write_u64(bytes, e + 16, count - 1);
        write_u64(bytes, e + 24, count - 1);
    });
    assert_eq!(rule, Some(Rule::Counts));
    // V38: build.opacity is filtered, but a triangle (the only record of its id) is not marked.
    let rule = edited(|bytes, ids, at| {
        let single = (0..ids.len()).find(|&t| ids.iter().filter(|&&id| id == ids[t]).count() == 1).unwrap();
        bytes[at + single] = 0;
    });
    assert_eq!(rule, Some(Rule::MetadataBuild));
    // V38: build.opacity says opaque in a file with the section.
    let rule = edited(|bytes, _, _| {
        let (at, len) = (data(bytes, 4), read_u64(bytes, entry(4) + 16) as usize);
        let text = String::from_utf8(bytes[at..at + len].to_vec()).unwrap();
        let edited = text.replace("\"opacity\":\"filtered\"", "\"opacity\":\"opaque\"  ");
        assert_ne!(text, edited);
        bytes[at..at + len].copy_from_slice(edited.as_bytes());
    });
    assert_eq!(rule, Some(Rule::MetadataBuild));
    // V38: build.opacity is a value no writer means (a word, a number), in a file the other clauses accept.
    for (replacement, wanted) in
        [("\"opacity\":\"clipped\" ", Some(Rule::MetadataBuild)), ("\"opacity\":7         ", Some(Rule::MetadataBuild))]
    {
        let rule = edited(|bytes, _, _| {
            let (at, len) = (data(bytes, 4), read_u64(bytes, entry(4) + 16) as usize);
            let text = String::from_utf8(bytes[at..at + len].to_vec()).unwrap();
            let edited = text.replace("\"opacity\":\"filtered\"", replacement);
            assert_eq!(edited.len(), text.len());
            bytes[at..at + len].copy_from_slice(edited.as_bytes());
        });
        assert_eq!(rule, wanted, "{replacement}");
    }
    // `materials` (what an absent key means) is a value V38 accepts, whatever the flags.
    let rule = edited(|bytes, _, _| {
        let (at, len) = (data(bytes, 4), read_u64(bytes, entry(4) + 16) as usize);
        let text = String::from_utf8(bytes[at..at + len].to_vec()).unwrap();
        // One byte longer: the optimizer's seed (which no rule checks) a digit shorter keeps the section's length.
        let mut edited = text.replace("\"opacity\":\"filtered\"", "\"opacity\":\"materials\"");
        let seed = edited.find("\"seed\":").unwrap() + "\"seed\":".len();
        edited.remove(seed);
        assert_eq!(edited.len(), text.len());
        bytes[at..at + len].copy_from_slice(edited.as_bytes());
    });
    assert_eq!(rule, None);
    // V51: a file without the section labelled 1.5.
    let mut bytes = crate::rules_metadata::converted().to_vec();
    relabel_minor(&mut bytes, 2, 5);
    assert_eq!(broken_rule(&bytes), Some(Rule::LowestMinor));
}

/// A scene without triangles converted with `--opacity filtered`: the section is written with 0 elements (every
/// element marked, vacuously), so the file is 1.5 and valid.
#[test]
fn an_empty_scene_with_every_triangle_filtered_has_an_empty_flags_section_and_is_valid() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("empty.obj");
    std::fs::write(&scene, "v 0 0 0\nv 1 0 0\n").unwrap();
    let output = dir.path().join("empty.bvh");
    bvhc::Conversion::new(&scene, &output).opacity(Opacity::Filtered).run().unwrap();
    let bytes = std::fs::read(&output).unwrap();
    assert_eq!(broken_rule(&bytes), None);
    let file = BvhFile::from_bytes(&bytes).unwrap();
    assert_eq!(file.view().version(), (1, 5));
    assert_eq!(file.view().triangles().len(), 0);
    assert_eq!(file.view().triangle_flags(), Some(&[][..]));
}
