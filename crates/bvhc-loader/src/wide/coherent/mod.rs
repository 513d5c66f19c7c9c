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

use std::mem::MaybeUninit;

use crate::format::{EMPTY_SLOT, LEAF_BIT, TrianglePacket4, WIDE, WideNode8};
use crate::ray::candidates::Unfiltered;
use crate::ray::hit::{TriangleHit, lane_address};
use crate::ray::intersect::{PreparedRay, Ray, shear_axes};
use crate::ray::query::Query;
use crate::ray::reach::{self, BoxRay, cull as reach_cull};
use crate::ray::slab::EXIT_PADDING;
use crate::ray::watertight::{
    EXACT_SIGNS, ILL_CONDITIONED, RelativeTriangle, TINY_EXTENT, barycentrics, conditioning, determinant, distance,
    edge_functions, has_zero_edge, hits, outside, sheared,
};
use crate::simd::{Isa, LaneMask, Lanes};
use crate::wide::packets::closest_in_packet;
use crate::wide::walk::{STACK_LEN, Sections};

/// Rays in one packet.
pub(crate) const PACKET_RAYS: usize = 8;

/// A stack entry: a child reference, the rays that enter it, and each ray's entry distance.
#[derive(Clone, Copy)]
struct Entry {
    child: u32,
    rays: u8,
    t_near: [f32; PACKET_RAYS],
}

/// The per-lane ray data of a packet, structure of arrays.
struct RayLanes {
    origin: [[f32; PACKET_RAYS]; 3],
    inverse_direction: [[f32; PACKET_RAYS]; 3],
    exit_inverse: [[f32; PACKET_RAYS]; 3],
    /// Per axis and lane: -1 where the ray's direction has its sign bit set (it enters through `max`), else 1.
    sign: [[f32; PACKET_RAYS]; 3],
    t_min: [f32; PACKET_RAYS],
    /// Per lane: the reach's `2^-11 D` (`crate::ray::reach`), as the single-ray walk computes it.
    reach_offset: [f32; PACKET_RAYS],
    /// Woop et al.'s shear per lane, and whether every ray of the packet has the same axes `[kx, ky, kz]`
    /// (those of the first ray), so that a triangle can be tested against all of them in lanes.
    shear: [[f32; PACKET_RAYS]; 3],
    shared_axes: Option<[usize; 3]>,
}

/// Each ray's search: its closest hit so far (any hit, for any-hit packets) and the distance limit.
struct Found {
    t_max: [f32; PACKET_RAYS],
    hit: [Option<(u32, TriangleHit)>; PACKET_RAYS],
}

impl Found {
    /// Whether a hit of ray `l` at `t` (within its `t_max`) in the lane at `address` of `sections` precedes its
    /// closest hit so far (spec 11.1's tie order, [`Sections::tie_key`]).
    #[inline(always)]
    fn taken_by(&self, sections: &Sections<'_>, l: usize, t: f32, address: u32) -> bool {
        match self.hit[l] {
            None => true,
            Some((best, _)) => t < self.t_max[l] || (t == self.t_max[l] && sections.first_at_tie(address, best)),
        }
    }

    /// Each ray's cull distance, the reach of its `t_max` (`crate::ray::reach`), as the single-ray walk culls.
    #[inline(always)]
    fn t_far(&self, reach_offset: &[f32; PACKET_RAYS]) -> [f32; PACKET_RAYS] {
        std::array::from_fn(|l| reach_cull(self.t_max[l], reach_offset[l]))
    }

    /// Ray `l`'s new closest hit.
    #[inline(always)]
    fn take(&mut self, l: usize, address: u32, hit: TriangleHit) {
        self.t_max[l] = hit.t;
        self.hit[l] = Some((address, hit));
    }
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
    let mut found = Found { t_max: [0.0; PACKET_RAYS], hit: [None; PACKET_RAYS] };
    let mut root = Entry { child: 0, rays: 0, t_near: [0.0; PACKET_RAYS] };
    let mut lanes = RayLanes {
        origin: [[0.0; PACKET_RAYS]; 3],
        inverse_direction: [[0.0; PACKET_RAYS]; 3],
        exit_inverse: [[0.0; PACKET_RAYS]; 3],
        sign: [[1.0; PACKET_RAYS]; 3],
        t_min: [0.0; PACKET_RAYS],
        reach_offset: [0.0; PACKET_RAYS],
        shear: [[0.0; PACKET_RAYS]; 3],
        shared_axes: rays.first().map(|ray| shear_axes(ray.direction)),
    };
    // The rays' set-up in lanes: the eight records transposed into fields, then the reciprocals and the shear
    // of all eight with one division an axis, each lane the IEEE operation `PreparedRay::new` does for its ray
    // (so the same bits). Lanes without a ray get a unit direction and `t_max` 0, and are never in a mask.
    let mut records = [[0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0]; PACKET_RAYS];
    for (record, ray) in records.iter_mut().zip(rays) {
        *record = bytemuck::must_cast(*ray);
        if lanes.shared_axes != Some(shear_axes(ray.direction)) {
            lanes.shared_axes = None;
        }
    }
    let fields = isa.transpose8(&records);
    let [o0, o1, o2, d0, d1, d2, t_min, t_max] = fields;
    lanes.origin = [o0, o1, o2];
    lanes.t_min = t_min;
    found.t_max = t_max;
    let direction = [d0, d1, d2];
    let one = isa.f8_splat(1.0);
    for (axis, lanes_d) in direction.iter().enumerate() {
        let d = isa.f8(lanes_d);
        let inverse = one.div(d);
        lanes.inverse_direction[axis] = inverse.to_array();
        lanes.exit_inverse[axis] = inverse.mul(isa.f8_splat(EXIT_PADDING)).to_array();
        lanes.sign[axis] = I::F8::select(d.is_sign_negative(), isa.f8_splat(-1.0), one).to_array();
    }
    // Rays whose shear axes differ test leaves one by one, with their scalar set-up.
    let mut prepared: [Option<PreparedRay>; PACKET_RAYS] = [None; PACKET_RAYS];
    match lanes.shared_axes {
        Some([kx, ky, kz]) => {
            let dz = isa.f8(&direction[kz]);
            lanes.shear = [
                isa.f8(&direction[kx]).div(dz).to_array(),
                isa.f8(&direction[ky]).div(dz).to_array(),
                one.div(dz).to_array(),
            ];
        }
        None => {
            // A plain loop: a closure of `array::from_fn` would be compiled apart from the instruction set's
            // function and called once a ray.
            for (slot, ray) in prepared.iter_mut().zip(rays) {
                *slot = Some(PreparedRay::new(ray));
            }
        }
    }
    // Each ray's reach over the tree, in lanes: the single-ray walk's.
    let inverse = [0, 1, 2].map(|a| isa.f8(&lanes.inverse_direction[a]));
    lanes.reach_offset = reach::offset(inverse, isa.f8_splat(sections.reach_scale)).to_array();
    if !sections.nodes.is_empty() {
        let t_far = found.t_far(&lanes.reach_offset);
        let root_box = (sections.root.min, sections.root.max);
        let (hit, t_near) = box_test_lanes(isa, root_box, &lanes, &t_far);
        root.rays = hit & ((1u32 << rays.len()) - 1) as u8;
        root.t_near = t_near;
    }
    // Rays still looking: all of them for closest hits; for any hit, those without a hit yet.
    let mut pending = root.rays;
    let mut stack = [const { MaybeUninit::<Entry>::uninit() }; STACK_LEN];
    let mut stack_len = 0usize;
    let mut visits_left = sections.nodes.len();
    let mut next = Some(root);
    while let Some(entry) = next.take() {
        let active = entry.rays & pending;
        if active != 0 {
            if entry.child & LEAF_BIT != 0 {
                let (first, count) = WideNode8::leaf_packets(entry.child);
                let packets = sections.packets.get(first as usize..(first + count) as usize).unwrap_or(&[]);
                let leaf = (first as usize, packets);
                let hit = match lanes.shared_axes {
                    Some(axes) => leaf_in_lanes::<Q, I>(isa, sections, leaf, &lanes, axes, active, rays, &mut found),
                    None => leaf_ray_by_ray::<Q, I>(isa, sections, leaf, active, &prepared, &mut found),
                };
                if Q::FIRST_HIT_ENDS {
                    pending &= !hit;
                }
            } else if let Some(node) = sections.nodes.get(entry.child as usize).filter(|_| visits_left > 0) {
                visits_left -= 1;
                let t_far = found.t_far(&lanes.reach_offset);
                let leader = active.trailing_zeros() as usize & (PACKET_RAYS - 1);
                // The hit slots, nearest first for the leader (the first active ray), ties in slot order.
                let mut order = [Entry { child: 0, rays: 0, t_near: [0.0; PACKET_RAYS] }; WIDE];
                let mut n = 0;
                for slot in 0..WIDE {
                    let child = node.child[slot];
                    if child == EMPTY_SLOT {
                        break;
                    }
                    let (hit, t_near) = slot_test(isa, node, slot, &lanes, &t_far);
                    let hit = hit & active;
                    if hit == 0 {
                        continue;
                    }
                    let entry = Entry { child, rays: hit, t_near };
                    let key = |e: &Entry| if e.rays & (1 << leader) != 0 { e.t_near[leader] } else { f32::INFINITY };
                    let mut at = n;
                    while at > 0 && key(&order[at - 1]) > key(&entry) {
                        order[at] = order[at - 1];
                        at -= 1;
                    }
                    order[at] = entry;
                    n += 1;
                }
                if n > 0 {
                    for entry in order[1..n].iter().rev() {
                        if let Some(slot) = stack.get_mut(stack_len) {
                            slot.write(*entry);
                            stack_len += 1;
                        }
                    }
                    next = Some(order[0]);
                    continue;
                }
            }
        }
        next = pop(&mut stack, &mut stack_len, &found.t_far(&lanes.reach_offset), pending);
    }
    for (l, hit) in found.hit.iter().enumerate().take(rays.len()) {
        done(l, *hit);
    }
}

/// The next entry that still has rays in `pending` whose closest hit's reach (`t_far`) is not before its box.
#[inline(always)]
#[allow(unsafe_code)] // reading the stack, see the SAFETY note
fn pop(
    stack: &mut [MaybeUninit<Entry>; STACK_LEN],
    stack_len: &mut usize,
    t_far: &[f32; PACKET_RAYS],
    pending: u8,
) -> Option<Entry> {
    while *stack_len > 0 {
        *stack_len -= 1;
        // SAFETY: entries below `stack_len` were written by the push in `trace_packet` before `stack_len` passed
        // them, and `stack_len` only moves down by one here, so this entry is initialized.
        let mut entry = unsafe { stack[*stack_len].assume_init() };
        for (l, (&t_near, &cull)) in entry.t_near.iter().zip(t_far).enumerate() {
            if t_near > cull {
                entry.rays &= !(1 << l);
            }
        }
        if entry.rays & pending != 0 {
            return Some(entry);
        }
    }
    None
}

/// Slot `slot` of `node` against every lane: [`box_test_lanes`] of its box.
#[inline(always)]
fn slot_test<I: Isa>(
    isa: I,
    node: &WideNode8,
    slot: usize,
    lanes: &RayLanes,
    t_far: &[f32; PACKET_RAYS],
) -> (u8, [f32; PACKET_RAYS]) {
    let (min, max) = ([0, 1, 2].map(|a| node.min[a][slot]), [0, 1, 2].map(|a| node.max[a][slot]));
    box_test_lanes(isa, (min, max), lanes, t_far)
}

/// The box `(min, max)` against every lane: (bit mask of the lanes whose ray enters the box within
/// `[t_min, t_far]`, entry distances). The single-ray slab test per lane (`PreparedRay::enter_box`).
#[inline(always)]
fn box_test_lanes<I: Isa>(
    isa: I,
    (min, max): ([f32; 3], [f32; 3]),
    lanes: &RayLanes,
    t_far: &[f32; PACKET_RAYS],
) -> (u8, [f32; PACKET_RAYS]) {
    let mut near = isa.f8(&lanes.t_min);
    let mut far = isa.f8(t_far);
    for axis in 0..3 {
        let (low, high) = (isa.f8_splat(min[axis]), isa.f8_splat(max[axis]));
        let negative = isa.f8(&lanes.sign[axis]).is_sign_negative();
        let entry = I::F8::select(negative, high, low);
        let exit = I::F8::select(negative, low, high);
        let origin = isa.f8(&lanes.origin[axis]);
        let t_entry = entry.sub(origin).mul(isa.f8(&lanes.inverse_direction[axis]));
        let t_exit = exit.sub(origin).mul(isa.f8(&lanes.exit_inverse[axis]));
        near = t_entry.max_or(near);
        far = t_exit.min_or(far);
    }
    (near.le(far).bits() as u8, near.to_array())
}

/// The triangles of `packets`, one after the other, against the `active` rays in lanes, when every ray has the
/// shear axes `axes`: per (ray, triangle) the scalar watertight test's operations in its order, a lane with an
/// edge function exactly 0 or an ill-conditioned hit redone by the scalar test, and a hit taken when it precedes
/// the ray's closest so far (a smaller `t`, or the same and a lower record), so each ray ends with what the
/// single-ray packet test gives (a redo prepares its ray, `rays[l]`, then). Returns the rays that took a hit.
#[inline(always)]
#[allow(clippy::too_many_arguments)] // the packet's state, passed apart so that it stays in registers
fn leaf_in_lanes<Q: Query, I: Isa>(
    isa: I,
    sections: &Sections<'_>,
    (first, packets): (usize, &[TrianglePacket4]),
    lanes: &RayLanes,
    [kx, ky, kz]: [usize; 3],
    mut active: u8,
    rays: &[Ray],
    found: &mut Found,
) -> u8 {
    let mut hit_rays = 0u8;
    let origin = [isa.f8(&lanes.origin[kx]), isa.f8(&lanes.origin[ky]), isa.f8(&lanes.origin[kz])];
    let (sx, sy, sz) = (isa.f8(&lanes.shear[0]), isa.f8(&lanes.shear[1]), isa.f8(&lanes.shear[2]));
    let (t_min, zero, one) = (isa.f8(&lanes.t_min), isa.f8_splat(0.0), isa.f8_splat(1.0));
    // Each ray's `t_max` kept in lanes and narrowed in lanes as hits are taken, not reloaded from `found` for
    // each triangle: a vector load of what the hits just stored lane by lane cannot be forwarded from the
    // stores and waits for them.
    let mut t_max = isa.f8(&found.t_max);
    for (p, packet) in packets.iter().enumerate() {
        for tri in 0..packet.used_lanes() {
            let r = RelativeTriangle {
                a: relative_vertex(isa, &packet.vertices[0], tri, [kx, ky, kz], &origin),
                b: relative_vertex(isa, &packet.vertices[1], tri, [kx, ky, kz], &origin),
                c: relative_vertex(isa, &packet.vertices[2], tri, [kx, ky, kz], &origin),
            };
            let projected = sheared(&r, sx, sy);
            let e = edge_functions(projected);
            let det = determinant(e);
            let t = distance(e, &r, sz, det);
            let outside = outside(e, zero);
            let valid = hits(outside, det, t, zero, t_min, t_max);
            let inside = det.is_number().and_not(outside);
            let mut redo_rays = has_zero_edge(e, zero).bits() as u8 & active;
            let mut exact_signs = 0u8;
            if inside.bits() as u8 & active != 0 {
                // Ill-conditioned hits get their exact values from the scalar test.
                let thresholds = (isa.f8_splat(ILL_CONDITIONED), isa.f8_splat(TINY_EXTENT), isa.f8_splat(EXACT_SIGNS));
                let (ill, exact) = conditioning(e, projected, &r, det, thresholds);
                redo_rays |= ill.and(inside).bits() as u8 & active;
                exact_signs = exact.bits() as u8;
            }
            let valid_rays = valid.bits() as u8 & active & !redo_rays;
            let address = lane_address(first + p, tri);
            let mut refused = false;
            if valid_rays != 0 {
                let (u, v) = barycentrics(e, det, one);
                let (t_lanes, u, v) = (t.to_array(), u.to_array(), v.to_array());
                let mut rays = valid_rays;
                while rays != 0 {
                    let l = rays.trailing_zeros() as usize & (PACKET_RAYS - 1);
                    rays &= rays - 1;
                    // A hit counts where it meets the box condition, which a lane with its edge functions' exact
                    // signs does (rare not to: the lanes are then reloaded).
                    let sure = exact_signs & (1 << l) != 0 && t_lanes[l] < f32::INFINITY;
                    let ray = (lanes.t_min[l], kz, lanes.shear[2][l]);
                    if !sure && !lanes.box_ray(l).meets_record_box(&packet.triangle(tri), t_lanes[l], ray) {
                        refused = true;
                        continue;
                    }
                    if Q::FIRST_HIT_ENDS || found.taken_by(sections, l, t_lanes[l], address) {
                        found.take(l, address, TriangleHit { t: t_lanes[l], u: u[l], v: v[l] });
                        hit_rays |= 1 << l;
                    }
                }
                // A taken hit sets its ray's `t_max` to its `t`; a valid one not taken is a tie lost at that very
                // `t`. So the lanes' minimum with the valid `t`s is what `found` now holds in every active lane
                // that no redo touches (the other lanes' tests are masked off), unless a lane was refused.
                if !refused {
                    t_max = t_max.min_or(I::F8::select(valid, t, isa.f8_splat(f32::INFINITY)));
                }
            }
            let mut redo = redo_rays;
            while redo != 0 {
                let l = redo.trailing_zeros() as usize & (PACKET_RAYS - 1);
                redo &= redo - 1;
                let Some(ray) = rays.get(l).map(PreparedRay::new) else { continue };
                if let Some(hit) = ray.intersect_triangle(&packet.triangle(tri), found.t_max[l])
                    && (Q::FIRST_HIT_ENDS || found.taken_by(sections, l, hit.t, address))
                {
                    found.take(l, address, hit);
                    hit_rays |= 1 << l;
                }
            }
            if redo_rays != 0 || refused {
                t_max = isa.f8(&found.t_max);
            }
        }
        if Q::FIRST_HIT_ENDS {
            active &= !hit_rays;
            if active == 0 {
                break;
            }
        }
    }
    hit_rays
}

impl RayLanes {
    /// Lane `l`'s ray as the box tests read it (the bits `PreparedRay::new` computes for that ray).
    #[inline(always)]
    fn box_ray(&self, l: usize) -> BoxRay {
        BoxRay {
            origin: [0, 1, 2].map(|a| self.origin[a][l]),
            inverse: [0, 1, 2].map(|a| self.inverse_direction[a][l]),
            exit_inverse: [0, 1, 2].map(|a| self.exit_inverse[a][l]),
            negative: [0, 1, 2].map(|a| self.sign[a][l] < 0.0),
        }
    }
}

/// Vertex `vertex` of the packet's triangle in lane `tri` minus each ray's origin (`origin`, in the permuted
/// axes), in the rays' permuted axes `[kx, ky, kz]`.
#[inline(always)]
fn relative_vertex<I: Isa>(
    isa: I,
    vertex: &[[f32; 4]; 3],
    tri: usize,
    [kx, ky, kz]: [usize; 3],
    origin: &[I::F8; 3],
) -> [I::F8; 3] {
    [
        isa.f8_splat(vertex[kx][tri]).sub(origin[0]),
        isa.f8_splat(vertex[ky][tri]).sub(origin[1]),
        isa.f8_splat(vertex[kz][tri]).sub(origin[2]),
    ]
}

/// The leaf's packets for each `active` ray in turn, with the single-ray packet test (rays whose shear axes
/// differ cannot share lanes). Returns the rays that were hit.
#[inline(always)]
fn leaf_ray_by_ray<Q: Query, I: Isa>(
    isa: I,
    sections: &Sections<'_>,
    (first, packets): (usize, &[TrianglePacket4]),
    active: u8,
    prepared: &[Option<PreparedRay>; PACKET_RAYS],
    found: &mut Found,
) -> u8 {
    let mut hit_rays = 0u8;
    for l in (0..PACKET_RAYS).filter(|l| active & (1 << l) != 0) {
        let Some(ray) = &prepared[l] else { continue };
        for (p, packet) in packets.iter().enumerate() {
            if let Some((lane, hit)) =
                closest_in_packet::<Q, I, _>(isa, packet, ray, found.t_max[l], &Unfiltered, sections.tie)
            {
                let address = lane_address(first + p, lane);
                if Q::FIRST_HIT_ENDS || found.taken_by(sections, l, hit.t, address) {
                    found.take(l, address, hit);
                    hit_rays |= 1 << l;
                }
                if Q::FIRST_HIT_ENDS {
                    break;
                }
            }
        }
    }
    hit_rays
}
