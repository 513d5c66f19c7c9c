//! Point queries through the C API (`bvhc_closest_point`, `bvhc_closest_points`, `bvhc_signed_distances`,
//! `bvhc_winding_numbers`): the loader's `Tracer::closest_point` and `WindingNumbers`, answers as
//! `bvhc_nearest_point` records (`format-spec/point-queries.md`) or plain arrays.

use std::ffi::{c_int, c_void};

use bvhc_loader::format::NO_INDEX;
use bvhc_loader::{ClosestPoint, PointCandidate, PointFilter, WindingNumbers};

use crate::boundary::{BVHC_OK, BvhcFile, argument, file_ref, guarded};

/// `bvhc_nearest_point`: the closest point of the surface to a query point (`include/bvhc.h`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhcNearestPoint {
    /// The point on the surface, world space.
    pub point: [f32; 3],
    /// Its distance from the query point.
    pub distance: f32,
    /// Weight of the record's `v1`.
    pub u: f32,
    /// Weight of the record's `v2`.
    pub v: f32,
    /// The triangle record.
    pub triangle_index: u32,
    /// Its source id, or `BVHC_NO_SOURCE_ID`.
    pub source_triangle_id: u32,
    /// The instance (two-level files), or `BVHC_NO_INSTANCE`.
    pub instance_index: u32,
    /// Zero.
    pub reserved: u32,
}

impl From<ClosestPoint> for BvhcNearestPoint {
    fn from(c: ClosestPoint) -> Self {
        BvhcNearestPoint {
            point: c.point,
            distance: c.distance,
            u: c.u,
            v: c.v,
            triangle_index: c.triangle_index,
            source_triangle_id: c.source_triangle_id.unwrap_or(u32::MAX),
            instance_index: c.instance_index.unwrap_or(u32::MAX),
            reserved: 0,
        }
    }
}

/// The record written where nothing lies within the bound: distance `INFINITY`, point NaN, no record.
const NOTHING: BvhcNearestPoint = BvhcNearestPoint {
    point: [f32::NAN; 3],
    distance: f32::INFINITY,
    u: 0.0,
    v: 0.0,
    triangle_index: u32::MAX,
    source_triangle_id: u32::MAX,
    instance_index: u32::MAX,
    reserved: 0,
};

/// An argument error unless `max_distance` is `>= 0` (`INFINITY` for no bound).
fn check_bound(call: &str, max_distance: f32) -> Result<(), (c_int, String)> {
    if max_distance.is_nan() || max_distance < 0.0 {
        return Err(argument(&format!("{call}: max_distance {max_distance} is not >= 0 (INFINITY for no bound)")));
    }
    Ok(())
}

/// An argument error naming point `index` unless its coordinates are finite.
fn check_point(call: &str, index: usize, point: [f32; 3]) -> Result<(), (c_int, String)> {
    if !point.iter().all(|c| c.is_finite()) {
        return Err(argument(&format!("{call}: point {index} {point:?} is not finite")));
    }
    Ok(())
}

/// Writes the closest point of the file's surface to `point` (3 floats) within `max_distance` (inclusive;
/// `INFINITY` for no bound) to `out` and returns 1, or writes the empty record (distance `INFINITY`, point NaN,
/// indices `0xFFFFFFFF`) and returns 0 when nothing is that near. A negative status for a null argument, a point
/// that is not finite or a bound below 0 or NaN.
///
/// # Safety
///
/// `file` is null or a live file; `point` null or 3 readable floats; `out` null or a writable record.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_closest_point(
    file: *const BvhcFile,
    point: *const f32,
    max_distance: f32,
    out: *mut BvhcNearestPoint,
) -> c_int {
    guarded(|| {
        let call = "bvhc_closest_point";
        // SAFETY: the caller's contract.
        let file = unsafe { file_ref(call, file) }?;
        if point.is_null() || out.is_null() {
            return Err(argument(&format!("{call}: point or out is null")));
        }
        // SAFETY: `point` is not null, and by the contract 3 readable floats.
        let p = unsafe { [*point, *point.add(1), *point.add(2)] };
        check_point(call, 0, p)?;
        check_bound(call, max_distance)?;
        let found = file.tracer().closest_point(p, max_distance);
        // SAFETY: `out` is not null, and by the contract writable.
        unsafe { *out = found.map_or(NOTHING, BvhcNearestPoint::from) };
        Ok(c_int::from(found.is_some()))
    })
}

/// The closest point of each of `count` points (`points`: `3 count` floats, x y z a point) within
/// `max_distance`, into `out[i]` (the empty record where nothing is that near), on up to `threads` threads (0:
/// every core): the same records as `bvhc_closest_point` a point, whatever the thread count. `BVHC_OK`, or an
/// argument error naming the first point that is not finite (nothing written then).
///
/// # Safety
///
/// `file` is null or a live file; `points` null or `3 count` readable floats; `out` null or `count` writable
/// records not overlapping `points`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_closest_points(
    file: *const BvhcFile,
    points: *const f32,
    count: usize,
    max_distance: f32,
    threads: u32,
    out: *mut BvhcNearestPoint,
) -> c_int {
    // SAFETY: the caller's contract, passed on.
    unsafe { closest_points_call("bvhc_closest_points", file, (points, count), max_distance, threads, None, out) }
}

/// A C point filter: `keep(user_data, triangle_index, source_triangle_id, instance_index)`, nonzero to keep.
pub type BvhcPointFilter = unsafe extern "C" fn(*mut c_void, u32, u32, u32) -> c_int;

/// [`bvhc_closest_points`] among the triangles `keep` keeps (nonzero), as if the others were absent: `keep` is
/// called with `user_data`, the record, its source id (`BVHC_NO_INDEX` without ids) and instance
/// (`BVHC_NO_INDEX` in a one-level file), for records within a query's reach, from up to `threads` threads at
/// once; it must answer alike for the same record. An argument error for a null `keep`.
///
/// # Safety
///
/// As [`bvhc_closest_points`]; `keep` may be called from several threads at once with `user_data`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_closest_points_filtered(
    file: *const BvhcFile,
    points: *const f32,
    count: usize,
    max_distance: f32,
    threads: u32,
    keep: Option<BvhcPointFilter>,
    user_data: *mut c_void,
    out: *mut BvhcNearestPoint,
) -> c_int {
    let call = "bvhc_closest_points_filtered";
    let Some(function) = keep else {
        return guarded(|| Err(argument(&format!("{call}: keep is null"))));
    };
    let filter = CPointFilter { function, user_data };
    // SAFETY: the caller's contract, passed on.
    unsafe { closest_points_call(call, file, (points, count), max_distance, threads, Some(&filter), out) }
}

/// A C point filter and its user data.
struct CPointFilter {
    function: BvhcPointFilter,
    user_data: *mut c_void,
}

// SAFETY: the batch shares one `CPointFilter` between its threads; `bvhc_closest_points_filtered`'s contract makes
// the caller promise that `function` may be called from several threads at once with `user_data`.
unsafe impl Sync for CPointFilter {}

impl PointFilter for CPointFilter {
    fn keep(&self, candidate: &PointCandidate) -> bool {
        let (source, instance) = (candidate.source_triangle_id, candidate.instance_index);
        // SAFETY: the caller gave `function` and `user_data` for this call, which outlives it.
        let kept = unsafe {
            (self.function)(
                self.user_data,
                candidate.triangle_index,
                source.unwrap_or(NO_INDEX),
                instance.unwrap_or(NO_INDEX),
            )
        };
        kept != 0
    }
}

/// The batch calls' work: the arguments checked, the points answered (among what `filter` keeps) into `out`.
///
/// # Safety
///
/// As [`bvhc_closest_points`].
unsafe fn closest_points_call(
    call: &str,
    file: *const BvhcFile,
    (points, count): (*const f32, usize),
    max_distance: f32,
    threads: u32,
    filter: Option<&CPointFilter>,
    out: *mut BvhcNearestPoint,
) -> c_int {
    guarded(|| {
        // SAFETY: the caller's contract.
        let file = unsafe { file_ref(call, file) }?;
        check_bound(call, max_distance)?;
        if count == 0 {
            return Ok(BVHC_OK);
        }
        if points.is_null() || out.is_null() {
            return Err(argument(&format!("{call}: points or out is null")));
        }
        // SAFETY: by the contract `points` holds `3 count` floats and `out` `count` records, apart.
        let rows = unsafe { point_rows(call, points, count) }?;
        // SAFETY: as above.
        let out = unsafe { std::slice::from_raw_parts_mut(out, count) };
        let mut found = vec![None; count];
        let (tracer, threads) = (file.tracer(), thread_count(threads));
        match filter {
            Some(filter) => tracer.closest_points_filtered(&rows, max_distance, filter, &mut found, threads),
            None => tracer.closest_points(&rows, max_distance, &mut found, threads),
        }
        for (slot, answer) in out.iter_mut().zip(found) {
            *slot = answer.map_or(NOTHING, BvhcNearestPoint::from);
        }
        Ok(BVHC_OK)
    })
}

/// The thread count a call's `threads` argument asks for (0: every core).
fn thread_count(threads: u32) -> usize {
    match threads {
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        n => n as usize,
    }
}

/// The `count` points at `points` (3 floats each), each checked finite (else an argument error naming it).
///
/// # Safety
///
/// `points` is not null and points to `3 count` readable floats.
unsafe fn point_rows(call: &str, points: *const f32, count: usize) -> Result<Vec<[f32; 3]>, (c_int, String)> {
    let floats = count.checked_mul(3).ok_or_else(|| argument(&format!("{call}: count {count} overflows")))?;
    // SAFETY: the caller's contract.
    let coordinates = unsafe { std::slice::from_raw_parts(points, floats) };
    let rows: Vec<[f32; 3]> = coordinates.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    for (i, &p) in rows.iter().enumerate() {
        check_point(call, i, p)?;
    }
    Ok(rows)
}

/// The signed distance of each of `count` points (3 floats each) to the surface into `out[i]`: the closest
/// point's distance, negative where the generalized winding number's magnitude exceeds 1/2 (inside), on up to
/// `threads` threads (0: every core). `BVHC_ERROR_ARGUMENT` naming the first point that is not finite;
/// `BVHC_ERROR_MEMORY` when the winding moments (computed by the first call on the file and kept with it until
/// it changes, 136 bytes a node) cannot be had.
///
/// # Safety
///
/// `file` is null or a live file; `points` null or `3 count` readable floats; `out` null or `count` writable
/// floats not overlapping `points`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_signed_distances(
    file: *const BvhcFile,
    points: *const f32,
    count: usize,
    threads: u32,
    out: *mut f32,
) -> c_int {
    let fill = |numbers: &WindingNumbers<'_>, rows: &[[f32; 3]], out: &mut [f32], threads| {
        numbers.signed_distances(rows, out, threads)
    };
    // SAFETY: the caller's contract is the helper's.
    unsafe { winding_call("bvhc_signed_distances", file, (points, count), threads, out, fill) }
}

/// The generalized winding number of the surface at each of `count` points into `out[i]` (1 inside a closed
/// mesh wound counter-clockwise seen from outside, -1 for the other winding, 0 outside), on up to `threads`
/// threads (0: every core). Errors as [`bvhc_signed_distances`].
///
/// # Safety
///
/// As [`bvhc_signed_distances`], with `out` `count` writable doubles.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_winding_numbers(
    file: *const BvhcFile,
    points: *const f32,
    count: usize,
    threads: u32,
    out: *mut f64,
) -> c_int {
    let fill = |numbers: &WindingNumbers<'_>, rows: &[[f32; 3]], out: &mut [f64], threads| {
        numbers.winding_numbers(rows, out, threads)
    };
    // SAFETY: the caller's contract is the helper's.
    unsafe { winding_call("bvhc_winding_numbers", file, (points, count), threads, out, fill) }
}

/// The calls over the winding moments: checks the arguments, takes the file's moments (computed by its first
/// such call), and has `fill` write
/// `count` values into `out` on `threads` threads.
///
/// # Safety
///
/// `file` is null or a live file; `points` null or `3 count` readable floats; `out` null or `count` writable
/// values not overlapping `points`.
unsafe fn winding_call<T>(
    call: &str,
    file: *const BvhcFile,
    (points, count): (*const f32, usize),
    threads: u32,
    out: *mut T,
    fill: impl FnOnce(&WindingNumbers<'_>, &[[f32; 3]], &mut [T], usize),
) -> c_int {
    guarded(|| {
        // SAFETY: the caller's contract.
        let file = unsafe { file_ref(call, file) }?;
        if count == 0 {
            return Ok(BVHC_OK);
        }
        if points.is_null() || out.is_null() {
            return Err(argument(&format!("{call}: points or out is null")));
        }
        // SAFETY: by the contract `points` holds `3 count` floats and `out` `count` values, apart.
        let (rows, out) = unsafe { (point_rows(call, points, count)?, std::slice::from_raw_parts_mut(out, count)) };
        let numbers = file.traced.winding_numbers().map_err(|e| memory(call, e))?;
        fill(&numbers, &rows, out, thread_count(threads));
        Ok(BVHC_OK)
    })
}

/// The memory error of a call whose winding moments could not be allocated.
fn memory(call: &str, error: std::collections::TryReserveError) -> (c_int, String) {
    (crate::boundary::BVHC_ERROR_MEMORY, format!("{call}: the winding moments: {error}"))
}
