//! What a file holds, for renderers that need more than hits: counts, the scene's bounds, a record's vertices
//! and source id, the meshes and instances of a two-level file (format 1.3) with their transforms, and the
//! metadata JSON.

use std::ffi::{c_char, c_int};

use crate::boundary::{
    BVHC_ERROR_ARGUMENT, BVHC_ERROR_NOT_IN_FILE, BVHC_OK, BvhcFile, argument, copy_text, file_ref, guarded,
};
use crate::records::{BvhcInstance, BvhcMesh};

/// An index out of range, for `call`.
fn out_of_range(call: &str, what: &str, index: u32, count: usize) -> (c_int, String) {
    (BVHC_ERROR_ARGUMENT, format!("{call}: {what} {index} is not below the file's {count}"))
}

/// The number of triangle records (0 for null). In a two-level file, the records of all meshes, each once.
///
/// # Safety
///
/// `file` is null or a live file.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_triangle_count(file: *const BvhcFile) -> usize {
    // SAFETY: by the contract `file` is null or live.
    unsafe { file.as_ref() }.map_or(0, |file| file.view().triangles().len())
}

/// The vertices `v0`, `v1`, `v2` of record `triangle_index` as nine floats (x, y, z of each) into `out`: in
/// world space in a one-level file, in its mesh's object space in a two-level one (map them by the hit
/// instance's `object_to_world`). The point a hit describes is `(1 - u - v) v0 + u v1 + v v2`.
///
/// # Safety
///
/// `file` is null or a live file; `out` is null or points to nine writable floats.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_triangle_vertices(file: *const BvhcFile, triangle_index: u32, out: *mut f32) -> c_int {
    guarded(|| {
        let call = "bvhc_triangle_vertices";
        // SAFETY: the caller's contract is `file_ref`'s.
        let file = unsafe { file_ref(call, file) }?;
        if out.is_null() {
            return Err(argument("bvhc_triangle_vertices: out must not be null"));
        }
        let triangles = file.view().triangles();
        let record = triangles.get(triangle_index as usize);
        let record = record.ok_or_else(|| out_of_range(call, "triangle index", triangle_index, triangles.len()))?;
        // SAFETY: `out` is not null and by the contract points to nine writable floats.
        unsafe { *(out as *mut [[f32; 3]; 3]) = record.vertices };
        Ok(BVHC_OK)
    })
}

/// The source id of record `triangle_index`, or `0xFFFFFFFF` when the file has none or the index is out of
/// range.
///
/// # Safety
///
/// `file` is null or a live file.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_source_id(file: *const BvhcFile, triangle_index: u32) -> u32 {
    // SAFETY: by the contract `file` is null or live.
    let Some(file) = (unsafe { file.as_ref() }) else { return u32::MAX };
    let view = file.view();
    view.triangle_ids().and_then(|ids| ids.get(triangle_index as usize).copied()).unwrap_or(u32::MAX)
}

/// The box of the whole scene in world space into `min` and `max` (three floats each): every ray that hits
/// something passes through it. `BVHC_ERROR_NOT_IN_FILE` for a file without triangles.
///
/// # Safety
///
/// `file` is null or a live file; `min` and `max` are null or point to three writable floats each.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_scene_bounds(file: *const BvhcFile, min: *mut f32, max: *mut f32) -> c_int {
    guarded(|| {
        // SAFETY: the caller's contract is `file_ref`'s.
        let file = unsafe { file_ref("bvhc_scene_bounds", file) }?;
        if min.is_null() || max.is_null() {
            return Err(argument("bvhc_scene_bounds: min and max must not be null"));
        }
        let (low, high) = file
            .view()
            .scene_box()
            .ok_or_else(|| (BVHC_ERROR_NOT_IN_FILE, "bvhc_scene_bounds: the file has no triangles".to_string()))?;
        // SAFETY: not null, and by the contract each points to three writable floats.
        unsafe {
            *(min as *mut [f32; 3]) = low;
            *(max as *mut [f32; 3]) = high;
        }
        Ok(BVHC_OK)
    })
}

/// The number of meshes of a two-level file; 0 for a one-level file (or null).
///
/// # Safety
///
/// `file` is null or a live file.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_mesh_count(file: *const BvhcFile) -> usize {
    // SAFETY: by the contract `file` is null or live.
    unsafe { file.as_ref() }.and_then(|file| file.view().two_level()).map_or(0, |sections| sections.meshes.len())
}

/// Mesh `mesh_index` of a two-level file (the range of triangle records it owns) into `*out`.
///
/// # Safety
///
/// `file` is null or a live file; `out` is null or writable storage for a `bvhc_mesh`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_get_mesh(file: *const BvhcFile, mesh_index: u32, out: *mut BvhcMesh) -> c_int {
    guarded(|| {
        let call = "bvhc_get_mesh";
        // SAFETY: the caller's contract is `file_ref`'s; `out` is null or writable.
        let (file, out) = (unsafe { file_ref(call, file) }?, unsafe { out.as_mut() });
        let out = out.ok_or_else(|| argument("bvhc_get_mesh: out must not be null"))?;
        let meshes = file.view().two_level().map_or(&[][..], |sections| sections.meshes);
        let mesh =
            meshes.get(mesh_index as usize).ok_or_else(|| out_of_range(call, "mesh", mesh_index, meshes.len()))?;
        *out = BvhcMesh { first_triangle: mesh.first_triangle, triangle_count: mesh.triangle_count };
        Ok(BVHC_OK)
    })
}

/// The number of instances of a two-level file; 0 for a one-level file (or null). A hit's `instance_index`
/// is below it.
///
/// # Safety
///
/// `file` is null or a live file.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_instance_count(file: *const BvhcFile) -> usize {
    // SAFETY: by the contract `file` is null or live.
    unsafe { file.as_ref() }.and_then(|file| file.view().two_level()).map_or(0, |sections| sections.instances.len())
}

/// Instance `instance_index` of a two-level file into `*out`: its object-to-world and world-to-object maps,
/// the mesh it places, and the glTF node and `EXT_mesh_gpu_instancing` instance it came from. A hit's normal
/// is already in world space; its record's vertices and a renderer's own object-space normals are mapped by
/// `object_to_world` (normals by the transpose of `world_to_object`'s 3x3 part).
///
/// # Safety
///
/// `file` is null or a live file; `out` is null or writable storage for a `bvhc_instance`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_get_instance(
    file: *const BvhcFile,
    instance_index: u32,
    out: *mut BvhcInstance,
) -> c_int {
    guarded(|| {
        let call = "bvhc_get_instance";
        // SAFETY: the caller's contract is `file_ref`'s; `out` is null or writable.
        let (file, out) = (unsafe { file_ref(call, file) }?, unsafe { out.as_mut() });
        let out = out.ok_or_else(|| argument("bvhc_get_instance: out must not be null"))?;
        let instances = file.view().two_level().map_or(&[][..], |sections| sections.instances);
        let instance = instances
            .get(instance_index as usize)
            .ok_or_else(|| out_of_range(call, "instance", instance_index, instances.len()))?;
        *out = *instance;
        Ok(BVHC_OK)
    })
}

/// Copies the file's metadata JSON (UTF-8, what `bvhc info --json` shows under `metadata`: inputs, options,
/// costs) into `buffer` as `snprintf` would (`capacity` bytes with the NUL, cut short when it does not fit) and
/// returns its full length without the NUL; 0 when the file has no metadata section (or for null). Call with
/// `capacity` 0 to ask the length.
///
/// # Safety
///
/// `file` is null or a live file; `buffer` is null or points to `capacity` writable bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_metadata_json(file: *const BvhcFile, buffer: *mut c_char, capacity: usize) -> usize {
    // SAFETY: by the contract `file` is null or live.
    let Some(file) = (unsafe { file.as_ref() }) else { return 0 };
    let json = file.view().metadata_bytes().unwrap_or_default();
    // SAFETY: the caller's contract is `copy_text`'s.
    unsafe { copy_text(json, buffer, capacity) }
}
