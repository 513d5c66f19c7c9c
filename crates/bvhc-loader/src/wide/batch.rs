//! The batch calls' kernels over wide sections: the stream call's rays grouped into packets where 8 consecutive
//! rays go well together ([`goes_as_packet`]), the others one by one or interleaved ([`Stream`]); and the
//! coherent call's packets of every 8 consecutive rays ([`Packets`]). Every ray gets its single-ray hit (ties as
//! spec 11.1 says; with split references possibly another record of the same triangle).

use std::marker::PhantomData;

use crate::ray::candidates::Unfiltered;
use crate::ray::hit::TriangleHit;
use crate::ray::intersect::Ray;
use crate::ray::query::Query;
use crate::simd::{Isa, Kernel};
use crate::wide::coherent::{PACKET_RAYS, trace_packet};
use crate::wide::walk::{PacketHit, PacketLeaves, Sections, SingleRay, Walk, new_stack};

/// Rays a stream keeps in flight, their steps interleaved.
const STREAM_WIDTH: usize = 8;

/// Whether the rays all start at the same point, bit for bit.
#[inline]
fn shares_origin(rays: &[Ray]) -> bool {
    let bits = |ray: &Ray| ray.origin.map(f32::to_bits);
    rays.split_first().is_some_and(|(first, rest)| rest.iter().all(|ray| bits(ray) == bits(first)))
}

/// Fraction of the scene's largest extent within which a group's origins count as nearby
/// ([`goes_as_packet`]).
const NEARBY_FRACTION: f32 = 1.0 / 16.0;

/// Whether a stream traces `rays` (a group of [`PACKET_RAYS`]) as a packet: they share their origin bit for bit,
/// or their directions lie in one octant (the same sign bits) and their origins within `nearby` of each other
/// on every axis (shadow rays from neighbouring pixels' hits toward a light, an orthographic camera's rays).
/// Such rays walk mostly the same nodes; rays from everywhere (an incoherent batch: 8 in one octant by chance
/// about once in 2 million groups) would walk apart, and go one by one. Only speed depends on this: a packet
/// gives each ray its single-ray hit.
#[inline]
fn goes_as_packet(rays: &[Ray], nearby: f32) -> bool {
    if shares_origin(rays) {
        return true;
    }
    let Some((first, rest)) = rays.split_first() else {
        return false;
    };
    let octant = |ray: &Ray| ray.direction.map(|d| d.is_sign_negative());
    let (mut low, mut high) = (first.origin, first.origin);
    for ray in rest {
        if octant(ray) != octant(first) {
            return false;
        }
        for a in 0..3 {
            low[a] = low[a].min(ray.origin[a]);
            high[a] = high[a].max(ray.origin[a]);
        }
    }
    // NaN origins (unchecked rays) fail the test and go one by one.
    (0..3).all(|a| high[a] - low[a] <= nearby)
}

/// The stream call's rays: groups of [`PACKET_RAYS`] that go well together ([`goes_as_packet`]) as packets, the
/// others apart.
pub(crate) struct Batch<'s, 'r, D, Q: Query> {
    pub(crate) sections: &'s Sections<'s>,
    pub(crate) rays: &'r [Ray],
    pub(crate) done: &'r mut D,
    pub(crate) interleave: bool,
    pub(crate) query: PhantomData<Q>,
}

impl<D: FnMut(usize, Option<(u32, TriangleHit)>), Q: Query> Kernel for Batch<'_, '_, D, Q> {
    type Output = ();

    #[inline(always)]
    fn run<I: Isa>(self, isa: I) {
        let Batch { sections, rays, done, interleave, .. } = self;
        let nearby = sections.root.largest_extent() * NEARBY_FRACTION;
        let mut start = 0;
        for (g, group) in rays.chunks_exact(PACKET_RAYS).enumerate() {
            if !goes_as_packet(group, nearby) {
                continue;
            }
            let at = g * PACKET_RAYS;
            trace_apart::<Q, I>(isa, sections, (&rays[start..at], start), interleave, done);
            trace_packet::<Q, I>(isa, sections, group, &mut |l, found| done(at + l, found));
            start = at + PACKET_RAYS;
        }
        trace_apart::<Q, I>(isa, sections, (&rays[start..], start), interleave, done);
    }
}

/// `rays` (ray `first` of the batch and those after it) traced one by one, or interleaved.
#[inline(always)]
fn trace_apart<Q: Query, I: Isa>(
    isa: I,
    sections: &Sections<'_>,
    (rays, first): (&[Ray], usize),
    interleave: bool,
    done: &mut impl FnMut(usize, Option<(u32, TriangleHit)>),
) {
    if interleave {
        let done = &mut |i: usize, found: Option<(u32, TriangleHit)>| done(first + i, found);
        Stream::<_, Q> { sections, rays, done, query: PhantomData }.run(isa);
        return;
    }
    for (i, ray) in rays.iter().enumerate() {
        let (counter, candidates) = (&mut (), &Unfiltered);
        done(first + i, SingleRay::<_, _, Q> { sections, ray, counter, candidates, query: PhantomData }.run(isa));
    }
}

/// A stream of rays, up to [`STREAM_WIDTH`] walks in flight, one step of each in turn; a finished walk's slot
/// takes the next ray.
struct Stream<'s, 'r, D, Q: Query> {
    sections: &'s Sections<'s>,
    rays: &'r [Ray],
    done: &'r mut D,
    query: PhantomData<Q>,
}

impl<D: FnMut(usize, Option<(u32, TriangleHit)>), Q: Query> Kernel for Stream<'_, '_, D, Q> {
    type Output = ();

    #[inline(always)]
    fn run<I: Isa>(self, isa: I) {
        let Stream { sections, rays, done, .. } = self;
        let mut stacks = [const { new_stack() }; STREAM_WIDTH];
        let mut walks: [Option<(usize, Walk<PacketHit>)>; STREAM_WIDTH] = [const { None }; STREAM_WIDTH];
        let mut next = 0;
        let mut in_flight = 0;
        loop {
            for (slot, stack) in walks.iter_mut().zip(&mut stacks) {
                if slot.is_none() {
                    // Start the next ray that enters the root's box; the others miss at once.
                    while next < rays.len() && slot.is_none() {
                        match Walk::start(sections, &rays[next], stack) {
                            Some(walk) => {
                                *slot = Some((next, walk));
                                in_flight += 1;
                            }
                            None => done(next, None),
                        }
                        next += 1;
                    }
                }
                if let Some((i, walk)) = slot
                    && !walk.step::<Q, I, (), _>(isa, sections, stack, &mut (), &mut PacketLeaves(&Unfiltered))
                {
                    done(*i, walk.found());
                    *slot = None;
                    in_flight -= 1;
                }
            }
            if in_flight == 0 && next >= rays.len() {
                return;
            }
        }
    }
}

/// Packets of [`PACKET_RAYS`] consecutive rays, one traversal each.
pub(crate) struct Packets<'s, 'r, D, Q: Query> {
    pub(crate) sections: &'s Sections<'s>,
    pub(crate) rays: &'r [Ray],
    pub(crate) done: &'r mut D,
    pub(crate) query: PhantomData<Q>,
}

impl<D: FnMut(usize, Option<(u32, TriangleHit)>), Q: Query> Kernel for Packets<'_, '_, D, Q> {
    type Output = ();

    #[inline(always)]
    fn run<I: Isa>(self, isa: I) {
        for (p, chunk) in self.rays.chunks(PACKET_RAYS).enumerate() {
            trace_packet::<Q, I>(isa, self.sections, chunk, &mut |l, found| (self.done)(p * PACKET_RAYS + l, found));
        }
    }
}
