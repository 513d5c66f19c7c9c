//! One test per validity rule of the GPU sections (format 1.4): corrupt a good 1.4 file in one way and expect
//! exactly that rule (V47-V50), plus the GPU clauses of V8, V9, V10 and V38.

use bvhc::loader::format::{GpuNode, GpuSlot, GpuTriangle, inner_meta, leaf_meta};
use bvhc::loader::{BvhFile, Rule};

use crate::common::random_triangles;
use crate::corrupt::{broken_rule, data, entry, refresh_checksums};
use crate::gpu_compare::gpu_file;

/// Section table positions of the good file's GPU sections (after nodes, triangles, ids, sources, metadata).
const GPU_NODES: usize = 5;
const GPU_TRIANGLES: usize = 6;

/// A good 1.4 file whose GPU tree has inner nodes, as plain bytes.
fn good_gpu_bytes() -> Vec<u8> {
    gpu_file(&random_triangles(71, 300, 1.0)).as_bytes().to_vec()
}

fn sections_of(bytes: &[u8]) -> (Vec<GpuNode>, Vec<GpuTriangle>) {
    let file = BvhFile::from_bytes(bytes).unwrap();
    let gpu = file.view().gpu_sections().unwrap();
    (gpu.nodes.to_vec(), gpu.triangles.to_vec())
}

/// Corrupts the good file's GPU nodes or triangles with `corrupt`, repairs the checksums, expects `rule`;
/// returns what the verifier said.
fn expect_gpu(rule: Rule, corrupt: impl FnOnce(&mut Vec<GpuNode>, &mut Vec<GpuTriangle>)) -> String {
    let mut bytes = good_gpu_bytes();
    assert_eq!(broken_rule(&bytes), None);
    let (mut nodes, mut triangles) = sections_of(&bytes);
    assert!(nodes.len() > 3 && nodes[0].inner_mask != 0, "the good file has inner GPU nodes");
    corrupt(&mut nodes, &mut triangles);
    let (node_at, triangle_at) = (data(&bytes, GPU_NODES), data(&bytes, GPU_TRIANGLES));
    let node_bytes: &[u8] = bytemuck::cast_slice(&nodes);
    bytes[node_at..node_at + node_bytes.len()].copy_from_slice(node_bytes);
    let triangle_bytes: &[u8] = bytemuck::cast_slice(&triangles);
    bytes[triangle_at..triangle_at + triangle_bytes.len()].copy_from_slice(triangle_bytes);
    refresh_checksums(&mut bytes);
    let file = BvhFile::from_bytes(&bytes).expect("GPU rules are not structural");
    let error = file.view().verify().expect_err("the corruption is caught");
    assert_eq!(error.rule, rule, "expected {rule}, got {error}");
    error.detail
}

/// The first (node, slot) holding a leaf, and one holding an inner child.
fn first_slot(nodes: &[GpuNode], leaf: bool) -> (usize, usize) {
    for (i, node) in nodes.iter().enumerate() {
        for slot in 0..8 {
            match node.slot(slot) {
                GpuSlot::Leaf { .. } if leaf => return (i, slot),
                GpuSlot::Inner(_) if !leaf => return (i, slot),
                _ => {}
            }
        }
    }
    panic!("no such slot")
}

#[test]
fn v47_child_base_out_of_order() {
    expect_gpu(Rule::GpuTreeShape, |nodes, _| nodes[1].child_base += 1);
}

#[test]
fn v47_triangle_base_out_of_order() {
    expect_gpu(Rule::GpuTreeShape, |nodes, _| nodes[0].triangle_base += 1);
}

#[test]
fn v47_meta_disagrees_with_the_inner_mask() {
    expect_gpu(Rule::GpuTreeShape, |nodes, _| {
        let (i, slot) = first_slot(nodes, false);
        nodes[i].inner_mask &= !(1 << slot);
    });
}

#[test]
fn v47_inner_meta_names_another_slot() {
    expect_gpu(Rule::GpuTreeShape, |nodes, _| {
        let (i, slot) = first_slot(nodes, false);
        nodes[i].meta[slot] = inner_meta((slot + 1) % 8);
    });
}

#[test]
fn v47_leaf_offsets_leave_a_gap() {
    expect_gpu(Rule::GpuTreeShape, |nodes, _| {
        let (i, slot) = first_slot(nodes, true);
        let GpuSlot::Leaf { first, count } = nodes[i].slot(slot) else { unreachable!() };
        nodes[i].meta[slot] = leaf_meta((first - nodes[i].triangle_base) as usize + 1, count as usize);
    });
}

#[test]
fn v47_invalid_unary_count() {
    expect_gpu(Rule::GpuTreeShape, |nodes, _| {
        let (i, slot) = first_slot(nodes, true);
        nodes[i].meta[slot] = (nodes[i].meta[slot] & 31) | 0b1010_0000;
    });
}

#[test]
fn v47_empty_slot_with_box_bytes() {
    expect_gpu(Rule::GpuTreeShape, |nodes, _| {
        let (i, slot) = nodes
            .iter()
            .enumerate()
            .find_map(|(i, n)| (0..8).find(|&s| n.meta[s] == 0).map(|s| (i, s)))
            .expect("an empty slot");
        nodes[i].quantized_max[0][slot] = 1;
    });
}

#[test]
fn v47_a_node_with_one_slot_below_the_root() {
    expect_gpu(Rule::GpuTreeShape, |nodes, _| {
        // The last node keeps only its first occupied slot: too few, and the triangles no longer tile.
        let last = nodes.len() - 1;
        let keep = (0..8).find(|&s| nodes[last].meta[s] != 0).unwrap();
        for slot in (keep + 1)..8 {
            nodes[last].meta[slot] = 0;
            for a in 0..3 {
                nodes[last].quantized_min[a][slot] = 0;
                nodes[last].quantized_max[a][slot] = 0;
            }
        }
    });
}

#[test]
fn v48_exponent_out_of_range() {
    expect_gpu(Rule::GpuBox, |nodes, _| nodes[2].exponents[1] = 255);
}

#[test]
fn v48_inner_box_does_not_contain_its_child() {
    expect_gpu(Rule::GpuBox, |nodes, _| {
        let (i, slot) = first_slot(nodes, false);
        let node = &mut nodes[i];
        node.quantized_max[2][slot] = node.quantized_min[2][slot];
    });
}

#[test]
fn v48_decoded_box_min_above_max() {
    expect_gpu(Rule::GpuBox, |nodes, _| {
        let (i, slot) = first_slot(nodes, true);
        nodes[i].quantized_min[0][slot] = 255;
        nodes[i].quantized_max[0][slot] = 0;
    });
}

#[test]
fn v48_subnormal_decoded_bound() {
    let detail = expect_gpu(Rule::GpuBox, |nodes, _| {
        let (i, slot) = first_slot(nodes, true);
        // A normal origin and grid step whose sum is subnormal: -1.5 * 2^-126 + 1 * 2^-126 = -2^-127.
        nodes[i].origin[1] = -1.5 * f32::MIN_POSITIVE;
        nodes[i].exponents[1] = 1;
        nodes[i].quantized_min[1][slot] = 1;
        nodes[i].quantized_max[1][slot] = 1;
    });
    assert!(detail.contains("decoded box"), "{detail}");
}

#[test]
fn v48_the_values_empty_slots_decode_to_are_zero_or_normal() {
    // An empty slot's box bytes are 0, so it decodes to the node's origin, which must then be zero or normal.
    let detail = expect_gpu(Rule::GpuBox, |nodes, _| {
        let i = (nodes.iter().position(|n| n.meta.contains(&0))).expect("a node with an empty slot");
        nodes[i].origin[2] = f32::from_bits(1);
    });
    assert!(detail.contains("origin"), "{detail}");
}

#[test]
fn v38_gpu_leaves_hold_at_most_max_leaf_size_triangles() {
    let file = gpu_file(&random_triangles(74, 300, 1.0));
    let view = file.view();
    let gpu = view.gpu_sections().unwrap();
    let largest = (gpu.nodes.iter())
        .flat_map(|n| (0..8).map(move |s| n.slot(s)))
        .filter_map(|slot| match slot {
            GpuSlot::Leaf { count, .. } => Some(count),
            _ => None,
        })
        .max()
        .unwrap();
    assert!(largest >= 2, "the good file has a GPU leaf of {largest} triangles");
    let metadata = |limit: u32| {
        format!(
            r#"{{"generator":"bvhc tests","format_version":"1.4","build":{{"gpu":{{"max_leaf_size":{limit},"node_visit":1.0,"triangle_test":0.3}}}}}}"#
        )
    };
    let written = |limit: u32| {
        bvhc::loader::write::BvhWriter::new(view.nodes(), view.triangles())
            .triangle_ids(view.triangle_ids().unwrap())
            .source_table(view.source_table().unwrap())
            .metadata(&metadata(limit))
            .gpu(gpu.nodes, gpu.triangles)
            .build()
    };
    assert!(written(largest).is_ok());
    let error = written(largest - 1).unwrap_err();
    assert_eq!(error.rule(), Some(Rule::MetadataBuild), "{error}");
    assert!(error.to_string().contains("gpu.max_leaf_size"), "{error}");
}

#[test]
fn v49_triangle_vertices_differ_from_the_record() {
    expect_gpu(Rule::GpuTriangles, |_, triangles| {
        triangles[3].vertices[1][2] = f32::from_bits(triangles[3].vertices[1][2].to_bits() ^ 1)
    });
}

#[test]
fn v49_a_record_named_twice_and_another_never() {
    expect_gpu(Rule::GpuTriangles, |nodes, triangles| {
        // The second triangle of a leaf becomes a copy of its first: the node's content does not grow (V48 holds).
        let first = nodes
            .iter()
            .flat_map(|n| (0..8).map(move |s| n.slot(s)))
            .find_map(|slot| match slot {
                GpuSlot::Leaf { first, count } if count >= 2 => Some(first as usize),
                _ => None,
            })
            .expect("a leaf of two triangles");
        triangles[first + 1] = triangles[first];
    });
}

#[test]
fn v49_triangle_index_out_of_range() {
    expect_gpu(Rule::GpuTriangles, |_, triangles| triangles[2].triangle_index = 1_000_000);
}

#[test]
fn v50_leaf_triangle_outside_its_box() {
    expect_gpu(Rule::GpuLeafBox, |nodes, triangles| {
        // Two leaves of one node swap a triangle: the node's content is unchanged (V48 holds), every record is
        // still named once with its vertices (V49), but one triangle now lies outside its leaf's box.
        for node in nodes.iter() {
            let leaves: Vec<(usize, u32)> = (0..8)
                .filter_map(|s| match node.slot(s) {
                    GpuSlot::Leaf { first, .. } => Some((s, first)),
                    _ => None,
                })
                .collect();
            for &(slot_a, first_a) in &leaves {
                for &(_, first_b) in &leaves {
                    let (min, max) = node.slot_box(slot_a);
                    let outside = triangles[first_b as usize]
                        .vertices
                        .iter()
                        .any(|v| (0..3).any(|a| v[a] < min[a] || v[a] > max[a]));
                    if outside {
                        triangles.swap(first_a as usize, first_b as usize);
                        return;
                    }
                }
            }
        }
        panic!("no two leaves of a node to swap between");
    });
}

#[test]
fn v8_gpu_sections_come_together_and_only_in_1_4() {
    let bytes = good_gpu_bytes();
    let mut alone = bytes.clone();
    // Renaming gpu_triangles to a private kind leaves gpu_nodes alone.
    alone[entry(GPU_TRIANGLES)..entry(GPU_TRIANGLES) + 4].copy_from_slice(&0x8000_0001u32.to_le_bytes());
    refresh_checksums(&mut alone);
    assert_eq!(broken_rule(&alone), Some(Rule::SectionMultiplicity));
    let mut older = bytes;
    crate::corrupt::relabel_minor(&mut older, 4, 3);
    assert_eq!(broken_rule(&older), Some(Rule::SectionMultiplicity));
}

#[test]
fn v9_gpu_sections_are_not_required() {
    let mut bytes = good_gpu_bytes();
    let flags = entry(GPU_NODES) + 4;
    bytes[flags] |= 1;
    refresh_checksums(&mut bytes);
    assert_eq!(broken_rule(&bytes), Some(Rule::SectionKindLayout));
}

#[test]
fn v10_gpu_counts() {
    // One GPU triangle fewer than records (without split references): the section is rewritten shorter.
    let triangles = random_triangles(72, 40, 1.0);
    let file = gpu_file(&triangles);
    let gpu = file.view().gpu_sections().unwrap();
    let view = file.view();
    let write = |nodes: &[GpuNode], gpu_triangles: &[GpuTriangle]| {
        let writer = bvhc::loader::write::BvhWriter::new(view.nodes(), view.triangles())
            .triangle_ids(view.triangle_ids().unwrap())
            .source_table(view.source_table().unwrap())
            .metadata(crate::gpu_compare::METADATA_1_4)
            .gpu(nodes, gpu_triangles);
        writer.build().err().and_then(|e| e.rule())
    };
    assert_eq!(write(gpu.nodes, &gpu.triangles[1..]), Some(Rule::Counts));
    assert_eq!(write(&[], gpu.triangles), Some(Rule::Counts));
}

#[test]
fn v38_build_gpu_agrees_with_the_sections() {
    let triangles = random_triangles(73, 40, 1.0);
    let file = gpu_file(&triangles);
    let view = file.view();
    let gpu = view.gpu_sections().unwrap();
    let with_key = r#"{"generator":"bvhc tests","format_version":"1.4","build":{"gpu":{"max_leaf_size":3,"node_visit":1.0,"triangle_test":0.3}}}"#;
    let older_key = with_key.replace("1.4", "1.0");
    let without_sections = bvhc::loader::write::BvhWriter::new(view.nodes(), view.triangles())
        .triangle_ids(view.triangle_ids().unwrap())
        .source_table(view.source_table().unwrap())
        .metadata(&older_key);
    assert_eq!(without_sections.build().err().and_then(|e| e.rule()), Some(Rule::MetadataBuild));
    let with_sections = bvhc::loader::write::BvhWriter::new(view.nodes(), view.triangles())
        .triangle_ids(view.triangle_ids().unwrap())
        .source_table(view.source_table().unwrap())
        .metadata(with_key)
        .gpu(gpu.nodes, gpu.triangles);
    assert!(with_sections.build().is_ok());
    let missing_key = r#"{"generator":"bvhc tests","format_version":"1.4","build":{"write_ids":true}}"#;
    let without_key = bvhc::loader::write::BvhWriter::new(view.nodes(), view.triangles())
        .triangle_ids(view.triangle_ids().unwrap())
        .source_table(view.source_table().unwrap())
        .metadata(missing_key)
        .gpu(gpu.nodes, gpu.triangles);
    assert!(without_key.build().is_ok(), "an absent key is not checked (section 8)");
    let null_key = missing_key.replace(r#""write_ids":true"#, r#""gpu":null"#);
    let with_null = bvhc::loader::write::BvhWriter::new(view.nodes(), view.triangles())
        .triangle_ids(view.triangle_ids().unwrap())
        .source_table(view.source_table().unwrap())
        .metadata(&null_key)
        .gpu(gpu.nodes, gpu.triangles);
    assert_eq!(with_null.build().err().and_then(|e| e.rule()), Some(Rule::MetadataBuild));
}
