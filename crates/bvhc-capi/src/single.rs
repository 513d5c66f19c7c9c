//! One ray at a time: `bvhc_closest_hit`, `bvhc_any_hit` (checked against the ray contract) and their
//! `_unchecked` forms, `bvhc_check_rays`, and `bvhc_spawn_ray` for secondary rays.

use bvhc_loader::Trace;
use std::ffi::c_int;

use bvhc_loader::Ray;

use crate::boundary::{BVHC_ERROR_ARGUMENT, BVHC_ERROR_RAY, BVHC_OK, BvhcFile, argument, guarded};
use crate::records::{BvhcHit, BvhcRay};

/// A ray call's status as the single-ray calls return it: 1 or 0, and -1 for any error.
fn hit_or_error(status: c_int) -> c_int {
    if status > 1 { -1 } else { status }
}

/// `ray`'s check for `call`: `BVHC_ERROR_RAY` naming the rule it breaks.
pub(crate) fn checked(call: &str, ray: &Ray) -> Result<(), (c_int, String)> {
    ray.check().map_err(|error| (BVHC_ERROR_RAY, format!("{call}: the ray breaks the ray contract: {error}")))
}

/// The closest hit of `ray`, checked when `check`, into `hit`.
///
/// # Safety
///
/// As [`bvhc_closest_hit`].
unsafe fn closest_hit(call: &str, check: bool, file: *const BvhcFile, ray: *const BvhcRay, hit: *mut BvhcHit) -> c_int {
    hit_or_error(guarded(|| {
        // SAFETY: by the contract each pointer is null or valid for its type; `as_ref`/`as_mut` check null.
        let (file, ray, out) = unsafe { (file.as_ref(), ray.as_ref(), hit.as_mut()) };
        let (Some(file), Some(ray), Some(out)) = (file, ray, out) else {
            return Err(argument(&format!("{call}: file, ray and hit must not be null")));
        };
        if check {
            checked(call, ray)?;
        }
        match file.tracer().closest_hit(ray) {
            Some(found) => {
                *out = BvhcHit::from(&found);
                Ok(1)
            }
            None => Ok(0),
        }
    }))
}

/// The closest hit of `*ray` into `*hit`: 1 when it hit, 0 on a miss (`*hit` untouched), -1 on an error (a
/// null pointer, or a ray that breaks the ray contract: the message names the rule).
///
/// # Safety
///
/// `file` is null or a live file; `ray` is null or points to a `bvhc_ray`; `hit` is null or points to
/// writable storage for a `bvhc_hit`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_closest_hit(file: *const BvhcFile, ray: *const BvhcRay, hit: *mut BvhcHit) -> c_int {
    // SAFETY: the caller's contract is this function's.
    unsafe { closest_hit("bvhc_closest_hit", true, file, ray, hit) }
}

/// [`bvhc_closest_hit`] without the ray check, for callers that check their rays themselves: a ray that
/// breaks the contract gets an unspecified answer (never a crash or a hang).
///
/// # Safety
///
/// As [`bvhc_closest_hit`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_closest_hit_unchecked(
    file: *const BvhcFile,
    ray: *const BvhcRay,
    hit: *mut BvhcHit,
) -> c_int {
    // SAFETY: the caller's contract is this function's.
    unsafe { closest_hit("bvhc_closest_hit_unchecked", false, file, ray, hit) }
}

/// Whether `ray`, checked when `check`, hits anything.
///
/// # Safety
///
/// As [`bvhc_any_hit`].
unsafe fn any_hit(call: &str, check: bool, file: *const BvhcFile, ray: *const BvhcRay) -> c_int {
    hit_or_error(guarded(|| {
        // SAFETY: by the contract each pointer is null or valid for its type.
        let (Some(file), Some(ray)) = (unsafe { file.as_ref() }, unsafe { ray.as_ref() }) else {
            return Err(argument(&format!("{call}: file and ray must not be null")));
        };
        if check {
            checked(call, ray)?;
        }
        Ok(c_int::from(file.tracer().any_hit(ray)))
    }))
}

/// Whether anything is hit along `*ray`: 1 or 0, -1 on an error (as [`bvhc_closest_hit`]).
///
/// # Safety
///
/// `file` is null or a live file; `ray` is null or points to a `bvhc_ray`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_any_hit(file: *const BvhcFile, ray: *const BvhcRay) -> c_int {
    // SAFETY: the caller's contract is this function's.
    unsafe { any_hit("bvhc_any_hit", true, file, ray) }
}

/// [`bvhc_any_hit`] without the ray check, as [`bvhc_closest_hit_unchecked`].
///
/// # Safety
///
/// As [`bvhc_any_hit`].
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_any_hit_unchecked(file: *const BvhcFile, ray: *const BvhcRay) -> c_int {
    // SAFETY: the caller's contract is this function's.
    unsafe { any_hit("bvhc_any_hit_unchecked", false, file, ray) }
}

/// Checks `count` rays against the ray contract, the check the checked calls make: `BVHC_OK`, or
/// `BVHC_ERROR_RAY` with the first ray that breaks it in `*first_invalid` (when not null) and the rule in the
/// message. For callers that check once and then trace with the `_unchecked` calls.
///
/// # Safety
///
/// `rays` is null or points to `count` rays; `first_invalid` is null or writable.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_check_rays(rays: *const BvhcRay, count: usize, first_invalid: *mut usize) -> c_int {
    guarded(|| {
        if count == 0 {
            return Ok(BVHC_OK);
        }
        if rays.is_null() {
            return Err(argument("bvhc_check_rays: rays must not be null"));
        }
        // SAFETY: not null, and by the contract it points to `count` rays.
        let rays = unsafe { std::slice::from_raw_parts(rays, count) };
        match bvhc_loader::check_rays(rays) {
            Ok(()) => Ok(BVHC_OK),
            Err(error) => {
                // SAFETY: by the contract `first_invalid` is null or writable.
                if let Some(out) = unsafe { first_invalid.as_mut() } {
                    *out = error.index;
                }
                Err((BVHC_ERROR_RAY, format!("bvhc_check_rays: {error}")))
            }
        }
    })
}

/// A ray leaving the surface of `*hit` along `direction` with `t_min = 0` that does not meet the triangle it
/// leaves (`SurfacePoint::spawn`), into `*out`. `BVHC_ERROR_ARGUMENT` for a hit that cannot be this file's (a
/// record or instance out of range, a record outside the instance's mesh, `u`, `v` NaN or off the triangle),
/// `BVHC_ERROR_RAY` for a direction the ray contract refuses (NaN, infinite, zero), each naming why.
///
/// # Safety
///
/// `file` is null or a live file; `hit` null or a `bvhc_hit`; `direction` null or three floats; `out` null
/// or writable storage for a `bvhc_ray`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_spawn_ray(
    file: *const BvhcFile,
    hit: *const BvhcHit,
    direction: *const f32,
    out: *mut BvhcRay,
) -> c_int {
    guarded(|| {
        if direction.is_null() {
            return Err(argument("bvhc_spawn_ray: direction must not be null"));
        }
        // SAFETY: by the contract each pointer is null (checked) or valid; `direction` points to three floats.
        let (file, hit, out, direction) =
            unsafe { (file.as_ref(), hit.as_ref(), out.as_mut(), *(direction as *const [f32; 3])) };
        let (Some(file), Some(hit), Some(out)) = (file, hit, out) else {
            return Err(argument("bvhc_spawn_ray: file, hit and out must not be null"));
        };
        let surface = file.tracer().surface(&hit.to_hit());
        let surface = surface.map_err(|why| (BVHC_ERROR_ARGUMENT, format!("bvhc_spawn_ray: {why}")))?;
        let ray = surface.spawn(direction).map_err(|why| {
            (
                BVHC_ERROR_RAY,
                format!("bvhc_spawn_ray: direction {direction:?}: {why}; no ray leaves the surface along it"),
            )
        })?;
        *out = ray;
        Ok(BVHC_OK)
    })
}
