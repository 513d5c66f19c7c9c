//! From a hit or a record back to the source scene: `bvhc_hit_source_corners` (the source primitive, its
//! vertices and the hit's weights, for interpolating the scene's own attributes) and
//! `bvhc_triangle_source_vertices`.

use std::ffi::c_int;

use crate::boundary::{BVHC_ERROR_ARGUMENT, BVHC_ERROR_NOT_IN_FILE, BVHC_OK, BvhcFile, argument, file_ref, guarded};
use crate::records::{BvhcHit, BvhcSourceCorners};

/// Why `view` cannot give source vertices: it has no `source_vertices` section (or no ids), for `call`.
fn no_source_vertices(call: &str) -> (c_int, String) {
    let why = "the file has no source_vertices section (format 1.2; convert without --no-source-vertices or --no-ids)";
    (BVHC_ERROR_NOT_IN_FILE, format!("{call}: {why}"))
}

/// The source primitive, source vertices and weights of `*hit` (`BvhView::source_corners`), into `*out`:
/// interpolate a per-vertex attribute `A` of that primitive as `weights[0] A[vertices[0]] + weights[1]
/// A[vertices[1]] + weights[2] A[vertices[2]]`. For a hit through an instance, `node_index` and
/// `instance_index` name the instance's glTF node and `EXT_mesh_gpu_instancing` instance.
/// `BVHC_ERROR_ARGUMENT` for a hit that cannot be this file's (naming why); `BVHC_ERROR_NOT_IN_FILE` when the
/// file has no source vertices.
///
/// # Safety
///
/// `file` is null or a live file; `hit` null or a `bvhc_hit`; `out` null or writable storage for a
/// `bvhc_source_corners`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_hit_source_corners(
    file: *const BvhcFile,
    hit: *const BvhcHit,
    out: *mut BvhcSourceCorners,
) -> c_int {
    guarded(|| {
        let call = "bvhc_hit_source_corners";
        // SAFETY: by the contract each pointer is null or valid.
        let (file, hit, out) = unsafe { (file_ref(call, file)?, hit.as_ref(), out.as_mut()) };
        let (Some(hit), Some(out)) = (hit, out) else {
            return Err(argument("bvhc_hit_source_corners: hit and out must not be null"));
        };
        let hit = hit.to_hit();
        // The same test `bvhc_spawn_ray` makes: a hit is refused as foreign before the file's sections are asked.
        file.tracer().surface(&hit).map_err(|why| (BVHC_ERROR_ARGUMENT, format!("{call}: {why}")))?;
        let corners = file.view().source_corners(&hit).ok_or_else(|| no_source_vertices(call))?;
        *out = BvhcSourceCorners::from(&corners);
        Ok(BVHC_OK)
    })
}

/// The source vertices of record `triangle_index`'s `v0`, `v1`, `v2` in its source primitive into `vertices`
/// (three `uint32_t`); the primitive is the source range of the record's source id.
///
/// # Safety
///
/// `file` is null or a live file; `vertices` is null or points to three writable `uint32_t`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_triangle_source_vertices(
    file: *const BvhcFile,
    triangle_index: u32,
    vertices: *mut u32,
) -> c_int {
    guarded(|| {
        let call = "bvhc_triangle_source_vertices";
        // SAFETY: the caller's contract is `file_ref`'s.
        let file = unsafe { file_ref(call, file) }?;
        if vertices.is_null() {
            return Err(argument("bvhc_triangle_source_vertices: vertices must not be null"));
        }
        let view = file.view();
        let count = view.triangles().len();
        if triangle_index as usize >= count {
            let why = format!("{call}: triangle index {triangle_index} is not below the file's {count}");
            return Err((BVHC_ERROR_ARGUMENT, why));
        }
        let record = view.source_vertices().and_then(|all| all.get(triangle_index as usize));
        let record = record.ok_or_else(|| no_source_vertices(call))?;
        // SAFETY: not null, and by the contract it points to three writable `uint32_t`.
        unsafe { *(vertices as *mut [u32; 3]) = record.indices };
        Ok(BVHC_OK)
    })
}
