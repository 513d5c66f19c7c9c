//! Runtime reader of bvhc's `.bvh` files: zero-copy views, a full verifier, and a robust ray traversal kernel
//! (closest hit and any hit); the writer is behind the `write` feature, which renderers do not need.
//!
//! The format is specified in `format-spec/bvh-1.md` of the bvhc repository; the types in [`mod@format`] are its
//! single source of truth in Rust, used by the writer and the reader alike.
//!
//! ```
//! use bvhc_loader::{BvhFile, Ray, Trace};
//!
//! // A file `bvhc` converted: here the golden quad of the format spec, embedded; `BvhFile::read("scene.bvh")`
//! // reads one from disk, `MappedBvh::open` maps it.
//! let file = BvhFile::from_bytes(include_bytes!("../tests/data/quad-v1.1.bvh"))?;
//! let view = file.view();
//! view.verify()?; // every validity rule (opening checked the structural ones)
//! let tracer = view.tracer();
//! let hit = tracer.closest_hit(&Ray::new([0.25, 0.75, 1.0], [0.0, 0.0, -1.0])).expect("the quad is below");
//! assert_eq!(hit.t, 1.0);
//! assert!(hit.front_face); // the quad's counter-clockwise side faces +z
//! // A secondary ray from the hit, with t_min = 0 and no epsilon: it never meets the quad it leaves.
//! let surface = tracer.surface(&hit)?;
//! assert!(!tracer.any_hit(&surface.spawn([0.0, 0.0, 1.0])?));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Ways in: [`BvhView::open`] on aligned bytes you own; [`BvhFile::read`] / [`BvhFile::from_bytes`] into an
//! aligned owned buffer; `unsafe` [`MappedBvh::open`] for a memory map; `unsafe` [`BvhView::open_unchecked`]
//! for bytes already known to be valid. Opening checks the structural rules in O(number of sections);
//! [`BvhView::verify`] checks every rule.
//!
//! Hits ([`Hit`]) carry `t`, the barycentrics `u` (weight of `v1`) and `v` (weight of `v2`), the record's
//! index, its source id, the geometric normal and whether the ray met the front side;
//! [`BvhView::triangle_identities`] names the triangle the same way for every record of a split triangle, and
//! [`BvhView::source_corners`] gives the source primitive's vertices and their weights, to interpolate a
//! renderer's own normals or texture coordinates ([`SourceCorners::interpolate`]). For secondary rays,
//! [`Tracer::surface`] gives the hit's [`SurfacePoint`], whose `spawn` and `spawn_to` make rays with
//! `t_min = 0` that never meet the triangle they leave, at any scale, with no epsilon to choose.
//!
//! Two-level files (format 1.3) store a mesh placed many times once, in its object space, and place it by
//! instances under a top-level tree ([`BvhView::two_level`], [`TwoLevelSections`]); the same tracer calls walk
//! them, and a hit then names its instance ([`Hit::instance_index`]) with a world-space normal.
//!
//! Threads: [`BvhFile`], [`MappedBvh`], [`BvhView`], [`Tracer`] and [`WideTracer`] are `Send` and `Sync`;
//! tracing takes `&self`, allocates nothing and never blocks, so one tracer is shared by every thread (for
//! example inside a rayon loop). The batch calls (`closest_hits`, `any_hits` and their coherent forms) panic
//! when the result slice is not as long as the ray slice, naming the call.
//!
//! Every CPU tracer ([`Tracer`], [`WideTracer`], [`FilteredTracer`], `gpu::GpuLayoutTracer`) answers the
//! queries of one trait, [`Trace`] (bring it into scope): closest hit and any hit of one ray, and the batch
//! calls (slices, or a callback per ray with `_with`; a stream or coherent packets, [`Order`]).
//!
//! The crate root holds what a renderer uses; the rest is in modules, one a role: [`mod@format`] (the on-disk
//! types, checksums and costs), [`ray`] (the ray, the box and triangle tests, hits, spawning, instance boxes),
//! [`tracer`] and [`filter`] (the tracers, batch sizes, hit filters), [`wide`] (the 8-wide kernel over
//! in-memory arrays), [`gpu`] (the WGSL kernel, its CPU model, the wgpu tracer), [`verify`] (single rules) and,
//! with the `write` feature, `write` (the writer, atomic outputs). An owned [`BvhFile`], or any writable bytes opened as a
//! [`BvhViewMut`], can be edited in place (`edit`), refit to moved triangles ([`BvhViewMut::refit`]: per record or
//! per source vertex, on any number of threads, with a [`RefitReport`] for a [`RebuildPolicy`]; each layout's
//! refit beside its walk and encoder) and have its instances moved ([`BvhViewMut::move_instances`]).
//!
//! Rays: a [`Tracer`] checks every ray against the ray contract ([`Ray::check`]: finite origin and direction,
//! the direction not below `2^-64`, `0 <= t_min <= t_max`) and panics naming the rule and the ray, since such a
//! ray has no specified answer; [`Tracer::trusting_rays`] skips the check for callers that validate rays
//! themselves ([`check_rays`] for a batch).

mod binary;
mod error;
pub mod format;
pub mod gpu;
mod instances;
mod open;
mod parallel;
pub mod point;
mod refit;
pub mod ray;
mod simd;
mod source;
mod subtrees;
pub mod top_tree;
mod trace;
pub mod tracer;
pub mod verify;
mod walk_stack;
pub mod wide;
#[cfg(feature = "write")]
pub mod write;

pub use error::{Error, Rule, Violation};
pub use open::edit::SectionsMut;
pub use open::file::BvhFile;
#[cfg(feature = "mmap")]
pub use open::file::MappedBvh;
pub use open::sections::{GpuSections, TwoLevelSections, WideSections};
pub use open::structure::SectionInfo;
pub use open::view::BvhView;
pub use open::view_mut::BvhViewMut;
pub use point::{ClosestPoint, PointCandidate, PointFilter};
pub use ray::check_rays;
pub use ray::{
    BatchRayError, ForeignHit, Hit, HitCore, Ray, RayError, SurfacePoint, TraversalCounter, TraversalStats, TriangleHit,
};
pub use refit::{RebuildPolicy, RefitPositions, RefitReport};
pub use simd::KernelPath;
pub use source::corners::SourceCorners;
pub use source::identity::TriangleIdentities;
pub use trace::{BatchResult, Order, Trace};
pub use tracer::filter;
pub use tracer::filter::{FilteredTracer, HitFilter};
pub use tracer::winding::{WindingMoments, WindingNumbers};
pub use tracer::{Crossings, Kernel, TracedFile, Tracer};
pub use wide::WideTracer;

/// The README's example, compiled by `cargo test` (a doctest) so that a wrong example fails the tests.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctest;

/// The types a renderer shares between threads are `Send + Sync` (checked at compile time).
const _: () = {
    const fn shared<T: Send + Sync>() {}
    shared::<BvhFile>();
    #[cfg(feature = "mmap")]
    shared::<MappedBvh>();
    shared::<BvhView<'static>>();
    shared::<Tracer<'static>>();
    shared::<TracedFile>();
    shared::<WideTracer<'static>>();
    shared::<Hit>();
    shared::<SurfacePoint>();
};
