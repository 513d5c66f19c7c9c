//! A two-level file's top trees built anew over its instances as they now stand ([`rebuilt_top_trees`]): after
//! `BvhFile::move_instances` has refit them through large moves, the refit top tree keeps the shape it was
//! built with and its boxes overlap where instances crossed; the conversion's own builder ([`build_top_tree`],
//! binned SAH over the instances' world boxes, and [`collapse_top_tree`]) gives the tree a fresh conversion
//! would. The meshes are untouched; the file is laid out anew (the wide top tree may change its node count) and
//! verified, so this is for the occasional rebuild a [`top_tree_cost`] comparison calls for, not every frame.

use bvhc_loader::format::cost::box_area;
use bvhc_loader::format::{Affine3x4, PackedNode};
use bvhc_loader::ray::instance_world_box;
use bvhc_loader::write::BvhWriter;
use bvhc_loader::{BvhFile, BvhView, Error, TwoLevelSections};

use super::{build_top_tree, collapse_top_tree};

/// `file` (two-level) with both top trees built anew over its instances' world boxes (each mesh's root box
/// mapped by its instance and padded, as the converter computes them); every other section kept. An error for
/// a one-level file, or where a world box does not fit f32 (naming the instance).
pub fn rebuilt_top_trees(file: &BvhFile) -> Result<BvhFile, Error> {
    let view = file.view();
    let Some(sections) = view.two_level() else {
        return Err(Error::Refit("a one-level file has no top tree to rebuild".into()));
    };
    let mut boxes = Vec::with_capacity(sections.instances.len());
    for (index, instance) in sections.instances.iter().enumerate() {
        let root =
            sections.meshes.get(instance.mesh_index as usize).and_then(|m| view.nodes().get(m.first_node as usize));
        let refused = |why: &str| Error::Refit(format!("instance {index}: {why}"));
        let root = root.ok_or_else(|| refused("its mesh has no root"))?;
        let map: &Affine3x4 = &instance.object_to_world;
        boxes.push(
            instance_world_box(map, (root.min, root.max)).ok_or_else(|| refused("its world box does not fit f32"))?,
        );
    }
    let top_nodes = build_top_tree(&boxes);
    let top_wide_nodes = if sections.top_wide_nodes.is_empty() { Vec::new() } else { collapse_top_tree(&top_nodes) };
    let rebuilt = TwoLevelSections { top_nodes: &top_nodes, top_wide_nodes: &top_wide_nodes, ..sections };
    let mut writer = BvhWriter::from_view(&view).two_level(rebuilt);
    let metadata = view.metadata_str().transpose()?;
    if let Some(metadata) = metadata {
        writer = writer.metadata(metadata);
    }
    writer.build()
}

/// The SAH cost of `view`'s binary top tree over its instances: the inner nodes' areas plus the leaves' areas,
/// over the root's (each instance counted as one; `None` for a one-level file). A refit top tree whose cost
/// exceeds a rebuilt one's ([`rebuilt_top_trees`]) by more than the rebuild's price is worth rebuilding.
pub fn top_tree_cost(view: &BvhView<'_>) -> Option<f64> {
    let nodes: &[PackedNode] = view.two_level()?.top_nodes;
    let root = nodes.first()?;
    let root_area = box_area(&root.min, &root.max);
    if root_area <= 0.0 {
        return Some(0.0);
    }
    Some(nodes.iter().map(|n| box_area(&n.min, &n.max)).sum::<f64>() / root_area)
}
