//! A coherent packet's rays in lanes: their set-up ([`RayLanes::new`]), each ray's search so far ([`Found`]),
//! and the shear axes of Woop, Benthin, Wald 2013 per lane ([`LaneAxes`]): one set for the whole packet when
//! every ray has the same ([`SharedAxes`]), or chosen lane by lane with selects ([`MixedAxes`]), so that a leaf
//! tests each triangle against all the packet's rays in lanes either way.
//!
//! Every lane computes the IEEE operations `PreparedRay::new` computes for its ray, in its order, so the bits are
//! the same: the reciprocals, the padded exit reciprocals, the shear `d[kx] / d[kz]`, `d[ky] / d[kz]`,
//! `1 / d[kz]` and the reach offset.

use crate::ray::hit::TriangleHit;
use crate::ray::intersect::{Ray, shear_axes};
use crate::ray::reach::{self, BoxRay};
use crate::ray::slab::EXIT_PADDING;
use crate::simd::{Isa, LaneMask, Lanes};
use crate::wide::walk::Sections;

/// Rays in one packet.
pub(crate) const PACKET_RAYS: usize = 8;

/// The per-lane ray data of a packet, structure of arrays.
pub(super) struct RayLanes {
    pub origin: [[f32; PACKET_RAYS]; 3],
    pub inverse_direction: [[f32; PACKET_RAYS]; 3],
    pub exit_inverse: [[f32; PACKET_RAYS]; 3],
    /// Per axis and lane: -1 where the ray's direction has its sign bit set (it enters through `max`), else 1.
    pub sign: [[f32; PACKET_RAYS]; 3],
    pub t_min: [f32; PACKET_RAYS],
    /// Per lane: the reach's `2^-11 D` (`crate::ray::reach`), as the single-ray walk computes it.
    pub reach_offset: [f32; PACKET_RAYS],
    /// Woop et al.'s shear per lane: `[sx, sy, sz]`.
    pub shear: [[f32; PACKET_RAYS]; 3],
}

/// Each ray's search: its closest hit so far (any hit, for any-hit packets) and the distance limit.
pub(super) struct Found {
    pub t_max: [f32; PACKET_RAYS],
    pub hit: [Option<(u32, TriangleHit)>; PACKET_RAYS],
}

/// The packet's shear axes, in one of two forms.
pub(super) enum PacketAxes<I: Isa> {
    /// Every ray has these.
    Shared(SharedAxes),
    /// They differ between rays: chosen lane by lane.
    Mixed(MixedAxes<I>),
}

impl RayLanes {
    /// The set-up of `rays` (at most [`PACKET_RAYS`]) over a tree of reach scale `reach_scale`: the rays' lanes,
    /// their searches (each `t_max` the ray's) and their shear axes. Lanes without a ray get a unit direction
    /// and `t_max` 0; callers keep them out of every mask.
    #[inline(always)]
    pub fn new<I: Isa>(isa: I, rays: &[Ray], reach_scale: f32) -> (RayLanes, Found, PacketAxes<I>) {
        // A full packet is transposed straight from the caller's rays: filling a local copy first cost a store a
        // field (5% of a camera pass in the profile).
        let fields = match <&[Ray; PACKET_RAYS]>::try_from(rays) {
            Ok(full) => isa.transpose8(bytemuck::must_cast_ref(full)),
            Err(_) => {
                let mut records = [[0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 0.0, 0.0]; PACKET_RAYS];
                for (record, ray) in records.iter_mut().zip(rays) {
                    *record = bytemuck::must_cast(*ray);
                }
                isa.transpose8(&records)
            }
        };
        let [o0, o1, o2, d0, d1, d2, t_min, t_max] = fields;
        // No closures over lanes here (`array::map`): a closure is compiled apart from the instruction set's
        // function, its intrinsics called one by one.
        let direction = [isa.f8(&d0), isa.f8(&d1), isa.f8(&d2)];
        let one = isa.f8_splat(1.0);
        let inverse = [one.div(direction[0]), one.div(direction[1]), one.div(direction[2])];
        let padding = isa.f8_splat(EXIT_PADDING);
        let sign = |d: I::F8| I::F8::select(d.is_sign_negative(), isa.f8_splat(-1.0), one).to_array();
        let mixed = MixedAxes::of(isa, direction);
        let axes = match mixed.uniform(rays.len()) {
            true => PacketAxes::Shared(SharedAxes(rays.first().map_or([0, 1, 2], |ray| shear_axes(ray.direction)))),
            false => PacketAxes::Mixed(mixed),
        };
        let [dx, dy, dz] = match &axes {
            PacketAxes::Shared(shared) => LaneAxes::<I>::pick(shared, direction),
            PacketAxes::Mixed(mixed) => mixed.pick(direction),
        };
        let lanes = RayLanes {
            origin: [o0, o1, o2],
            inverse_direction: [inverse[0].to_array(), inverse[1].to_array(), inverse[2].to_array()],
            exit_inverse: [
                inverse[0].mul(padding).to_array(),
                inverse[1].mul(padding).to_array(),
                inverse[2].mul(padding).to_array(),
            ],
            sign: [sign(direction[0]), sign(direction[1]), sign(direction[2])],
            t_min,
            reach_offset: reach::offset(inverse, isa.f8_splat(reach_scale)).to_array(),
            shear: [dx.div(dz).to_array(), dy.div(dz).to_array(), one.div(dz).to_array()],
        };
        (lanes, Found { t_max, hit: [None; PACKET_RAYS] }, axes)
    }

    /// Lane `l`'s ray as the box tests read it (the bits `PreparedRay::new` computes for that ray).
    #[inline(always)]
    pub fn box_ray(&self, l: usize) -> BoxRay {
        BoxRay {
            origin: [0, 1, 2].map(|a| self.origin[a][l]),
            inverse: [0, 1, 2].map(|a| self.inverse_direction[a][l]),
            exit_inverse: [0, 1, 2].map(|a| self.exit_inverse[a][l]),
            negative: [0, 1, 2].map(|a| self.sign[a][l] < 0.0),
        }
    }
}

impl Found {
    /// Whether a hit of ray `l` at `t` (within its `t_max`) in the lane at `address` of `sections` precedes its
    /// closest hit so far (spec 11.1's tie order, [`Sections::tie_key`]).
    #[inline(always)]
    pub fn taken_by(&self, sections: &Sections<'_>, l: usize, t: f32, address: u32) -> bool {
        match self.hit[l] {
            None => true,
            Some((best, _)) => t < self.t_max[l] || (t == self.t_max[l] && sections.first_at_tie(address, best)),
        }
    }

    /// Each ray's cull distance, the reach of its `t_max` (`crate::ray::reach`), as the single-ray walk culls,
    /// computed in lanes (eight scalar results stored and loaded as a vector could not be forwarded).
    #[inline(always)]
    pub fn t_far<I: Isa>(&self, isa: I, reach_offset: &[f32; PACKET_RAYS]) -> I::F8 {
        reach::cull_lanes(isa.f8(&self.t_max), isa.f8(reach_offset), isa.f8_splat(reach::CULL_FACTOR))
    }

    /// Ray `l`'s new closest hit.
    #[inline(always)]
    pub fn take(&mut self, l: usize, address: u32, hit: TriangleHit) {
        self.t_max[l] = hit.t;
        self.hit[l] = Some((address, hit));
    }
}

/// How a packet's lanes permute the three axes into their rays' `[kx, ky, kz]`.
pub(super) trait LaneAxes<I: Isa> {
    /// `[v[kx], v[ky], v[kz]]` of each lane's ray, from `v` by axis.
    fn pick(&self, v: [I::F8; 3]) -> [I::F8; 3];
    /// Lane `l`'s `kz` (its ray is `ray`).
    fn kz(&self, ray: &Ray) -> usize;
}

/// Axes every ray of the packet shares.
#[derive(Clone, Copy)]
pub(super) struct SharedAxes(pub [usize; 3]);

impl<I: Isa> LaneAxes<I> for SharedAxes {
    #[inline(always)]
    fn pick(&self, v: [I::F8; 3]) -> [I::F8; 3] {
        let [kx, ky, kz] = self.0;
        [v[kx], v[ky], v[kz]]
    }

    #[inline(always)]
    fn kz(&self, _: &Ray) -> usize {
        self.0[2]
    }
}

/// Axes chosen lane by lane: for each of `kx`, `ky`, `kz` the lanes where it is axis 0 and where it is axis 1
/// (elsewhere axis 2).
#[derive(Clone, Copy)]
pub(super) struct MixedAxes<I: Isa> {
    picks: [(Mask8<I>, Mask8<I>); 3],
}

/// A mask of eight lanes of the instruction set `I`.
type Mask8<I> = <<I as Isa>::F8 as Lanes>::Mask;

impl<I: Isa> MixedAxes<I> {
    /// [`shear_axes`] of each lane's direction (`direction` by axis), with its comparisons in lanes: `kz` the
    /// axis of the largest magnitude (the first of equal ones), `kx`, `ky` the next two in cyclic order, swapped
    /// where the direction along `kz` is negative.
    #[inline(always)]
    fn of(isa: I, direction: [I::F8; 3]) -> MixedAxes<I> {
        let [x, y, z] = [direction[0].abs(), direction[1].abs(), direction[2].abs()];
        let z0 = x.ge(y).and(x.ge(z));
        let z1 = y.ge(z).and_not(z0);
        let every = isa.f8_splat(0.0).le(isa.f8_splat(0.0));
        let z2 = every.and_not(z0).and_not(z1);
        let along = I::F8::select(z0, direction[0], I::F8::select(z1, direction[1], direction[2]));
        let negative = along.lt(isa.f8_splat(0.0));
        let positive = every.and_not(negative);
        // kx = kz + 1 (mod 3) and ky = kz + 2, swapped where negative.
        let kx0 = positive.and(z2).or(negative.and(z1));
        let kx1 = positive.and(z0).or(negative.and(z2));
        let ky0 = positive.and(z1).or(negative.and(z2));
        let ky1 = positive.and(z2).or(negative.and(z0));
        MixedAxes { picks: [(kx0, kx1), (ky0, ky1), (z0, z1)] }
    }

    /// Whether the first `count` lanes all have the same axes. (Comparing each ray's `shear_axes` with the
    /// first's stalled every packet: the three stores could not be forwarded to the wide load that compared
    /// them, 16% of a camera pass.)
    #[inline(always)]
    fn uniform(&self, count: usize) -> bool {
        let all = (1u32 << count.min(PACKET_RAYS)) - 1;
        let mut uniform = true;
        for (axis0, axis1) in self.picks {
            for bits in [axis0.bits() & all, axis1.bits() & all] {
                uniform &= bits == 0 || bits == all;
            }
        }
        uniform
    }
}

impl<I: Isa> LaneAxes<I> for MixedAxes<I> {
    #[inline(always)]
    fn pick(&self, v: [I::F8; 3]) -> [I::F8; 3] {
        let [(x0, x1), (y0, y1), (z0, z1)] = self.picks;
        [
            I::F8::select(x0, v[0], I::F8::select(x1, v[1], v[2])),
            I::F8::select(y0, v[0], I::F8::select(y1, v[1], v[2])),
            I::F8::select(z0, v[0], I::F8::select(z1, v[1], v[2])),
        ]
    }

    #[inline(always)]
    fn kz(&self, ray: &Ray) -> usize {
        shear_axes(ray.direction)[2]
    }
}
