//! Packets of up to eight coherent rays (camera rays of neighbouring pixels) traced through the wide sections
//! together: one traversal, its stack entries carrying a mask of the rays that go there (after Wald, Slusallek,
//! Benthin, Wagner, "Interactive Rendering with Coherent Ray Tracing", Eurographics 2001, on an 8-wide BVH).
//! At a wide node each occupied slot's box is tested against all the packet's rays at once, one ray a lane of
//! the instruction set's eight lanes, with the single-ray kernel's robust slab test per lane (Ize 2013; entry
//! and exit planes picked per lane by the sign of that ray's direction). Children are visited in the order of
//! the packet's first active ray; each stack entry keeps every lane's entry distance, so on pop the rays whose
//! closest hit is already nearer leave the packet. At a leaf, when the rays share their shear axes, each
//! triangle is tested against all active rays in lanes ([`crate::ray::watertight`]); otherwise each ray tests the
//! leaf's packets with the single-ray packet test (`wide_packets`).
//!
//! The eight rays are set up in lanes: their records transposed into fields (one `Isa::transpose8`), then the
//! reciprocals and, when the rays share their shear axes, the shear with one division an axis for all of them;
//! a ray's scalar `PreparedRay` is made only where its lane is redone by the scalar test. Each lane computes the
//! IEEE operations `PreparedRay::new` computes for its ray, so the bits are the same. (Writing the lanes one
//! ray at a time and loading them as vectors stalled every load on stores it cannot forward from: 6-9% slower
//! with 21% fewer instructions; transposed, 5-25% faster on the shared scenes.)
//!
//! Each ray's closest hit (and any-hit answer) is the single-ray kernel's: the box test is the same arithmetic,
//! conservative for each ray, culling uses the same padding, and a tie at the closest `t` goes to the first in
//! spec 11.1's order (the lowest record, or with split references the lowest coordinates), whichever order the
//! packet met the triangles in. Safe on any bytes: indices are bounds-checked and a packet visits
//! at most `node_count` wide nodes.

mod lanes;
mod leaf;
mod node;

use crate::format::{LEAF_BIT, WideNode8};
use crate::ray::hit::TriangleHit;
use crate::ray::intersect::Ray;
use crate::ray::query::Query;
use crate::simd::{Isa, LaneMask, Lanes};
use crate::walk_stack::WalkStack;
use crate::wide::walk::{STACK_LEN, Sections};

pub(crate) use lanes::PACKET_RAYS;
use lanes::{PacketAxes, RayLanes};
use leaf::leaf_in_lanes;
use node::{HitSlots, box_test_lanes};

/// A stack entry: a child reference, the rays that enter it, and each ray's entry distance.
#[derive(Clone, Copy)]
struct Entry {
    child: u32,
    rays: u8,
    t_near: [f32; PACKET_RAYS],
}

/// Traces `rays` (at most [`PACKET_RAYS`]) as one packet; `done(l, found)` receives ray `l`'s result.
#[inline(always)]
pub(crate) fn trace_packet<Q: Query, I: Isa>(
    isa: I,
    sections: &Sections<'_>,
    rays: &[Ray],
    done: &mut impl FnMut(usize, Option<(u32, TriangleHit)>),
) {
    let rays = &rays[..rays.len().min(PACKET_RAYS)];
    let (lanes, mut found, axes) = RayLanes::new(isa, rays, sections.reach_scale);
    let mut root = Entry { child: 0, rays: 0, t_near: [0.0; PACKET_RAYS] };
    if !sections.nodes.is_empty() {
        let t_far = found.t_far(isa, &lanes.reach_offset);
        let root_box = (sections.root.min, sections.root.max);
        let (hit, t_near) = box_test_lanes(isa, root_box, &lanes, t_far);
        root.rays = hit & ((1u32 << rays.len()) - 1) as u8;
        root.t_near = t_near;
    }
    // Rays still looking: all of them for closest hits; for any hit, those without a hit yet.
    let mut pending = root.rays;
    let mut stack = WalkStack::<Entry, STACK_LEN>::new();
    let mut visits_left = sections.nodes.len();
    let mut order = HitSlots::EMPTY;
    let mut next = Some(root);
    while let Some(entry) = next.take() {
        let active = entry.rays & pending;
        if active != 0 {
            if entry.child & LEAF_BIT != 0 {
                let (first, count) = WideNode8::leaf_packets(entry.child);
                let packets = sections.packets.get(first as usize..(first + count) as usize).unwrap_or(&[]);
                let leaf = (first as usize, packets);
                let hit = match &axes {
                    PacketAxes::Shared(shared) => {
                        leaf_in_lanes::<Q, I>(isa, sections, leaf, &lanes, shared, active, rays, &mut found)
                    }
                    PacketAxes::Mixed(mixed) => {
                        leaf_in_lanes::<Q, I>(isa, sections, leaf, &lanes, mixed, active, rays, &mut found)
                    }
                };
                if Q::FIRST_HIT_ENDS {
                    pending &= !hit;
                }
            } else if let Some(node) = sections.nodes.get(entry.child as usize).filter(|_| visits_left > 0) {
                visits_left -= 1;
                let t_far = found.t_far(isa, &lanes.reach_offset);
                order.fill(isa, node, &lanes, (t_far, active));
                let (slots, n) = (&order.slots, order.count);
                let entry = |slot: usize| Entry {
                    child: node.child[slot],
                    rays: order.rays_in[slot],
                    t_near: order.t_near[slot],
                };
                if n > 0 {
                    for &slot in slots[1..n].iter().rev() {
                        stack.push(entry(slot));
                    }
                    next = Some(entry(slots[0]));
                    continue;
                }
            }
        }
        next = pop(isa, &mut stack, found.t_far(isa, &lanes.reach_offset), pending);
    }
    for (l, hit) in found.hit.iter().enumerate().take(rays.len()) {
        done(l, *hit);
    }
}

/// The next entry that still has rays in `pending` whose closest hit's reach (`t_far`) is not before its box.
#[inline(always)]
fn pop<I: Isa>(isa: I, stack: &mut WalkStack<Entry, STACK_LEN>, t_far: I::F8, pending: u8) -> Option<Entry> {
    while let Some(mut entry) = stack.pop() {
        entry.rays &= !(isa.f8(&entry.t_near).gt(t_far).bits() as u8);
        if entry.rays & pending != 0 {
            return Some(entry);
        }
    }
    None
}
