//! The file's arrays as plain C pointers (`bvhc_sections`), for look-ups a renderer makes per candidate hit or per
//! pixel: the header's `static inline` functions over them (`bvhc_sections_source_id`, `..._triangle_flags`,
//! `..._source_vertices`, `..._source_range`) are array reads and one binary search, with no call into the
//! library, where the exported getters cost a call, a panic guard and a view of the file each. And the source
//! range of a source id (`bvhc_source_range_of`): the glTF mesh and primitive, so the material, of a triangle.

use std::ffi::c_int;

use bvhc_loader::format::{PackedTriangle, SourceRange, SourceVertexIndices};

use crate::boundary::{BVHC_ERROR_ARGUMENT, BVHC_ERROR_NOT_IN_FILE, BVHC_OK, BvhcFile, argument, file_ref, guarded};

/// `bvhc_sections`: pointers into the open file's sections (valid until `bvhc_close`), null where the file has
/// no such section.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct BvhcSections {
    /// Triangle records (the `triangles` section).
    pub triangle_count: usize,
    /// Each record's `v0`, `v1`, `v2` (nine floats).
    pub triangles: *const PackedTriangle,
    /// Each record's source id (`triangle_ids`), or null.
    pub triangle_ids: *const u32,
    /// Each record's source vertices (`source_vertices`, format 1.2), or null.
    pub source_vertices: *const SourceVertexIndices,
    /// Each record's flags (`triangle_flags`, format 1.5; bit 0 not opaque), or null: every record opaque.
    pub triangle_flags: *const u8,
    /// Source ranges (the `source_table` section), ascending by `first_source_triangle`.
    pub source_range_count: usize,
    /// The ranges, or null.
    pub source_ranges: *const SourceRange,
}

/// Fills `*out` with pointers into `file`'s sections (`bvhc_sections`; they stay valid until `bvhc_close`).
///
/// # Safety
///
/// `file` is null or a live file; `out` null or writable storage for a `bvhc_sections`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_get_sections(file: *const BvhcFile, out: *mut BvhcSections) -> c_int {
    guarded(|| {
        let call = "bvhc_get_sections";
        // SAFETY: by the contract each pointer is null or valid.
        let (file, out) = unsafe { (file_ref(call, file)?, out.as_mut()) };
        let out = out.ok_or_else(|| argument("bvhc_get_sections: out must not be null"))?;
        let view = file.view();
        *out = BvhcSections {
            triangle_count: view.triangles().len(),
            triangles: view.triangles().as_ptr(),
            triangle_ids: view.triangle_ids().map_or(std::ptr::null(), <[_]>::as_ptr),
            source_vertices: view.source_vertices().map_or(std::ptr::null(), <[_]>::as_ptr),
            triangle_flags: view.triangle_flags().map_or(std::ptr::null(), <[_]>::as_ptr),
            source_range_count: view.source_table().map_or(0, <[_]>::len),
            source_ranges: view.source_table().map_or(std::ptr::null(), <[_]>::as_ptr),
        };
        Ok(BVHC_OK)
    })
}

/// The source range that holds `source_triangle_id` (its file, glTF node, mesh, primitive and
/// `EXT_mesh_gpu_instancing` instance) into `*out`, found in O(log ranges). `BVHC_ERROR_NOT_IN_FILE` for a file
/// without a source table; `BVHC_ERROR_ARGUMENT` for an id no range holds.
///
/// # Safety
///
/// `file` is null or a live file; `out` null or writable storage for a `bvhc_source_range`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_source_range_of(
    file: *const BvhcFile,
    source_triangle_id: u32,
    out: *mut SourceRange,
) -> c_int {
    guarded(|| {
        let call = "bvhc_source_range_of";
        // SAFETY: by the contract each pointer is null or valid.
        let (file, out) = unsafe { (file_ref(call, file)?, out.as_mut()) };
        let out = out.ok_or_else(|| argument("bvhc_source_range_of: out must not be null"))?;
        let view = file.view();
        if view.source_table().is_none() {
            let why = format!("{call}: the file has no source table (convert without --no-ids)");
            return Err((BVHC_ERROR_NOT_IN_FILE, why));
        }
        let range = view.source_range_of(source_triangle_id).ok_or_else(|| {
            (BVHC_ERROR_ARGUMENT, format!("{call}: no source range holds source id {source_triangle_id}"))
        })?;
        *out = *range;
        Ok(BVHC_OK)
    })
}
