//! The top trees of a two-level file (format 1.3), built over the instances' world boxes: [`build_top_tree`] the
//! binary one (`top_nodes`, binned SAH), [`collapse_top_tree`] its 8-wide form (`top_wide_nodes`). The converter
//! builds a file's top trees with them, and a program that has moved instances far
//! ([`crate::BvhViewMut::move_instances`] refits the top trees, keeping their shape, whose boxes then overlap
//! where instances crossed) rebuilds them here with the same builder: [`BvhView::rebuilt_top_trees`] (feature
//! `write`) gives the tree a fresh conversion of the moved scene would, at the price of a new file (the wide top
//! tree may change its node count), and [`BvhView::top_tree_cost`] tells when that pays.
//!
//! The builder's quality suffices because it is the conversion's own: top trees hold one instance a leaf and a
//! few thousand leaves at most in the scenes bvhc sees, where a full binned SAH build over every instance's box
//! takes milliseconds (10,000 instances: 7.6 ms for the whole rebuilt file, `cargo bench --bench refit`), so
//! nothing cheaper is needed; and the trees it builds are those the converter's files are measured with.

mod build;
mod wide;

pub use build::{MEDIAN_BELOW_DEPTH, build_top_tree};
pub use wide::collapse_top_tree;

use crate::format::PackedNode;
use crate::format::cost::box_area;
use crate::open::view::BvhView;

#[cfg(feature = "write")]
use crate::{
    error::Error, format::Affine3x4, open::file::BvhFile, open::sections::TwoLevelSections,
    ray::transform::instance_world_box, write::BvhWriter,
};

impl BvhView<'_> {
    /// The SAH cost of a two-level file's binary top tree over its instances: the inner nodes' areas plus the
    /// leaves' areas (each instance counted as one), over the root's; `None` for a one-level file. A refit top
    /// tree whose cost exceeds a rebuilt one's ([`BvhView::rebuilt_top_trees`]) by more than the rebuild's price
    /// is worth rebuilding.
    pub fn top_tree_cost(&self) -> Option<f64> {
        let nodes: &[PackedNode] = self.two_level()?.top_nodes;
        let root = nodes.first()?;
        let root_area = box_area(&root.min, &root.max);
        if root_area <= 0.0 {
            return Some(0.0);
        }
        Some(nodes.iter().map(|n| box_area(&n.min, &n.max)).sum::<f64>() / root_area)
    }

    /// This two-level file with both top trees built anew over its instances' world boxes (each mesh's root box
    /// mapped by its instance and padded, as the converter computes them), by the converter's builder
    /// ([`build_top_tree`], [`collapse_top_tree`]); every other section kept, the file laid out anew (the wide
    /// top tree may change its node count) and verified. For the occasional rebuild a [`BvhView::top_tree_cost`]
    /// comparison calls for after large moves, not every frame. An error for a one-level file, or where a world
    /// box does not fit f32 (naming the instance).
    #[cfg(feature = "write")]
    pub fn rebuilt_top_trees(&self) -> Result<BvhFile, Error> {
        let Some(sections) = self.two_level() else {
            return Err(Error::Refit("a one-level file has no top tree to rebuild".into()));
        };
        let mut boxes = Vec::with_capacity(sections.instances.len());
        for (index, instance) in sections.instances.iter().enumerate() {
            let root =
                sections.meshes.get(instance.mesh_index as usize).and_then(|m| self.nodes().get(m.first_node as usize));
            let refused = |why: &str| Error::Refit(format!("instance {index}: {why}"));
            let root = root.ok_or_else(|| refused("its mesh has no root"))?;
            let map: &Affine3x4 = &instance.object_to_world;
            boxes.push(
                instance_world_box(map, (root.min, root.max))
                    .ok_or_else(|| refused("its world box does not fit f32"))?,
            );
        }
        let top_nodes = build_top_tree(&boxes);
        let top_wide_nodes =
            if sections.top_wide_nodes.is_empty() { Vec::new() } else { collapse_top_tree(&top_nodes) };
        let rebuilt = TwoLevelSections { top_nodes: &top_nodes, top_wide_nodes: &top_wide_nodes, ..sections };
        let mut writer = BvhWriter::from_view(self).two_level(rebuilt);
        if let Some(metadata) = self.metadata_str().transpose()? {
            writer = writer.metadata(metadata);
        }
        writer.build()
    }
}

#[cfg(feature = "write")]
impl BvhFile {
    /// [`BvhView::rebuilt_top_trees`] of the file.
    pub fn rebuilt_top_trees(&self) -> Result<BvhFile, Error> {
        self.view().rebuilt_top_trees()
    }
}
