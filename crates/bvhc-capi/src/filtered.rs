//! Hit filters from C: a function pointer and the caller's data, called for each candidate hit (by default only
//! on triangles the file marks not opaque, format 1.5) before it is accepted; nonzero accepts it, zero rejects
//! it and traversal goes on (`bvhc_loader::filter`). The candidate carries what a renderer's alpha test needs
//! to find its material and texture coordinates: the source primitive (glTF mesh, primitive, node) and the
//! record's source vertices. Closest and any hit of one ray here, one- and two-level files; rays checked as the
//! other calls check them. Batches: `filtered_batch.rs`.

use bvhc_loader::Trace;
use std::ffi::{c_int, c_void};

use bvhc_loader::format::NO_INDEX;
use bvhc_loader::{BvhView, HitFilter, filter::Candidate, filter::FilterScope};

use crate::boundary::{BVHC_ERROR_ARGUMENT, BvhcFile, argument, file_ref, guarded};
use crate::records::{BvhcHit, BvhcRay};
use crate::single::checked;

/// `bvhc_candidate`: what a C filter sees of a candidate hit.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct BvhcCandidate {
    /// The ray as the caller gave it.
    pub ray: *const BvhcRay,
    /// Distance along the ray.
    pub t: f32,
    /// Barycentric weight of the record's `v1`.
    pub u: f32,
    /// Barycentric weight of the record's `v2`.
    pub v: f32,
    /// The triangle record.
    pub triangle_index: u32,
    /// Its source id, or `0xFFFFFFFF` without ids.
    pub source_triangle_id: u32,
    /// In a two-level file, the instance; `0xFFFFFFFF` otherwise.
    pub instance_index: u32,
    /// The glTF mesh (OBJ model) of its source primitive, or `0xFFFFFFFF` without ids and a source table.
    pub mesh_index: u32,
    /// The glTF primitive within that mesh (whose material the triangle has), or `0xFFFFFFFF`.
    pub primitive_index: u32,
    /// The glTF node that placed it (through an instance, the instance's node), or `0xFFFFFFFF`.
    pub node_index: u32,
    /// The source vertices of the record's `v0`, `v1`, `v2` in that primitive (format 1.2), which `u` and `v`
    /// weigh as in `bvhc_source_corners`; `0xFFFFFFFF` each without the `source_vertices` section.
    pub source_vertices: [u32; 3],
}

/// `bvhc_filter`: returns nonzero to accept `candidate`, zero to reject it.
pub type BvhcFilter = Option<unsafe extern "C" fn(user_data: *mut c_void, candidate: *const BvhcCandidate) -> c_int>;

/// Only triangles the file marks not opaque are asked about (the default).
pub const BVHC_FILTER_NOT_OPAQUE: c_int = 0;
/// Every candidate is asked about.
pub const BVHC_FILTER_EVERY: c_int = 1;

/// A C filter as a [`HitFilter`], with the file's view for the candidate's source primitive.
pub(crate) struct CFilter<'a> {
    function: unsafe extern "C" fn(*mut c_void, *const BvhcCandidate) -> c_int,
    user_data: *mut c_void,
    view: BvhView<'a>,
}

// SAFETY: the parallel batch calls share one `CFilter` between threads; their C contract makes the caller
// promise that `function` may be called from several threads at once with `user_data`, and `view` is `Sync`.
unsafe impl Sync for CFilter<'_> {}

impl CFilter<'_> {
    /// `candidate` as C sees it: the kernel's fields and the source primitive's (an O(log ranges) lookup).
    fn record(&self, candidate: &Candidate<'_>) -> BvhcCandidate {
        let view = &self.view;
        let range = candidate.source_triangle_id.and_then(|id| view.source_range_of(id));
        let placement = candidate.instance_index.and_then(|i| view.two_level().and_then(|s| s.placement(i)));
        let node_index = match (range.map_or(NO_INDEX, |r| r.node_index), placement) {
            (NO_INDEX, Some((instance, _))) => instance.node_index,
            (node, _) => node,
        };
        let source_vertices = view.source_vertices().and_then(|all| all.get(candidate.triangle_index as usize));
        BvhcCandidate {
            ray: candidate.ray,
            t: candidate.t,
            u: candidate.u,
            v: candidate.v,
            triangle_index: candidate.triangle_index,
            source_triangle_id: candidate.source_triangle_id.unwrap_or(NO_INDEX),
            instance_index: candidate.instance_index.unwrap_or(NO_INDEX),
            mesh_index: range.map_or(NO_INDEX, |r| r.mesh_index),
            primitive_index: range.map_or(NO_INDEX, |r| r.primitive_index),
            node_index,
            source_vertices: source_vertices.map_or([NO_INDEX; 3], |s| s.indices),
        }
    }
}

impl HitFilter for CFilter<'_> {
    fn accept(&self, candidate: &Candidate<'_>) -> bool {
        let record = self.record(candidate);
        // SAFETY: the caller of the filtered entry point promised a function that takes its user data and a
        // candidate; `record` lives for the call.
        unsafe { (self.function)(self.user_data, &record) != 0 }
    }
}

/// The filter over `file` and the scope of a call, or an argument error naming `call`.
pub(crate) fn filter_of<'a>(
    call: &str,
    file: &'a BvhcFile,
    filter: BvhcFilter,
    user_data: *mut c_void,
    scope: c_int,
) -> Result<(CFilter<'a>, FilterScope), (c_int, String)> {
    let function = filter.ok_or_else(|| argument(&format!("{call}: filter must not be null")))?;
    let scope = match scope {
        BVHC_FILTER_NOT_OPAQUE => FilterScope::NotOpaque,
        BVHC_FILTER_EVERY => FilterScope::Every,
        other => {
            let why = format!("{call}: scope {other} is neither BVHC_FILTER_NOT_OPAQUE (0) nor BVHC_FILTER_EVERY (1)");
            return Err((BVHC_ERROR_ARGUMENT, why));
        }
    };
    Ok((CFilter { function, user_data, view: file.view() }, scope))
}

/// The closest hit of `*ray` that `filter` accepts, into `*hit`: 1, 0 on a miss (`*hit` untouched), -1 on an
/// error (a null pointer, a bad scope, a ray that breaks the contract).
///
/// # Safety
///
/// As `bvhc_closest_hit`; `filter` is null or a function that may be called with `user_data` and a candidate
/// from the calling thread, any number of times during the call.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_closest_hit_filtered(
    file: *const BvhcFile,
    ray: *const BvhcRay,
    hit: *mut BvhcHit,
    filter: BvhcFilter,
    user_data: *mut c_void,
    scope: c_int,
) -> c_int {
    let call = "bvhc_closest_hit_filtered";
    let status = guarded(|| {
        // SAFETY: by the contract each pointer is null or valid for its type; `as_ref`/`as_mut` check null.
        let (file, ray, out) = unsafe { (file_ref(call, file)?, ray.as_ref(), hit.as_mut()) };
        let (filter, scope) = filter_of(call, file, filter, user_data, scope)?;
        let (Some(ray), Some(out)) = (ray, out) else {
            return Err(argument("bvhc_closest_hit_filtered: ray and hit must not be null"));
        };
        checked(call, ray)?;
        match file.tracer().filtered(&filter, scope).closest_hit(ray) {
            Some(found) => {
                *out = BvhcHit::from(&found);
                Ok(1)
            }
            None => Ok(0),
        }
    });
    if status > 1 { -1 } else { status }
}

/// Whether `filter` accepts some hit along `*ray`: 1 or 0, -1 on an error (as `bvhc_closest_hit_filtered`).
///
/// # Safety
///
/// As `bvhc_closest_hit_filtered`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_any_hit_filtered(
    file: *const BvhcFile,
    ray: *const BvhcRay,
    filter: BvhcFilter,
    user_data: *mut c_void,
    scope: c_int,
) -> c_int {
    let call = "bvhc_any_hit_filtered";
    let status = guarded(|| {
        // SAFETY: by the contract each pointer is null or valid for its type.
        let (file, ray) = unsafe { (file_ref(call, file)?, ray.as_ref()) };
        let (filter, scope) = filter_of(call, file, filter, user_data, scope)?;
        let ray = ray.ok_or_else(|| argument("bvhc_any_hit_filtered: ray must not be null"))?;
        checked(call, ray)?;
        Ok(c_int::from(file.tracer().filtered(&filter, scope).any_hit(ray)))
    });
    if status > 1 { -1 } else { status }
}

/// The flags of triangle record `triangle_index` (bit 0 `BVHC_TRIANGLE_NOT_OPAQUE`; 0 in a file without the
/// `triangle_flags` section), or -1 for an index out of range or a null file.
///
/// # Safety
///
/// `file` is null or a live file.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_triangle_flags(file: *const BvhcFile, triangle_index: u32) -> c_int {
    // SAFETY: by the contract `file` is null or live.
    let Some(file) = (unsafe { file.as_ref() }) else { return -1 };
    let view = file.view();
    if triangle_index as usize >= view.triangles().len() {
        return -1;
    }
    view.triangle_flags().and_then(|flags| flags.get(triangle_index as usize)).map_or(0, |&f| c_int::from(f))
}
