//! Editing a file in place (`BvhFile::edit`): every node of every layout re-encoded by the loader's encoders
//! from the geometry beneath it, bottom up (the binary boxes as unions of their children's or triangles'
//! bounds, each wide slot's box likewise, each GPU node's grid quantized again from its slots' exact boxes),
//! gives the file's bytes back (but for the sign of zero bounds, and the checksums that follow them); and a changed box changes the section's checksum, which the
//! edit recomputes, so the file still passes the checksum rules.

use bvhc::loader::format::{GpuSlot, PackedTriangle, SectionKind, WIDE, WideNode8};
use bvhc::loader::{BvhFile, Rule, SectionsMut};
use bvhc::options::{OptimizeOver, Overrides, Preset};

type Bounds = ([f32; 3], [f32; 3]);

const EMPTY: Bounds = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);

fn union(a: Bounds, b: Bounds) -> Bounds {
    (std::array::from_fn(|i| a.0[i].min(b.0[i])), std::array::from_fn(|i| a.1[i].max(b.1[i])))
}

fn triangle_box(t: &PackedTriangle) -> Bounds {
    t.vertices.iter().fold(EMPTY, |b, v| union(b, (*v, *v)))
}

/// The teapot converted without split references (whose clipped boxes are not the triangles' bounds), with the
/// wide and GPU layouts.
fn converted(dir: &std::path::Path) -> BvhFile {
    converted_with(dir, Overrides::default())
}

/// The teapot converted as [`converted`] says, with `overrides` on top.
fn converted_with(dir: &std::path::Path, overrides: Overrides) -> BvhFile {
    let teapot = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj");
    let output = dir.join("teapot.bvh");
    let overrides = Overrides { splits: Some(false), gpu_layout: Some(true), ..overrides };
    bvhc::Conversion::new(teapot, &output).preset(Preset::Balanced).overrides(overrides).run().unwrap();
    BvhFile::read(&output).unwrap()
}

/// Every node of every layout re-encoded from the geometry beneath it, children before parents.
pub fn reencode_everything(file: &mut BvhFile) {
    let mut edit = file.edit().unwrap();
    let triangles: Vec<PackedTriangle> = edit.triangles.to_vec();
    // Binary: children follow their parent, so reverse order sees children first.
    let nodes = &mut *edit.nodes;
    for i in (0..nodes.len()).rev() {
        let node = nodes[i];
        let b = if node.is_leaf() {
            let records = &triangles[node.index as usize..(node.index + node.count) as usize];
            records.iter().fold(EMPTY, |b, t| union(b, triangle_box(t)))
        } else {
            let (l, r) = (nodes[node.index as usize], nodes[node.index as usize + 1]);
            union((l.min, l.max), (r.min, r.max))
        };
        (nodes[i].min, nodes[i].max) = b;
    }
    // Wide: a slot's box is its child's slots' union, or its packets' lanes' triangles.
    let packets = edit.triangle_packets.as_deref().expect("wide sections");
    let wide = edit.wide_nodes.as_deref_mut().expect("wide sections");
    let node_box = |n: &WideNode8| (0..WIDE).filter_map(|s| n.slot(s)).fold(EMPTY, |b, (sb, _)| union(b, sb));
    for i in (0..wide.len()).rev() {
        for slot in 0..WIDE {
            let Some((_, child)) = wide[i].slot(slot) else { continue };
            let b = if child & bvhc::loader::format::LEAF_BIT == 0 {
                node_box(&wide[child as usize])
            } else {
                let (first, count) = WideNode8::leaf_packets(child);
                let mut b = EMPTY;
                for packet in &packets[first as usize..(first + count) as usize] {
                    for lane in (0..4).filter(|&l| packet.triangle_index[l] != u32::MAX) {
                        b = union(b, triangle_box(&triangles[packet.triangle_index[lane] as usize]));
                    }
                }
                b
            };
            wide[i].set_slot_box(slot, b);
        }
    }
    // GPU: breadth first, so reverse order sees children first; each node quantized from exact slot boxes.
    let gpu_triangles = edit.gpu_triangles.as_deref().expect("GPU sections");
    let gpu = edit.gpu_nodes.as_deref_mut().expect("GPU sections");
    let mut content = vec![EMPTY; gpu.len()];
    for i in (0..gpu.len()).rev() {
        let boxes: [Option<Bounds>; 8] = std::array::from_fn(|slot| match gpu[i].slot(slot) {
            GpuSlot::Inner(child) => Some(content[child as usize]),
            GpuSlot::Leaf { first, count } => Some(
                gpu_triangles[first as usize..(first + count) as usize]
                    .iter()
                    .fold(EMPTY, |b, t| union(b, t.vertices.iter().fold(EMPTY, |b, v| union(b, (*v, *v))))),
            ),
            _ => None,
        });
        content[i] = boxes.iter().flatten().fold(EMPTY, |b, s| union(b, *s));
        assert!(gpu[i].encode_slot_boxes(&boxes), "node {i}");
    }
}

/// `original` with its records, packet lanes and GPU triangles moved to `moved` and every box re-encoded by the
/// test's own reading of the format's rules (`reencode::reencode_everything`).
pub fn reencoded(original: &BvhFile, moved: &[[[f32; 3]; 3]]) -> BvhFile {
    let mut expected = BvhFile::from_bytes(original.as_bytes()).unwrap();
    {
        let mut edit = expected.edit().unwrap();
        for (record, vertices) in edit.triangles.iter_mut().zip(moved) {
            *record = PackedTriangle { vertices: *vertices };
        }
        let packets = edit.triangle_packets.as_deref_mut().unwrap();
        for packet in packets.iter_mut() {
            for lane in (0..4).filter(|&l| packet.triangle_index[l] != u32::MAX) {
                let t = moved[packet.triangle_index[lane] as usize];
                (0..3).for_each(|v| (0..3).for_each(|a| packet.vertices[v][a][lane] = t[v][a]));
            }
        }
        for gpu_triangle in edit.gpu_triangles.as_deref_mut().unwrap() {
            gpu_triangle.vertices = moved[gpu_triangle.triangle_index as usize];
        }
    }
    reencode_everything(&mut expected);
    expected
}

/// A copy of `file` with its checksums recomputed (an edit that changes nothing), as a refit leaves them stale.
pub fn with_checksums(file: &BvhFile) -> BvhFile {
    let mut copy = BvhFile::from_bytes(file.as_bytes()).unwrap();
    drop(copy.edit().unwrap());
    copy
}

/// The binary and wide trees laid out anew breadth first (each inner node's pair of children, each wide node's
/// children, placed in the order a breadth-first walk meets them), keeping every box, leaf and packet: a valid
/// file in a layout other than the converter's depth-first one.
pub fn breadth_first(file: &mut BvhFile) {
    let mut edit = file.edit().unwrap();
    let old = edit.nodes.to_vec();
    let mut order = vec![0usize];
    let mut new_index = vec![0u32; old.len()];
    let mut k = 0;
    while k < order.len() {
        let node = old[order[k]];
        if !node.is_leaf() {
            new_index[node.index as usize] = order.len() as u32;
            order.extend([node.index as usize, node.index as usize + 1]);
        }
        k += 1;
    }
    for (new, &at) in order.iter().enumerate() {
        let mut node = old[at];
        if !node.is_leaf() {
            node.index = new_index[node.index as usize];
        }
        edit.nodes[new] = node;
    }
    let wide = edit.wide_nodes.as_deref_mut().expect("wide sections");
    let old = wide.to_vec();
    let (mut order, mut new_index) = (vec![0usize], vec![0u32; old.len()]);
    let mut k = 0;
    while k < order.len() {
        for &child in old[order[k]].child.iter().filter(|&&c| c & bvhc::loader::format::LEAF_BIT == 0) {
            new_index[child as usize] = order.len() as u32;
            order.push(child as usize);
        }
        k += 1;
    }
    for (new, &at) in order.iter().enumerate() {
        let mut node = old[at];
        for child in node.child.iter_mut().filter(|c| **c & bvhc::loader::format::LEAF_BIT == 0) {
            *child = new_index[*child as usize];
        }
        wide[new] = node;
    }
}

/// Every binary box emptied and every occupied wide slot's box set to the unit box: what a re-encoding or a
/// refit must overwrite, not inherit.
pub fn scramble_boxes(edit: &mut SectionsMut<'_>) {
    edit.nodes.iter_mut().for_each(|n| (n.min, n.max) = ([0.0; 3], [0.0; 3]));
    for node in edit.wide_nodes.as_deref_mut().unwrap() {
        for slot in 0..WIDE {
            if node.slot(slot).is_some() {
                node.set_slot_box(slot, ([0.0; 3], [1.0; 3]));
            }
        }
    }
}

/// Word-by-word equality of two files' sections but the metadata, but for the sign of a zero bound: the
/// converter's unions and the tests' (or a refit's) meet the vertex coordinates +0 and -0 in another order, and a
/// box's bound is the same plane either way.
pub fn assert_same_sections(a: &BvhFile, b: &BvhFile, what: &str) {
    let same_but_zero_signs = |(x, y): (&[u8], &[u8])| {
        x == y
            || (x[..3] == y[..3]
                && (x[3] | 0x80) == (y[3] | 0x80)
                && u32::from_le_bytes(x.try_into().unwrap()) & 0x7FFF_FFFF == 0)
    };
    for section in a.view().sections().filter(|s| s.kind.is_some_and(|k| !matches!(k, SectionKind::Metadata))) {
        let range = section.entry.section_byte_offset as usize
            ..(section.entry.section_byte_offset + section.entry.section_byte_len) as usize;
        let (x, y) = (&a.as_bytes()[range.clone()], &b.as_bytes()[range]);
        let first = x.chunks(4).zip(y.chunks(4)).position(|words| !same_but_zero_signs(words));
        assert_eq!(first, None, "{what}: {:?} differs at word {first:?}", section.kind);
    }
}

#[test]
fn every_node_re_encoded_in_place_gives_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    let mut file = converted(dir.path());
    let original = file.as_bytes().to_vec();
    // Scramble every box and grid first, so that the re-encoding, not the old bytes, makes the result.
    {
        let mut edit = file.edit().unwrap();
        scramble_boxes(&mut edit);
        edit.gpu_nodes
            .as_deref_mut()
            .unwrap()
            .iter_mut()
            .for_each(|n| (n.origin, n.quantized_max) = ([0.0; 3], [[0; 8]; 3]));
    }
    assert_ne!(file.as_bytes(), &original[..]);
    reencode_everything(&mut file);
    // The same bytes, but for the sign of a zero bound (see `assert_same_sections`). The checksums (recomputed by
    // the edit) then differ with them; the verifier checks them.
    let original = BvhFile::from_bytes(&original).unwrap();
    assert_same_sections(&file, &original, "re-encoding");
    assert_eq!(file.as_bytes().len(), original.as_bytes().len());
    file.view().verify().unwrap();
}

#[test]
fn an_edit_recomputes_the_checksums_of_what_it_changed() {
    let dir = tempfile::tempdir().unwrap();
    let mut file = converted(dir.path());
    {
        let edit = file.edit().unwrap();
        // A leaf box grown: still enclosing, so the tree rules hold, but the bytes and the costs change.
        let leaf = edit.nodes.iter_mut().rev().find(|n| n.is_leaf()).unwrap();
        leaf.max[0] += 1.0;
    }
    // The checksums are right (V11, V12), so the first broken rule is the metadata's cost (V37) or a box rule.
    let rule = file.view().verify().unwrap_err().rule;
    assert!(!matches!(rule, Rule::HeaderChecksum | Rule::SectionChecksum), "the edit left a stale checksum: {rule:?}");
}

/// The metadata as JSON.
fn metadata_of(file: &BvhFile) -> serde_json::Value {
    serde_json::from_str(file.view().metadata_str().unwrap().unwrap()).unwrap()
}

#[test]
fn a_file_rewritten_without_an_edit_is_the_same_bytes() {
    let dir = tempfile::tempdir().unwrap();
    for overrides in
        [Overrides::default(), Overrides { optimize_over: Some(OptimizeOver::Choose), ..Overrides::default() }]
    {
        let file = converted_with(dir.path(), overrides);
        let rewritten = file.rewritten().unwrap();
        assert!(rewritten.as_bytes() == file.as_bytes(), "the converter's costs are the file's, to the bit");
    }
}

#[test]
fn an_edited_file_rewritten_states_its_new_costs_and_verifies() {
    let dir = tempfile::tempdir().unwrap();
    let overrides = Overrides { optimize_over: Some(OptimizeOver::Choose), ..Overrides::default() };
    let mut file = converted_with(dir.path(), overrides);
    let before = metadata_of(&file);
    assert!(before.get("choice").is_some(), "the conversion chose among candidates: {before}");
    // Stretch the teapot to twice its width (exact in f32), then re-encode every node: a valid tree whose
    // costs changed (its boxes' areas do not all scale alike).
    {
        let mut edit = file.edit().unwrap();
        edit.triangles.iter_mut().flat_map(|t| t.vertices.iter_mut()).for_each(|v| v[0] *= 2.0);
        for packet in edit.triangle_packets.as_deref_mut().unwrap() {
            for lane in (0..4).filter(|&l| packet.triangle_index[l] != u32::MAX) {
                packet.vertices.iter_mut().for_each(|v| v[0][lane] *= 2.0);
            }
        }
        edit.gpu_triangles
            .as_deref_mut()
            .unwrap()
            .iter_mut()
            .flat_map(|t| t.vertices.iter_mut())
            .for_each(|v| v[0] *= 2.0);
    }
    reencode_everything(&mut file);
    assert_eq!(file.view().verify().unwrap_err().rule, Rule::MetadataCost, "the edit left the costs stale");

    let rewritten = file.rewritten().unwrap();
    rewritten.view().verify().unwrap();
    let view = rewritten.view();
    let after = metadata_of(&rewritten);
    let binary = bvhc::loader::format::cost::binary_cost(view.nodes(), 3.0, 2.0);
    let wide =
        bvhc::loader::format::cost::wide_cost(view.nodes().first(), view.wide_sections().unwrap().nodes, 1.0, 1.0);
    for (key, stated, computed) in [
        ("cost.sah_cost", &after["cost"]["sah_cost"], binary.sah_cost),
        ("cost.inner_area_ratio", &after["cost"]["inner_area_ratio"], binary.inner_area_ratio),
        ("cost.leaf_area_ratio", &after["cost"]["leaf_area_ratio"], binary.leaf_area_ratio),
        ("wide.cost", &after["wide"]["cost"], wide),
    ] {
        assert_eq!(stated.as_f64().map(f64::to_bits), Some(computed.to_bits()), "{key}: {stated} against {computed}");
    }
    assert_ne!(after["cost"]["sah_cost"], before["cost"]["sah_cost"], "the stretch changed the cost");
    assert!(after.get("choice").is_none(), "the conversion's candidates were measured on other geometry");
    // The rest of the metadata is as it was, and so is every other section.
    let (mut rest_before, mut rest_after) = (before.clone(), after.clone());
    for rest in [&mut rest_before, &mut rest_after] {
        let object = rest.as_object_mut().unwrap();
        object.remove("choice");
        object.remove("cost");
        object["wide"].as_object_mut().unwrap().remove("cost");
    }
    assert_eq!(rest_before, rest_after);
    let sections_of = |file: &BvhFile| {
        let view = file.view();
        let bytes = view.bytes();
        view.sections()
            .filter(|s| s.kind != Some(SectionKind::Metadata))
            .map(|s| {
                (s.kind, bytes[s.entry.section_byte_offset as usize..][..s.entry.section_byte_len as usize].to_vec())
            })
            .collect::<Vec<_>>()
    };
    assert!(sections_of(&rewritten) == sections_of(&file));
    assert_eq!(view.version(), file.view().version());
}
