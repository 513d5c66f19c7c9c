//! A wide node's visit by a coherent packet: each occupied slot's box tested against every active ray in lanes
//! (the single-ray slab test per lane), and the hit slots ordered for the walk. (A frustum test of all eight
//! slots first, as Embree's coherent packets do, was measured and declined: `docs/kernel-peer.md`.)

use crate::format::{EMPTY_SLOT, WIDE, WideNode8};
use crate::simd::{Isa, LaneMask, Lanes};
use crate::wide::coherent::lanes::{PACKET_RAYS, RayLanes};

/// A node's hit slots (filled in place by [`HitSlots::fill`], for each node in turn), nearest first for the leader (the first active ray), ties in slot order: the slots'
/// indices sorted by the leader's entry distance, each slot's lanes kept where its test wrote them (sorting
/// 40-byte entries cost 5% of a camera pass).
pub(super) struct HitSlots {
    /// Per slot: each lane's entry distance, and the lanes that enter it.
    pub t_near: [[f32; PACKET_RAYS]; WIDE],
    pub rays_in: [u8; WIDE],
    /// The hit slots in order, `count` of them.
    pub slots: [usize; WIDE],
    pub count: usize,
}

impl HitSlots {
    /// No slots yet.
    pub const EMPTY: HitSlots =
        HitSlots { t_near: [[0.0; PACKET_RAYS]; WIDE], rays_in: [0; WIDE], slots: [0; WIDE], count: 0 };

    /// The slots of `node` (up to the first empty slot) that the `active` rays enter within their cull distances
    /// `t_far`.
    #[inline(always)]
    pub fn fill<I: Isa>(&mut self, isa: I, node: &WideNode8, lanes: &RayLanes, (t_far, active): (I::F8, u8)) {
        let leader = active.trailing_zeros() as usize & (PACKET_RAYS - 1);
        self.count = 0;
        let mut keys = [0.0f32; WIDE];
        for slot in 0..WIDE {
            if node.child[slot] == EMPTY_SLOT {
                break;
            }
            let (hit, near) = slot_test(isa, node, slot, lanes, t_far);
            self.insert(&mut keys, slot, (hit & active, near), leader);
        }
    }

    /// Slot `slot` with the lanes `hit` entering it at `near`, in order by the leader's distance (`keys`).
    #[inline(always)]
    fn insert(&mut self, keys: &mut [f32; WIDE], slot: usize, (hit, near): (u8, [f32; PACKET_RAYS]), leader: usize) {
        if hit == 0 {
            return;
        }
        (self.t_near[slot], self.rays_in[slot]) = (near, hit);
        let key = if hit & (1 << leader) != 0 { near[leader] } else { f32::INFINITY };
        let mut at = self.count;
        while at > 0 && keys[at - 1] > key {
            (keys[at], self.slots[at]) = (keys[at - 1], self.slots[at - 1]);
            at -= 1;
        }
        (keys[at], self.slots[at]) = (key, slot);
        self.count += 1;
    }
}

/// Slot `slot` of `node` against every lane: [`box_test_lanes`] of its box.
#[inline(always)]
fn slot_test<I: Isa>(
    isa: I,
    node: &WideNode8,
    slot: usize,
    lanes: &RayLanes,
    t_far: I::F8,
) -> (u8, [f32; PACKET_RAYS]) {
    let (min, max) = ([0, 1, 2].map(|a| node.min[a][slot]), [0, 1, 2].map(|a| node.max[a][slot]));
    box_test_lanes(isa, (min, max), lanes, t_far)
}

/// The box `(min, max)` against every lane: (bit mask of the lanes whose ray enters the box within
/// `[t_min, t_far]`, entry distances). The single-ray slab test per lane (`PreparedRay::enter_box`).
#[inline(always)]
pub(super) fn box_test_lanes<I: Isa>(
    isa: I,
    (min, max): ([f32; 3], [f32; 3]),
    lanes: &RayLanes,
    t_far: I::F8,
) -> (u8, [f32; PACKET_RAYS]) {
    let mut near = isa.f8(&lanes.t_min);
    let mut far = t_far;
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
