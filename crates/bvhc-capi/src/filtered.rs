//! Hit filters from C: a function pointer and the caller's data, called for each candidate hit (by default only
//! on triangles the file marks not opaque, format 1.5) before it is accepted; nonzero accepts it, zero rejects
//! it and traversal goes on (`bvhc_loader::filter`). Closest and any hit, one ray or an array of them, one- and
//! two-level files; rays checked as the other calls check them.

use std::ffi::{c_int, c_void};

use bvhc_loader::{Candidate, FilterScope, HitFilter};

use crate::boundary::{BVHC_ERROR_ARGUMENT, BVHC_ERROR_RAY, BVHC_OK, BvhcFile, argument, file_ref, guarded};
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
}

/// `bvhc_filter`: returns nonzero to accept `candidate`, zero to reject it.
pub type BvhcFilter = Option<unsafe extern "C" fn(user_data: *mut c_void, candidate: *const BvhcCandidate) -> c_int>;

/// Only triangles the file marks not opaque are asked about (the default).
pub const BVHC_FILTER_NOT_OPAQUE: c_int = 0;
/// Every candidate is asked about.
pub const BVHC_FILTER_EVERY: c_int = 1;

/// A C filter as a [`HitFilter`].
struct CFilter {
    function: unsafe extern "C" fn(*mut c_void, *const BvhcCandidate) -> c_int,
    user_data: *mut c_void,
}

impl HitFilter for CFilter {
    fn accept(&self, candidate: &Candidate<'_>) -> bool {
        let record = BvhcCandidate {
            ray: candidate.ray,
            t: candidate.t,
            u: candidate.u,
            v: candidate.v,
            triangle_index: candidate.triangle_index,
            source_triangle_id: candidate.source_triangle_id.unwrap_or(u32::MAX),
            instance_index: candidate.instance_index.unwrap_or(u32::MAX),
        };
        // SAFETY: the caller of the filtered entry point promised a function that takes its user data and a
        // candidate; `record` lives for the call.
        unsafe { (self.function)(self.user_data, &record) != 0 }
    }
}

/// The filter and scope of a call, or an argument error naming `call`.
fn filter_of(
    call: &str,
    filter: BvhcFilter,
    user_data: *mut c_void,
    scope: c_int,
) -> Result<(CFilter, FilterScope), (c_int, String)> {
    let function = filter.ok_or_else(|| argument(&format!("{call}: filter must not be null")))?;
    let scope = match scope {
        BVHC_FILTER_NOT_OPAQUE => FilterScope::NotOpaque,
        BVHC_FILTER_EVERY => FilterScope::Every,
        other => {
            let why = format!("{call}: scope {other} is neither BVHC_FILTER_NOT_OPAQUE (0) nor BVHC_FILTER_EVERY (1)");
            return Err((BVHC_ERROR_ARGUMENT, why));
        }
    };
    Ok((CFilter { function, user_data }, scope))
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
        let (filter, scope) = filter_of(call, filter, user_data, scope)?;
        // SAFETY: by the contract each pointer is null or valid for its type; `as_ref`/`as_mut` check null.
        let (file, ray, out) = unsafe { (file_ref(call, file)?, ray.as_ref(), hit.as_mut()) };
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
        let (filter, scope) = filter_of(call, filter, user_data, scope)?;
        // SAFETY: by the contract each pointer is null or valid for its type.
        let (file, ray) = unsafe { (file_ref(call, file)?, ray.as_ref()) };
        let ray = ray.ok_or_else(|| argument("bvhc_any_hit_filtered: ray must not be null"))?;
        checked(call, ray)?;
        Ok(c_int::from(file.tracer().filtered(&filter, scope).any_hit(ray)))
    });
    if status > 1 { -1 } else { status }
}

/// `count` rays' closest accepted hits, as `bvhc_closest_hits` (each ray checked first: `BVHC_ERROR_RAY` naming
/// the first that breaks the contract, before any is traced), traced one after the other.
///
/// # Safety
///
/// As `bvhc_closest_hits` and `bvhc_closest_hit_filtered`.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)] // the C signature: the batch's arrays, then the filter's three
pub unsafe extern "C" fn bvhc_closest_hits_filtered(
    file: *const BvhcFile,
    rays: *const BvhcRay,
    count: usize,
    hits: *mut BvhcHit,
    found: *mut u8,
    filter: BvhcFilter,
    user_data: *mut c_void,
    scope: c_int,
) -> c_int {
    let call = "bvhc_closest_hits_filtered";
    guarded(|| {
        let (filter, scope) = filter_of(call, filter, user_data, scope)?;
        // SAFETY: the caller's contract is `file_ref`'s.
        let file = unsafe { file_ref(call, file) }?;
        if count == 0 {
            return Ok(BVHC_OK);
        }
        if rays.is_null() || hits.is_null() || found.is_null() {
            return Err(argument("bvhc_closest_hits_filtered: rays, hits and found must not be null"));
        }
        // SAFETY: not null, and by the contract each points to `count` elements; the outputs are distinct arrays.
        let (rays, hits, found) = unsafe {
            (
                std::slice::from_raw_parts(rays, count),
                std::slice::from_raw_parts_mut(hits, count),
                std::slice::from_raw_parts_mut(found, count),
            )
        };
        bvhc_loader::check_rays(rays).map_err(|error| (BVHC_ERROR_RAY, format!("{call}: {error}")))?;
        let filtered = file.tracer().filtered(&filter, scope);
        for ((ray, hit), flag) in rays.iter().zip(hits).zip(found) {
            let result = filtered.closest_hit(ray);
            *hit = result.as_ref().map(BvhcHit::from).unwrap_or_default();
            *flag = u8::from(result.is_some());
        }
        Ok(BVHC_OK)
    })
}

/// `count` rays' any-hit answers under `filter`, as `bvhc_closest_hits_filtered`.
///
/// # Safety
///
/// As `bvhc_any_hits` and `bvhc_closest_hit_filtered`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_any_hits_filtered(
    file: *const BvhcFile,
    rays: *const BvhcRay,
    count: usize,
    occluded: *mut u8,
    filter: BvhcFilter,
    user_data: *mut c_void,
    scope: c_int,
) -> c_int {
    let call = "bvhc_any_hits_filtered";
    guarded(|| {
        let (filter, scope) = filter_of(call, filter, user_data, scope)?;
        // SAFETY: the caller's contract is `file_ref`'s.
        let file = unsafe { file_ref(call, file) }?;
        if count == 0 {
            return Ok(BVHC_OK);
        }
        if rays.is_null() || occluded.is_null() {
            return Err(argument("bvhc_any_hits_filtered: rays and occluded must not be null"));
        }
        // SAFETY: not null, and by the contract each points to `count` elements.
        let (rays, occluded) =
            unsafe { (std::slice::from_raw_parts(rays, count), std::slice::from_raw_parts_mut(occluded, count)) };
        bvhc_loader::check_rays(rays).map_err(|error| (BVHC_ERROR_RAY, format!("{call}: {error}")))?;
        let filtered = file.tracer().filtered(&filter, scope);
        for (ray, flag) in rays.iter().zip(occluded) {
            *flag = u8::from(filtered.any_hit(ray));
        }
        Ok(BVHC_OK)
    })
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
