//! Batches under a hit filter (`filtered.rs` has the filter and single rays): every ray checked first
//! (`BVHC_ERROR_RAY` naming the first that breaks the contract, before any is traced), then traced one after the
//! other, on the calling thread or, in the `_threads` forms, split into contiguous chunks over as many threads as
//! the caller allows (the filter is then called from all of them at once). Results are each ray's own, whatever
//! the thread count.

use bvhc_loader::Trace;
use std::ffi::{c_int, c_void};

use bvhc_loader::{Ray, filter::FilterScope};

use crate::boundary::{BVHC_ERROR_MEMORY, BVHC_ERROR_RAY, BVHC_OK, BvhcFile, argument, file_ref, guarded};
use crate::filtered::{BvhcFilter, CFilter, filter_of};
use crate::records::{BvhcHit, BvhcRay};

/// Fewest rays a thread of the `_threads` calls is given (below it, starting a thread costs more than tracing).
const RAYS_PER_THREAD: usize = 1024;

/// The threads to use for `count` rays when the caller allows `threads` (0: every core this process may use).
fn thread_count(threads: usize, count: usize) -> usize {
    let allowed = match threads {
        0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
        n => n,
    };
    allowed.min(count.div_ceil(RAYS_PER_THREAD)).max(1)
}

/// Runs `work` over matching chunks of `rays` and `out` on `threads` threads (the calling thread takes the
/// first chunk).
fn in_chunks<T: Send>(rays: &[Ray], out: &mut [T], threads: usize, work: impl Fn(&[Ray], &mut [T]) + Sync) {
    let chunk = rays.len().div_ceil(threads).max(1);
    std::thread::scope(|scope| {
        let mut pieces = rays.chunks(chunk).zip(out.chunks_mut(chunk));
        let first = pieces.next();
        for (r, o) in pieces {
            let work = &work;
            scope.spawn(move || work(r, o));
        }
        if let Some((r, o)) = first {
            work(r, o);
        }
    });
}

/// The shared body of the closest-hit batch calls.
///
/// # Safety
///
/// As `bvhc_closest_hits_filtered_threads`.
#[allow(clippy::too_many_arguments)] // the C signature's arguments, passed through
unsafe fn closest_hits(
    call: &'static str,
    file: *const BvhcFile,
    (rays, count): (*const BvhcRay, usize),
    (hits, found): (*mut BvhcHit, *mut u8),
    (filter, user_data, scope): (BvhcFilter, *mut c_void, c_int),
    threads: usize,
) -> c_int {
    guarded(|| {
        // SAFETY: the caller's contract is `file_ref`'s.
        let file = unsafe { file_ref(call, file) }?;
        let (filter, scope) = filter_of(call, file, filter, user_data, scope)?;
        if count == 0 {
            return Ok(BVHC_OK);
        }
        if rays.is_null() || hits.is_null() || found.is_null() {
            return Err(argument(&format!("{call}: rays, hits and found must not be null")));
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
        let mut results: Vec<(BvhcHit, u8)> = Vec::new();
        let memory = |_| (BVHC_ERROR_MEMORY, format!("{call}: the system refused memory for {count} results"));
        results.try_reserve_exact(count).map_err(memory)?;
        results.resize(count, (BvhcHit::default(), 0));
        in_chunks(rays, &mut results, thread_count(threads, count), |rays, out| {
            trace_closest(file, &filter, scope, rays, out);
        });
        for ((hit, flag), (result, was_found)) in hits.iter_mut().zip(found.iter_mut()).zip(results) {
            *hit = result;
            *flag = was_found;
        }
        Ok(BVHC_OK)
    })
}

fn trace_closest(file: &BvhcFile, filter: &CFilter<'_>, scope: FilterScope, rays: &[Ray], out: &mut [(BvhcHit, u8)]) {
    let filtered = file.tracer().filtered(filter, scope);
    for (ray, slot) in rays.iter().zip(out) {
        let result = filtered.closest_hit(ray);
        *slot = (result.as_ref().map(BvhcHit::from).unwrap_or_default(), u8::from(result.is_some()));
    }
}

/// The shared body of the any-hit batch calls.
///
/// # Safety
///
/// As `bvhc_any_hits_filtered_threads`.
unsafe fn any_hits(
    call: &'static str,
    file: *const BvhcFile,
    (rays, count): (*const BvhcRay, usize),
    occluded: *mut u8,
    (filter, user_data, scope): (BvhcFilter, *mut c_void, c_int),
    threads: usize,
) -> c_int {
    guarded(|| {
        // SAFETY: the caller's contract is `file_ref`'s.
        let file = unsafe { file_ref(call, file) }?;
        let (filter, scope) = filter_of(call, file, filter, user_data, scope)?;
        if count == 0 {
            return Ok(BVHC_OK);
        }
        if rays.is_null() || occluded.is_null() {
            return Err(argument(&format!("{call}: rays and occluded must not be null")));
        }
        // SAFETY: not null, and by the contract each points to `count` elements.
        let (rays, occluded) =
            unsafe { (std::slice::from_raw_parts(rays, count), std::slice::from_raw_parts_mut(occluded, count)) };
        bvhc_loader::check_rays(rays).map_err(|error| (BVHC_ERROR_RAY, format!("{call}: {error}")))?;
        in_chunks(rays, occluded, thread_count(threads, count), |rays, out| {
            let filtered = file.tracer().filtered(&filter, scope);
            for (ray, flag) in rays.iter().zip(out) {
                *flag = u8::from(filtered.any_hit(ray));
            }
        });
        Ok(BVHC_OK)
    })
}

/// `count` rays' closest accepted hits, as `bvhc_closest_hits`, traced one after the other on the calling
/// thread.
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
    // SAFETY: this function's contract is `closest_hits`'s with one thread.
    unsafe { closest_hits(call, file, (rays, count), (hits, found), (filter, user_data, scope), 1) }
}

/// `bvhc_closest_hits_filtered` on up to `threads` threads (0: every core this process may use), contiguous
/// chunks of at least 1024 rays each: the same results, with the filter called from several threads at once.
///
/// # Safety
///
/// As `bvhc_closest_hits_filtered`; moreover `filter` may be called with `user_data` from several threads at the
/// same time (it must not modify shared state without synchronizing).
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)] // the C signature: the batch's arrays, the filter's three, the threads
pub unsafe extern "C" fn bvhc_closest_hits_filtered_threads(
    file: *const BvhcFile,
    rays: *const BvhcRay,
    count: usize,
    hits: *mut BvhcHit,
    found: *mut u8,
    filter: BvhcFilter,
    user_data: *mut c_void,
    scope: c_int,
    threads: usize,
) -> c_int {
    let call = "bvhc_closest_hits_filtered_threads";
    // SAFETY: this function's contract is `closest_hits`'s.
    unsafe { closest_hits(call, file, (rays, count), (hits, found), (filter, user_data, scope), threads) }
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
    // SAFETY: this function's contract is `any_hits`'s with one thread.
    unsafe { any_hits(call, file, (rays, count), occluded, (filter, user_data, scope), 1) }
}

/// `bvhc_any_hits_filtered` on up to `threads` threads, as `bvhc_closest_hits_filtered_threads`.
///
/// # Safety
///
/// As `bvhc_closest_hits_filtered_threads`.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)] // the C signature: the batch's arrays, the filter's three, the threads
pub unsafe extern "C" fn bvhc_any_hits_filtered_threads(
    file: *const BvhcFile,
    rays: *const BvhcRay,
    count: usize,
    occluded: *mut u8,
    filter: BvhcFilter,
    user_data: *mut c_void,
    scope: c_int,
    threads: usize,
) -> c_int {
    let call = "bvhc_any_hits_filtered_threads";
    // SAFETY: this function's contract is `any_hits`'s.
    unsafe { any_hits(call, file, (rays, count), occluded, (filter, user_data, scope), threads) }
}
