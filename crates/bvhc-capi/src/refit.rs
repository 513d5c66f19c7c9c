//! Moving geometry from C: refitting an open file to moved triangles (`bvhc_refit_triangles`, per record;
//! `bvhc_refit_source_vertices`, per source vertex of each primitive), moving instances of a two-level file
//! (`bvhc_move_instances`; per frame `bvhc_refit_mesh` and `bvhc_move_instances_in_frame`), rebuilding a moved file's top trees (`bvhc_rebuild_top_trees`, `bvhc_top_tree_cost`),
//! and writing the result (`bvhc_write`, its costs and checksums recomputed so that it verifies).
//! These change the file: they must not race with any other call on it (as `bvhc_close` must not); each makes
//! the file's tracer again, so the next trace sees the new geometry.

use std::ffi::{CStr, c_char, c_int, c_uint};

use bvhc_loader::format::Affine3x4;
use bvhc_loader::{RefitPositions, RefitReport};

use crate::boundary::{BVHC_ERROR_NOT_IN_FILE, BVHC_OK, BvhcFile, argument, guarded, status_of};

/// `bvhc_refit_report`: the refit tree's costs beside the costs the file states, NaN where the file states none
/// (no metadata, or no wide sections for the wide cost); `cost_ratio` is 1 then.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BvhcRefitReport {
    /// The binary tree's SAH cost now (`format-spec/bvh-1.md` 5.6).
    pub cost: f64,
    /// The binary tree's SAH cost the metadata states.
    pub file_cost: f64,
    /// The wide tree's cost now (6.1).
    pub wide_cost: f64,
    /// The wide tree's cost the metadata states.
    pub file_wide_cost: f64,
    /// `RefitReport::cost_ratio`: the wide tree's cost over the stated one where both exist, else the binary
    /// tree's; what a rebuild policy compares with a threshold.
    pub cost_ratio: f64,
}

impl From<&RefitReport> for BvhcRefitReport {
    fn from(report: &RefitReport) -> BvhcRefitReport {
        BvhcRefitReport {
            cost: report.cost.unwrap_or(f64::NAN),
            file_cost: report.file_cost.unwrap_or(f64::NAN),
            wide_cost: report.wide_cost.unwrap_or(f64::NAN),
            file_wide_cost: report.file_wide_cost.unwrap_or(f64::NAN),
            cost_ratio: report.cost_ratio(),
        }
    }
}

/// The file behind `file` for a change, or an argument error naming `call`.
///
/// # Safety
///
/// `file` is null or a live file that no other call uses now.
unsafe fn file_mut<'f>(call: &str, file: *mut BvhcFile) -> Result<&'f mut BvhcFile, (c_int, String)> {
    // SAFETY: by the contract `file` is null or live and not shared during the call; `as_mut` checks null.
    unsafe { file.as_mut() }.ok_or_else(|| argument(&format!("{call}: file is null")))
}

/// Refits with `positions` on `threads` threads and writes the report where asked.
fn refit(
    call: &str,
    file: &mut BvhcFile,
    positions: RefitPositions<'_>,
    threads: c_uint,
    report: Option<&mut BvhcRefitReport>,
) -> Result<c_int, (c_int, String)> {
    let result = file.traced.edit_file(|file| file.refit(positions, threads as usize));
    let done = result.map_err(|e| (status_of(&e), format!("{call}: {e}")))?;
    if let Some(report) = report {
        *report = BvhcRefitReport::from(&done);
    }
    Ok(BVHC_OK)
}

/// Moves every triangle record to `positions` (9 floats a record: `v0`, `v1`, `v2` as `bvhc_triangle_vertices`
/// gives them, in record order; `triangle_count` records, the file's count) and refits the file's layouts on up
/// to `threads` threads (0 or 1: the calling thread alone), the same result for any count. `report`, when not
/// null, receives the refit tree's costs. A file with split references refits each reference to its whole
/// triangle (correct, looser: convert meshes meant to deform with `--no-splits-deforming`); in a two-level file
/// the records are each mesh's, in its own space, and every instance follows its mesh. Refused, with the file
/// unchanged: another count, a coordinate that is not finite, a split triangle's references given different
/// positions (the message names the records), an instance whose moved mesh no longer fits f32.
///
/// # Safety
///
/// `file` is null or a live file no other call uses now; `positions` is null or points to `9 * triangle_count`
/// readable floats; `report` is null or writable storage for a `bvhc_refit_report`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_refit_triangles(
    file: *mut BvhcFile,
    positions: *const f32,
    triangle_count: usize,
    threads: c_uint,
    report: *mut BvhcRefitReport,
) -> c_int {
    guarded(|| {
        let call = "bvhc_refit_triangles";
        // SAFETY: the caller's contract is `file_mut`'s; `report` is null or writable.
        let (file, report) = (unsafe { file_mut(call, file) }?, unsafe { report.as_mut() });
        if positions.is_null() {
            return Err(argument("bvhc_refit_triangles: positions must not be null"));
        }
        let len = triangle_count.checked_mul(9).ok_or_else(|| argument("bvhc_refit_triangles: count too large"))?;
        // SAFETY: `positions` is not null and, by the contract, points to `9 * triangle_count` readable floats,
        // unchanged during the call.
        let floats = unsafe { std::slice::from_raw_parts(positions, len) };
        // Read in place: 9 floats a record are three vertices of three floats.
        let triangles = floats.as_chunks::<3>().0.as_chunks::<3>().0;
        refit(call, file, RefitPositions::Triangles(triangles), threads, report)
    })
}

/// Moves the records to new positions per source vertex and refits, as `bvhc_refit_triangles` does: for each
/// of the file's `range_count` source ranges (`bvhc_get_sections`' source table, in order), `positions[r]`
/// points to `3 * vertex_counts[r]` floats, the positions of that primitive's vertices indexed as the source
/// primitive indexes them (`bvhc_triangle_source_vertices`), in the file's space (world space after the glTF
/// node's transform: what skinning produces), or is null to leave that range's records where they are.
/// Refused, with the file unchanged: a file without source vertices, another range count, a vertex index past
/// its range's count, a coordinate that is not finite (the message names the range and vertex).
///
/// # Safety
///
/// `file` is null or a live file no other call uses now; `positions` and `vertex_counts` are null or point to
/// `range_count` readable entries, each `positions[r]` null or pointing to `3 * vertex_counts[r]` readable
/// floats; `report` is null or writable storage for a `bvhc_refit_report`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_refit_source_vertices(
    file: *mut BvhcFile,
    positions: *const *const f32,
    vertex_counts: *const usize,
    range_count: usize,
    threads: c_uint,
    report: *mut BvhcRefitReport,
) -> c_int {
    guarded(|| {
        let call = "bvhc_refit_source_vertices";
        // SAFETY: the caller's contract is `file_mut`'s; `report` is null or writable.
        let (file, report) = (unsafe { file_mut(call, file) }?, unsafe { report.as_mut() });
        if positions.is_null() || vertex_counts.is_null() {
            return Err(argument("bvhc_refit_source_vertices: positions and vertex_counts must not be null"));
        }
        // SAFETY: both are non-null and, by the contract, point to `range_count` readable entries.
        let (pointers, counts) = unsafe {
            (std::slice::from_raw_parts(positions, range_count), std::slice::from_raw_parts(vertex_counts, range_count))
        };
        let mut ranges: Vec<Option<&[[f32; 3]]>> = Vec::with_capacity(range_count);
        for (&pointer, &count) in pointers.iter().zip(counts) {
            ranges.push(if pointer.is_null() {
                None
            } else {
                let len =
                    count.checked_mul(3).ok_or_else(|| argument("bvhc_refit_source_vertices: count too large"))?;
                // SAFETY: `pointer` is not null and, by the contract, points to `3 * count` readable floats.
                let floats = unsafe { std::slice::from_raw_parts(pointer, len) };
                Some(floats.as_chunks::<3>().0)
            });
        }
        refit(call, file, RefitPositions::SourceVertices(&ranges), threads, report)
    })
}

/// Places the `count` instances named by `instances` anew, each by the 3x4 row-major object-to-world map at
/// `transforms + 12 k` (rows `[a b c d]`: `p'_i = a p_x + b p_y + c p_z + d`, as `bvhc_instance` stores them):
/// the inverse and world box computed as the converter computes them, the top trees refit, the checksums
/// recomputed (so `bvhc_verify` passes). Refused, with the file unchanged: a one-level file, an index out of
/// range, a map that is not finite and invertible (rule V42) or whose world box does not fit f32, naming the
/// instance.
///
/// # Safety
///
/// `file` is null or a live file no other call uses now; `instances` and `transforms` are null or point to
/// `count` indices and `12 * count` floats.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_move_instances(
    file: *mut BvhcFile,
    instances: *const u32,
    transforms: *const f32,
    count: usize,
) -> c_int {
    // SAFETY: the caller's contract is `move_instances`'.
    guarded(|| unsafe { move_instances("bvhc_move_instances", file, instances, transforms, count, true) })
}

/// `bvhc_move_instances` for a frame: the same moves and refusals, the checksums left as a refit leaves them
/// (hashing a large file's sections costs more than moving its instances; `bvhc_write` recomputes them, and
/// `bvhc_verify` fails until then), so a frame that moves instances costs the moves and the top trees' refit.
///
/// # Safety
///
/// As `bvhc_move_instances`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_move_instances_in_frame(
    file: *mut BvhcFile,
    instances: *const u32,
    transforms: *const f32,
    count: usize,
) -> c_int {
    // SAFETY: the caller's contract is `move_instances`'.
    guarded(|| unsafe { move_instances("bvhc_move_instances_in_frame", file, instances, transforms, count, false) })
}

/// The instances named by `instances` placed by `transforms` (see `bvhc_move_instances`), the checksums
/// recomputed when `checksums`; errors name `call`.
///
/// # Safety
///
/// `file` is null or a live file no other call uses now; `instances` and `transforms` are null or point to
/// `count` indices and `12 * count` floats.
unsafe fn move_instances(
    call: &str,
    file: *mut BvhcFile,
    instances: *const u32,
    transforms: *const f32,
    count: usize,
    checksums: bool,
) -> Result<c_int, (c_int, String)> {
    // SAFETY: the caller's contract is `file_mut`'s.
    let file = unsafe { file_mut(call, file) }?;
    if count > 0 && (instances.is_null() || transforms.is_null()) {
        return Err(argument(&format!("{call}: instances and transforms must not be null")));
    }
    let len = count.checked_mul(12).ok_or_else(|| argument(&format!("{call}: count too large")))?;
    let (indices, floats) = if count == 0 {
        (&[][..], &[][..])
    } else {
        // SAFETY: both are non-null and, by the contract, point to `count` indices and `12 * count` floats.
        unsafe { (std::slice::from_raw_parts(instances, count), std::slice::from_raw_parts(transforms, len)) }
    };
    let maps: &[Affine3x4] = floats.as_chunks::<4>().0.as_chunks::<3>().0;
    let moves: Vec<(u32, Affine3x4)> = indices.iter().copied().zip(maps.iter().copied()).collect();
    let result = file.traced.edit_file(|file| match checksums {
        true => file.move_instances(&moves),
        false => file.move_instances_in_frame(&moves),
    });
    result.map_err(|e| (status_of(&e), format!("{call}: {e}")))?;
    Ok(BVHC_OK)
}

/// Moves the records of mesh `mesh` of a two-level file to `positions` (9 floats a record, `v0`, `v1`, `v2` in
/// the mesh's own space and record order: `bvhc_get_mesh`'s `first_triangle` .. `+ triangle_count`; the file's
/// `triangle_count` records of that mesh) and refits that mesh's trees, its instances' world boxes and the top
/// trees on up to `threads` threads, leaving every other mesh untouched: a frame's work is the deforming mesh's,
/// whatever rigid meshes (moved by `bvhc_move_instances_in_frame`) the file holds. The checksums are left as a
/// refit leaves them. Refused, with the file unchanged: a one-level file (`bvhc_refit_triangles` refits it
/// whole), a mesh that does not exist, another count, a coordinate that is not finite, an instance whose world
/// box would not fit f32, each named.
///
/// # Safety
///
/// `file` is null or a live file no other call uses now; `positions` is null or points to `9 * triangle_count`
/// readable floats.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_refit_mesh(
    file: *mut BvhcFile,
    mesh: u32,
    positions: *const f32,
    triangle_count: usize,
    threads: c_uint,
) -> c_int {
    guarded(|| {
        let call = "bvhc_refit_mesh";
        // SAFETY: the caller's contract is `file_mut`'s.
        let file = unsafe { file_mut(call, file) }?;
        if positions.is_null() {
            return Err(argument("bvhc_refit_mesh: positions must not be null"));
        }
        let len = triangle_count.checked_mul(9).ok_or_else(|| argument("bvhc_refit_mesh: count too large"))?;
        // SAFETY: `positions` is not null and, by the contract, points to `9 * triangle_count` readable floats,
        // unchanged during the call.
        let floats = unsafe { std::slice::from_raw_parts(positions, len) };
        let triangles = floats.as_chunks::<3>().0.as_chunks::<3>().0;
        let result = file.traced.edit_file(|file| file.refit_mesh(mesh, triangles, threads as usize));
        result.map_err(|e| (status_of(&e), format!("{call}: {e}")))?;
        Ok(BVHC_OK)
    })
}

/// Builds both top trees of a two-level file anew over its instances as they now stand (after large moves, when
/// [`bvhc_top_tree_cost`] says the refit trees cost more), by the converter's builder
/// (`BvhView::rebuilt_top_trees`): the file's bytes are replaced by the rebuilt file's, so pointers from
/// `bvhc_get_sections` must be fetched again. Refused, with the file unchanged: a one-level file, a world box that
/// does not fit f32 (naming the instance).
///
/// # Safety
///
/// `file` is null or a live file no other call uses now.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_rebuild_top_trees(file: *mut BvhcFile) -> c_int {
    guarded(|| {
        let call = "bvhc_rebuild_top_trees";
        // SAFETY: the caller's contract is `file_mut`'s.
        let file = unsafe { file_mut(call, file) }?;
        let rebuilt = file.traced.file().rebuilt_top_trees().map_err(|e| (status_of(&e), format!("{call}: {e}")))?;
        file.traced.edit_file(|file| *file = rebuilt);
        Ok(BVHC_OK)
    })
}

/// Writes to `cost` the SAH cost of a two-level file's binary top tree (`BvhView::top_tree_cost`: the nodes'
/// areas over the root's, each instance counted as one), to compare a refit top tree with a rebuilt one.
/// `BVHC_ERROR_NOT_IN_FILE` for a one-level file.
///
/// # Safety
///
/// `file` is null or a live file; `cost` is null or points to a writable double.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_top_tree_cost(file: *const BvhcFile, cost: *mut f64) -> c_int {
    guarded(|| {
        let call = "bvhc_top_tree_cost";
        // SAFETY: by the contract `file` is null or live, `cost` null or writable.
        let (file, cost) = unsafe { (file.as_ref(), cost.as_mut()) };
        let (Some(file), Some(cost)) = (file, cost) else {
            return Err(argument(&format!("{call}: file and cost must not be null")));
        };
        let Some(value) = file.traced.view().top_tree_cost() else {
            return Err((BVHC_ERROR_NOT_IN_FILE, format!("{call}: a one-level file has no top tree")));
        };
        *cost = value;
        Ok(BVHC_OK)
    })
}

/// Writes to `ratio` the largest refit cost ratio a tree chosen for an animation reaches at the poses it was
/// chosen for (`BvhView::planned_cost_ratio`: the metadata's pose costs over the cost the file states), what a
/// rebuild policy's threshold multiplies. `BVHC_ERROR_NOT_IN_FILE` for a file converted without `--animation`.
///
/// # Safety
///
/// `file` is null or a live file; `ratio` is null or points to a writable double.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_planned_cost_ratio(file: *const BvhcFile, ratio: *mut f64) -> c_int {
    guarded(|| {
        let call = "bvhc_planned_cost_ratio";
        // SAFETY: by the contract `file` is null or live, `ratio` null or writable.
        let (file, ratio) = unsafe { (file.as_ref(), ratio.as_mut()) };
        let (Some(file), Some(ratio)) = (file, ratio) else {
            return Err(argument(&format!("{call}: file and ratio must not be null")));
        };
        let Some(value) = file.traced.view().planned_cost_ratio() else {
            return Err((BVHC_ERROR_NOT_IN_FILE, format!("{call}: the file was not converted with --animation")));
        };
        *ratio = value;
        Ok(BVHC_OK)
    })
}

/// Writes the file to the NUL-terminated UTF-8 `path`, atomically (a temporary file renamed over it), with the
/// costs its metadata states recomputed from its sections, so that a refit or moved file passes `bvhc verify`:
/// how a baker ships a posed file.
///
/// # Safety
///
/// `file` is null or a live file; `path` is null or a NUL-terminated string.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn bvhc_write(file: *const BvhcFile, path: *const c_char) -> c_int {
    guarded(|| {
        let call = "bvhc_write";
        // SAFETY: by the contract `file` is null or live.
        let file = unsafe { file.as_ref() }.ok_or_else(|| argument(&format!("{call}: file is null")))?;
        if path.is_null() {
            return Err(argument("bvhc_write: path must not be null"));
        }
        // SAFETY: `path` is not null and, by the contract, NUL-terminated.
        let path =
            unsafe { CStr::from_ptr(path) }.to_str().map_err(|_| argument("bvhc_write: the path is not UTF-8"))?;
        let written = file
            .traced
            .file()
            .rewritten()
            .and_then(|shipped| bvhc_loader::write::write_atomic(std::path::Path::new(path), shipped.as_bytes()));
        written.map_err(|e| (status_of(&e), format!("{call}: {e}")))?;
        Ok(BVHC_OK)
    })
}
