//! The wide layout's refit: each packet lane's vertices copied from the triangle record it names, and every
//! slot's box recomputed bottom up (a leaf slot's from its packets' lanes, an inner slot's from its child's
//! slots), keeping the tree's shape.

use std::ops::Range;

use crate::format::cost::AreaSums;
use crate::format::{
    Bounds, EMPTY_BOUNDS, EMPTY_SLOT, LEAF_BIT, PACKET_LANES, PackedTriangle, TrianglePacket4, UNUSED_LANE,
    UNUSED_LANE_COORDINATE_BITS, WIDE, WideNode8,
};
use crate::parallel::Workers;
use crate::subtrees::{TreeShape, carve, cut};

/// Wide nodes from which the tree is cut into subtrees, each refit on its own while it is in cache, on threads
/// where the caller allows them (below, the tree is one run on one thread: a thread's start costs more than it
/// saves).
const CUT_NODES: usize = 1 << 10;

/// Parts a cut aims at: several a thread, so that threads balance subtrees of unequal sizes.
const PARTS: usize = 32;

/// Rewrites `packets`' used lanes from `records` (each lane's `triangle_index` record) and every slot box of
/// `nodes` (a verified file's wide tree, children after parents, V29-V35) bottom up, as the converter's packing
/// computes them: a leaf slot's box the box of its packets' lanes, folded from the records as the lanes are
/// written, an inner slot's the box of its child's slots. Returns the refit tree's area sums (section 6.1's,
/// summed as the boxes are made). A large tree in the layout bvhc writes is cut into subtrees
/// (`crate::subtrees`), each refit in one forward pass over its leaf slots (the packets streaming in order) and
/// one backward pass over its inner slots, the subtrees on `workers`' threads; any other tree is refit whole,
/// node by node on one thread, with the same result. Indices out of range (a file that does not verify) leave
/// lanes as they are and boxes empty rather than panic.
pub(crate) fn refit_wide(
    nodes: &mut [WideNode8],
    packets: &mut [TrianglePacket4],
    records: &[PackedTriangle],
    workers: Workers,
) -> AreaSums {
    let refit = match nodes.len() >= CUT_NODES {
        true => refit_by_parts(nodes, packets, records, workers),
        false => refit_run(nodes, 0, packets, 0, records),
    };
    refit.unwrap_or_else(|| refit_whole(nodes, packets, records))
}

/// The wide tree as [`cut`] sees it: a node's inner slots name its children.
struct Slots<'a>(&'a [WideNode8]);

impl TreeShape for Slots<'_> {
    fn node_count(&self) -> usize {
        self.0.len()
    }

    fn for_each_inner_child(&self, node: usize, mut child: impl FnMut(usize)) {
        let Some(node) = self.0.get(node) else { return };
        node.child.iter().filter(|&&c| c != EMPTY_SLOT && c & LEAF_BIT == 0).for_each(|&c| child(c as usize));
    }
}

/// Refits the tree cut into parts (each with its run of nodes and of packets) on `workers`' threads, then its
/// top on this one. `None`, with some lanes and boxes written, where the tree does not keep to bvhc's layout.
fn refit_by_parts(
    nodes: &mut [WideNode8],
    packets: &mut [TrianglePacket4],
    records: &[PackedTriangle],
    workers: Workers,
) -> Option<AreaSums> {
    let cut = cut(&Slots(nodes), PARTS)?;
    let packet_runs: Vec<Range<usize>> = cut.parts.iter().map(|part| leaf_packets(&nodes[part.clone()])).collect();
    let part_packets = carve(packets, &packet_runs)?;
    let tasks: Vec<_> = carve(nodes, &cut.parts)?
        .into_iter()
        .zip(part_packets)
        .zip(cut.parts.iter().zip(&packet_runs))
        .map(|((nodes, packets), (part, run))| {
            (part.len(), move || refit_run(nodes, part.start, packets, run.start, records))
        })
        .collect();
    let mut sums = AreaSums::default();
    for part_sums in workers.run_largest_first(tasks) {
        sums = sums.plus(part_sums?);
    }
    Some(cut.top.iter().fold(sums, |sums, &node| sums.plus(refit_node(nodes, node, packets, records))))
}

/// Refits node `node`'s slots from what lies below them, refit already: a leaf slot rewrites its packets and
/// takes their box, an inner slot its child's box. Returns the node's area sums. Indices out of range (a file
/// that does not verify) give an empty box rather than panic.
fn refit_node(
    nodes: &mut [WideNode8],
    node: usize,
    packets: &mut [TrianglePacket4],
    records: &[PackedTriangle],
) -> AreaSums {
    for slot in 0..WIDE {
        let child = nodes[node].child[slot];
        let bounds = if child == EMPTY_SLOT {
            continue;
        } else if child & LEAF_BIT != 0 {
            let (first, count) = WideNode8::leaf_packets(child);
            refit_packets(packets.get_mut(first as usize..(first + count) as usize).unwrap_or(&mut []), records)
        } else {
            nodes.get(child as usize).map_or(EMPTY_BOUNDS, node_box)
        };
        nodes[node].set_slot_box(slot, bounds);
    }
    slot_sums(&nodes[node])
}

/// The packets the leaf slots of a part's nodes name, in bvhc's layout (packets in the order of the nodes and
/// slots that hold them): from the first leaf slot's first packet to the last one's end; empty without leaves.
fn leaf_packets(nodes: &[WideNode8]) -> Range<usize> {
    let leaves = |node: &WideNode8| {
        let slots = node.child.into_iter().filter(|&c| c != EMPTY_SLOT && c & LEAF_BIT != 0);
        slots.map(WideNode8::leaf_packets).map(|(first, count)| first as usize..(first + count) as usize)
    };
    let first = nodes.iter().find_map(|node| leaves(node).next());
    let last = nodes.iter().rev().find_map(|node| leaves(node).next_back());
    match (first, last) {
        (Some(first), Some(last)) if first.start <= last.end => first.start..last.end,
        _ => 0..0,
    }
}

/// Refits a run of nodes that holds whole subtrees (the nodes `node_base ..`, children after parents) over the
/// run of packets `packet_base ..`: forwards over its leaf slots, each rewriting its packets and taking their
/// box, then backwards over its inner slots, each taking its child's box. Returns the run's area sums; `None`
/// where a child or a packet lies outside the runs (or a child before its parent): the run is then partly refit.
fn refit_run(
    nodes: &mut [WideNode8],
    node_base: usize,
    packets: &mut [TrianglePacket4],
    packet_base: usize,
    records: &[PackedTriangle],
) -> Option<AreaSums> {
    let mut sums = AreaSums::default();
    for node in nodes.iter_mut() {
        for slot in 0..WIDE {
            let child = node.child[slot];
            if child == EMPTY_SLOT || child & LEAF_BIT == 0 {
                continue;
            }
            let (first, count) = WideNode8::leaf_packets(child);
            let first = (first as usize).wrapping_sub(packet_base);
            let leaf = packets.get_mut(first..first.saturating_add(count as usize))?;
            node.set_slot_box(slot, refit_packets(leaf, records));
        }
    }
    for i in (0..nodes.len()).rev() {
        for slot in 0..WIDE {
            let child = nodes[i].child[slot];
            if child == EMPTY_SLOT || child & LEAF_BIT != 0 {
                continue;
            }
            let child = (child as usize).wrapping_sub(node_base);
            if child <= i || child >= nodes.len() {
                return None;
            }
            let bounds = node_box(&nodes[child]);
            nodes[i].set_slot_box(slot, bounds);
        }
        sums = sums.plus(slot_sums(&nodes[i]));
    }
    Some(sums)
}

/// The area sums of a node's slots (section 6.1): its inner slots' areas, and its leaf slots' areas each times
/// its packet count, each area as [`box_area`] computes it; the eight slots at once (their boxes are stored axis
/// by axis), an empty slot counting 0.
fn slot_sums(node: &WideNode8) -> AreaSums {
    let (mut inner, mut leaf) = (0.0, 0.0);
    for slot in 0..WIDE {
        let extent = |a: usize| {
            let e = f64::from(node.max[a][slot]) - f64::from(node.min[a][slot]);
            if e > 0.0 { e } else { 0.0 }
        };
        let (x, y, z) = (extent(0), extent(1), extent(2));
        let area = 2.0 * (x * y + y * z + z * x);
        let child = node.child[slot];
        let packets = f64::from(WideNode8::leaf_packets(child).1);
        inner += if child & LEAF_BIT == 0 { area } else { 0.0 };
        leaf += if child != EMPTY_SLOT && child & LEAF_BIT != 0 { area * packets } else { 0.0 };
    }
    AreaSums { inner, leaf }
}

/// The vertices of an unused lane (V33).
const UNUSED_ROW: [[f32; 3]; 3] = [[f32::from_bits(UNUSED_LANE_COORDINATE_BITS); 3]; 3];

/// Rewrites the used lanes of a leaf's packets from the records they name (a lane naming no record keeps its
/// vertices) and returns the box of the used lanes' vertices. Each packet is assembled lane by lane into a local
/// copy (a transposition of four records), boxed there four lanes at a time (an unused lane's NaN coordinates
/// pass over the compare-and-selects, as in the unused lanes of the format, V33) and stored whole.
fn refit_packets(packets: &mut [TrianglePacket4], records: &[PackedTriangle]) -> Bounds {
    type Four = [f32; PACKET_LANES];
    let mut low = [[f32::INFINITY; PACKET_LANES]; 3];
    let mut high = [[f32::NEG_INFINITY; PACKET_LANES]; 3];
    for packet in packets {
        let rows: [&[[f32; 3]; 3]; PACKET_LANES] = std::array::from_fn(|lane| {
            let index = packet.triangle_index[lane];
            records.get(index as usize).filter(|_| index != UNUSED_LANE).map_or(&UNUSED_ROW, |r| &r.vertices)
        });
        let vertices: [[Four; 3]; 3] =
            std::array::from_fn(|v| std::array::from_fn(|a| std::array::from_fn(|lane| rows[lane][v][a])));
        for a in 0..3 {
            for corner in &vertices {
                low[a] = std::array::from_fn(|l| if corner[a][l] < low[a][l] { corner[a][l] } else { low[a][l] });
                high[a] = std::array::from_fn(|l| if corner[a][l] > high[a][l] { corner[a][l] } else { high[a][l] });
            }
        }
        packet.vertices = vertices;
    }
    let lower = |a: f32, b: f32| if b < a { b } else { a };
    let upper = |a: f32, b: f32| if b > a { b } else { a };
    (
        low.map(|l| lower(lower(l[0], l[2]), lower(l[1], l[3]))),
        high.map(|h| upper(upper(h[0], h[2]), upper(h[1], h[3]))),
    )
}

/// Refits any tree (one not in bvhc's layout, or one that does not verify) node by node in reverse node order,
/// on one thread: children come after their parent (V29), so each node's children are refit before it.
fn refit_whole(nodes: &mut [WideNode8], packets: &mut [TrianglePacket4], records: &[PackedTriangle]) -> AreaSums {
    (0..nodes.len()).rev().fold(AreaSums::default(), |sums, node| sums.plus(refit_node(nodes, node, packets, records)))
}

/// A wide node's box: the union of its eight slots' boxes (empty slots hold the empty box `+inf..-inf`, V29, so
/// all eight are folded alike).
pub(crate) fn node_box(node: &WideNode8) -> Bounds {
    let lowest = |axis: &[f32; WIDE]| axis.iter().fold(f32::INFINITY, |m, &v| if v < m { v } else { m });
    let highest = |axis: &[f32; WIDE]| axis.iter().fold(f32::NEG_INFINITY, |m, &v| if v > m { v } else { m });
    (node.min.each_ref().map(lowest), node.max.each_ref().map(highest))
}
