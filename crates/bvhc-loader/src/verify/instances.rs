//! Rules V41-V46 of `format-spec/bvh-1.md`: the two-level sections of format 1.3, and the one-level rules
//! applied to each mesh.
//!
//! * V41: the meshes tile the nodes, triangles and wide sections in order, each with the counts of a one-level
//!   file (V10); each mesh's ranges then obey V14-V20, V25 and V29-V35 as a file of their own would (errors
//!   name the mesh and the node, triangle or packet relative to its ranges);
//! * V42: each instance names a mesh, and its transforms are finite, invertible and each other's inverse;
//! * V43: the top tree has the shape of a binary tree of rules V14, V16, V17 and V20 whose leaves hold one
//!   instance each, every instance in exactly one leaf (so each placement is reachable exactly once, and the
//!   walk never recurses: a leaf names an instance, an instance a mesh, a mesh only triangles);
//! * V44: a top leaf's box contains its instance's mesh root box mapped to world space (conservative);
//! * V45: every mesh is placed by at least one instance;
//! * V46: the wide top tree, where the file has one: a tree of wide nodes whose leaf slots hold every instance
//!   once, with conservative boxes.
//!
//! Cost: O(top nodes + instances + meshes) beyond the per-mesh rules, whose cost is that of the one-level rules
//! over the same sections. Memory: a bit per top node, instance and mesh.

use crate::error::{Rule, Violation, violation};
use crate::format::{EMPTY_SLOT, LEAF_BIT, MAX_DEPTH, MeshRecord, PackedNode, PackedTriangle, WideNode8};
use crate::open::sections::TwoLevelSections;
use crate::open::sections::WideSections;
use crate::open::structure::check_wide_counts;
use crate::open::view::BvhView;
use crate::ray::transform::{check_transform, transformed_box};
use crate::verify::references::verify_references;
use crate::verify::tree::verify_tree;
use crate::verify::wide::{WideContext, verify_wide};

/// A mesh's ranges of the one-level sections.
struct MeshSlices<'a> {
    nodes: &'a [PackedNode],
    triangles: &'a [PackedTriangle],
    triangle_ids: Option<&'a [u32]>,
    wide: Option<WideSections<'a>>,
}

/// `first..first + count` of `items`; V41 has proven it in bounds before any caller slices.
fn range<T>(items: &[T], first: u32, count: u32) -> &[T] {
    let start = first as usize;
    items.get(start..start.saturating_add(count as usize)).unwrap_or(&[])
}

fn mesh_slices<'a>(view: &BvhView<'a>, mesh: &MeshRecord) -> MeshSlices<'a> {
    let ids = view.triangle_ids().map(|ids| range(ids, mesh.first_triangle, mesh.triangle_count));
    MeshSlices {
        nodes: range(view.nodes(), mesh.first_node, mesh.node_count),
        triangles: range(view.triangles(), mesh.first_triangle, mesh.triangle_count),
        triangle_ids: ids,
        wide: view.wide_sections().map(|wide| WideSections {
            nodes: range(wide.nodes, mesh.first_wide_node, mesh.wide_node_count),
            packets: range(wide.packets, mesh.first_packet, mesh.packet_count),
        }),
    }
}

/// `violation` with the mesh named before its detail.
fn in_mesh(m: usize, violation: Violation) -> Violation {
    Violation { detail: format!("mesh {m}: {}", violation.detail), ..violation }
}

/// V41: the mesh table, then V14-V20 and V24-V25 per mesh (V24 over all ids: ids are distinct file-wide).
pub(crate) fn verify_meshes(view: &BvhView<'_>, sections: &TwoLevelSections<'_>) -> Result<(), Violation> {
    check_mesh_table(view, sections.meshes)?;
    let split = view.has_split_references();
    if !split {
        verify_references(&[], &[], view.triangle_ids(), false)?;
    }
    for (m, mesh) in sections.meshes.iter().enumerate() {
        let slices = mesh_slices(view, mesh);
        verify_tree(slices.nodes, slices.triangles, split).map_err(|v| in_mesh(m, v))?;
        if split {
            verify_references(slices.nodes, slices.triangles, slices.triangle_ids, true).map_err(|v| in_mesh(m, v))?;
        }
    }
    Ok(())
}

/// V29-V35 per mesh.
pub(crate) fn verify_mesh_wide(view: &BvhView<'_>, sections: &TwoLevelSections<'_>) -> Result<(), Violation> {
    for (m, mesh) in sections.meshes.iter().enumerate() {
        let slices = mesh_slices(view, mesh);
        let Some(wide) = slices.wide else { return Ok(()) };
        let context = WideContext {
            triangles: slices.triangles,
            triangle_ids: slices.triangle_ids,
            root_box: slices.nodes.first().map(|root| (root.min, root.max)),
            split_references: view.has_split_references(),
        };
        verify_wide(wide.nodes, wide.packets, &context).map_err(|v| in_mesh(m, v))?;
    }
    Ok(())
}

/// V41's table part: in order, the meshes tile each section, with a one-level file's counts.
fn check_mesh_table(view: &BvhView<'_>, meshes: &[MeshRecord]) -> Result<(), Violation> {
    let wide = view.wide_sections();
    let section_lens = [
        view.nodes().len() as u64,
        view.triangles().len() as u64,
        wide.map_or(0, |w| w.nodes.len() as u64),
        wide.map_or(0, |w| w.packets.len() as u64),
    ];
    let names = ["nodes", "triangles", "wide_nodes", "triangle_packets"];
    let mut next = [0u64; 4];
    for (m, mesh) in meshes.iter().enumerate() {
        let fail = |detail: String| Err(violation(Rule::MeshTable, format!("mesh {m}: {detail}")));
        let ranges = [
            (mesh.first_node, mesh.node_count),
            (mesh.first_triangle, mesh.triangle_count),
            (mesh.first_wide_node, mesh.wide_node_count),
            (mesh.first_packet, mesh.packet_count),
        ];
        for (k, &(first, count)) in ranges.iter().enumerate() {
            if u64::from(first) != next[k] {
                return fail(format!(
                    "{} start at {first}, expected {} (meshes tile the section in order)",
                    names[k], next[k]
                ));
            }
            next[k] += u64::from(count);
            if next[k] > section_lens[k] {
                return fail(format!(
                    "{} {first}..{} run past the section's {} elements",
                    names[k], next[k], section_lens[k]
                ));
            }
        }
        let (nodes, triangles) = (u64::from(mesh.node_count), u64::from(mesh.triangle_count));
        if triangles == 0 || nodes.is_multiple_of(2) || nodes > 2 * triangles - 1 {
            return fail(format!(
                "{nodes} nodes for {triangles} triangles: at least one triangle, and an odd number of nodes at most \
                 2 x triangle_count - 1"
            ));
        }
        // Without wide sections the tiling above has already held every wide range empty.
        if wide.is_some() {
            check_wide_counts(u64::from(mesh.wide_node_count), u64::from(mesh.packet_count), triangles)
                .map_err(|v| in_mesh(m, Violation { rule: Rule::MeshTable, ..v }))?;
        }
    }
    if let Some(k) = (0..4).find(|&k| next[k] != section_lens[k]) {
        return Err(violation(
            Rule::MeshTable,
            format!(
                "the meshes cover {} of the {} {} (every element belongs to one mesh)",
                next[k], section_lens[k], names[k]
            ),
        ));
    }
    Ok(())
}

/// V42-V46.
pub(crate) fn verify_instances(sections: &TwoLevelSections<'_>, nodes: &[PackedNode]) -> Result<(), Violation> {
    let mut placed = vec![false; sections.meshes.len()];
    for (i, instance) in sections.instances.iter().enumerate() {
        let fail = |detail: String| Err(violation(Rule::InstanceTransform, format!("instance {i}: {detail}")));
        let Some(seen) = placed.get_mut(instance.mesh_index as usize) else {
            return fail(format!(
                "mesh_index {} out of range (mesh count {})",
                instance.mesh_index,
                sections.meshes.len()
            ));
        };
        *seen = true;
        if let Err(why) = check_transform(instance) {
            return fail(why);
        }
    }
    check_top_tree(sections, nodes)?;
    if let Some(m) = placed.iter().position(|&p| !p) {
        return Err(violation(Rule::MeshPlaced, format!("mesh {m} is placed by no instance")));
    }
    check_top_wide_tree(sections, nodes)
}

/// V43, depth first (the tree's shape, boxes and leaves), then V44 on every leaf.
fn check_top_tree(sections: &TwoLevelSections<'_>, nodes: &[PackedNode]) -> Result<(), Violation> {
    let top = sections.top_nodes;
    let fail = |detail: String| Err(violation(Rule::TopTree, detail));
    let mut reached = vec![false; top.len()];
    let mut instance_seen = vec![false; sections.instances.len()];
    let mut stack: Vec<(usize, usize)> = vec![(0, 0)];
    while let Some((i, depth)) = stack.pop() {
        let node = &top[i];
        if depth > MAX_DEPTH {
            return fail(format!("top node {i}: depth {depth} exceeds {MAX_DEPTH}"));
        }
        if std::mem::replace(&mut reached[i], true) {
            return fail(format!("top node {i}: reached twice"));
        }
        let finite = node.min.iter().chain(&node.max).all(|c| c.is_finite());
        if !finite || (0..3).any(|a| node.min[a] > node.max[a]) {
            return fail(format!("top node {i}: box {:?}..{:?} must be finite with min <= max", node.min, node.max));
        }
        if node.is_leaf() {
            let index = node.index as usize;
            if node.count != 1 || index >= instance_seen.len() {
                return fail(format!(
                    "top node {i}: a leaf holds one instance below {} (index {}, count {})",
                    instance_seen.len(),
                    node.index,
                    node.count
                ));
            }
            if std::mem::replace(&mut instance_seen[index], true) {
                return fail(format!("top node {i}: instance {index} is in a second leaf"));
            }
            continue;
        }
        let first = node.index as usize;
        if first <= i || first + 1 >= top.len() {
            return fail(format!(
                "top node {i}: children {first} and {} must come after it and be < {}",
                first + 1,
                top.len()
            ));
        }
        for child in [first, first + 1] {
            let c = &top[child];
            if (0..3).any(|a| !(c.min[a] >= node.min[a] && c.max[a] <= node.max[a])) {
                return fail(format!(
                    "top node {child}: box {:?}..{:?} not inside parent {i} {:?}..{:?}",
                    c.min, c.max, node.min, node.max
                ));
            }
        }
        stack.push((first + 1, depth + 1));
        stack.push((first, depth + 1));
    }
    // Every leaf holds one instance and every instance is in at most one leaf; a binary tree of
    // `2 * instance_count - 1` nodes (V10) has `instance_count` leaves, so every node reached means every
    // instance in exactly one leaf.
    if let Some(i) = reached.iter().position(|&r| !r) {
        return fail(format!("top node {i}: unreachable from the root"));
    }
    for (i, leaf) in top.iter().enumerate().filter(|(_, node)| node.is_leaf()) {
        check_instance_box(sections, nodes, i, leaf)?;
    }
    Ok(())
}

/// V44 for top leaf `i`: its box contains the instance's mesh root box mapped to world space (in f64).
fn check_instance_box(
    sections: &TwoLevelSections<'_>,
    nodes: &[PackedNode],
    i: usize,
    leaf: &PackedNode,
) -> Result<(), Violation> {
    let Some((instance, mesh)) = sections.placement(leaf.index) else { return Ok(()) };
    let Some(root) = nodes.get(mesh.first_node as usize) else { return Ok(()) };
    let (lo, hi) = transformed_box(&instance.object_to_world, (root.min, root.max));
    let holds = (0..3).all(|a| f64::from(leaf.min[a]) <= lo[a] && hi[a] <= f64::from(leaf.max[a]));
    if holds {
        return Ok(());
    }
    Err(violation(
        Rule::InstanceBox,
        format!(
            "top node {i}: box {:?}..{:?} does not contain instance {}'s mesh box in world space {lo:?}..{hi:?}",
            leaf.min, leaf.max, leaf.index
        ),
    ))
}

/// V46: the wide top tree (`top_wide_nodes`), where the file has one. In node index order (children come after
/// their parent, so a node's parent slot is known when the node is reached): slots well formed, each node but
/// the root in exactly one slot, no node deeper than `MAX_DEPTH`, slot boxes finite and inside the box of the
/// slot that references the node (the top root's box for node 0), each instance in exactly one leaf slot,
/// whose box contains its mesh's root box mapped to world space (as V44 asks of the binary leaves; checked once
/// the shape holds).
fn check_top_wide_tree(sections: &TwoLevelSections<'_>, nodes: &[PackedNode]) -> Result<(), Violation> {
    let wide = sections.top_wide_nodes;
    let Some(root) = sections.top_nodes.first().filter(|_| !wide.is_empty()) else { return Ok(()) };
    let fail = |detail: String| Err(violation(Rule::TopWideTree, detail));
    let mut bound: Vec<Option<([f32; 3], [f32; 3])>> = vec![None; wide.len()];
    let mut depth = vec![0usize; wide.len()];
    bound[0] = Some((root.min, root.max));
    let mut seen = vec![false; sections.instances.len()];
    // (node, slot, instance, slot box) of every leaf slot, checked against the instances once the shape holds.
    let mut leaves = Vec::new();
    for (i, node) in wide.iter().enumerate() {
        let Some((lo, hi)) = bound[i] else { return fail(format!("top wide node {i}: in no slot")) };
        if depth[i] > MAX_DEPTH {
            return fail(format!("top wide node {i}: depth {} exceeds {MAX_DEPTH}", depth[i]));
        }
        let occupied = node.child.iter().take_while(|&&c| c != EMPTY_SLOT).count();
        if occupied < if i == 0 { 1 } else { 2 } {
            return fail(format!("top wide node {i}: {occupied} occupied slots"));
        }
        for (slot, &child) in node.child.iter().enumerate() {
            let (min, max) = slot_box(node, slot);
            let at = format!("top wide node {i} slot {slot}");
            if slot >= occupied {
                let empty = min.iter().all(|c| c.to_bits() == f32::INFINITY.to_bits())
                    && max.iter().all(|c| c.to_bits() == f32::NEG_INFINITY.to_bits());
                if child != EMPTY_SLOT || !empty {
                    return fail(format!("{at}: after an empty slot, must be EMPTY_SLOT with the box +inf..-inf"));
                }
                continue;
            }
            let finite = min.iter().chain(&max).all(|c| c.is_finite());
            if !finite || (0..3).any(|a| !(lo[a] <= min[a] && min[a] <= max[a] && max[a] <= hi[a])) {
                return fail(format!("{at}: box {min:?}..{max:?} must be finite, min <= max, inside {lo:?}..{hi:?}"));
            }
            if child & LEAF_BIT == 0 {
                let c = child as usize;
                if c <= i || c >= wide.len() || bound[c].is_some() {
                    return fail(format!("{at}: child {c} must come after it, exist and have no other slot"));
                }
                bound[c] = Some((min, max));
                depth[c] = depth[i] + 1;
                continue;
            }
            let index = (child & !LEAF_BIT) as usize;
            match seen.get_mut(index) {
                Some(done) if !*done => *done = true,
                _ => return fail(format!("{at}: leaf of instance {index}, which is out of range or in a second slot")),
            }
            leaves.push((i, slot, index as u32, (min, max)));
        }
    }
    if let Some(index) = seen.iter().position(|&s| !s) {
        return fail(format!("instance {index} is in no leaf slot of the wide top tree"));
    }
    for (i, slot, index, (min, max)) in leaves {
        let Some((instance, mesh)) = sections.placement(index) else { continue };
        let Some(mesh_root) = nodes.get(mesh.first_node as usize) else { continue };
        let (need_lo, need_hi) = transformed_box(&instance.object_to_world, (mesh_root.min, mesh_root.max));
        if (0..3).any(|a| !(f64::from(min[a]) <= need_lo[a] && need_hi[a] <= f64::from(max[a]))) {
            return fail(format!(
                "top wide node {i} slot {slot}: box {min:?}..{max:?} does not contain instance {index}'s mesh box \
                 in world space {need_lo:?}..{need_hi:?}"
            ));
        }
    }
    Ok(())
}

fn slot_box(node: &WideNode8, slot: usize) -> ([f32; 3], [f32; 3]) {
    (std::array::from_fn(|a| node.min[a][slot]), std::array::from_fn(|a| node.max[a][slot]))
}
