//! The C API of `bvhc-loader` (`include/bvhc.h`): open a `.bvh` file from a path or from memory, verify it,
//! trace closest-hit and any-hit rays one at a time or in batches (with the same hit records as Rust), spawn
//! secondary rays, run hit filters (alpha testing) on the triangles the file marks not opaque, go from a hit
//! back to the source scene, and read what the file holds: bounds, records, the meshes and instances of a
//! two-level file, the metadata; refit a file to moved triangles, move its instances, and write it back.
//!
//! Contract at the boundary: no Rust panic crosses it (every entry point runs under `catch_unwind` and reports
//! `BVHC_ERROR_PANIC`); null pointers, indices out of range and hits that are not the file's are argument
//! errors, never crashes; rays are checked against the ray contract (`BVHC_ERROR_RAY`, naming the ray and the
//! rule) except by the `_unchecked` calls; the message of the last error is per thread and stays valid until
//! the next failing call on it (`bvhc_last_error_message`, or copied with `bvhc_error_message`); every status
//! has a name (`bvhc_status_name`). A `bvhc_file` changes only through the refit calls (`bvhc_refit_triangles`,
//! `bvhc_refit_source_vertices`, `bvhc_refit_mesh`, `bvhc_move_instances`, `bvhc_move_instances_in_frame`,
//! `bvhc_rebuild_top_trees`); otherwise any number of threads may trace through one at
//! the same time; only `bvhc_close` and the refit calls must not race with them.

mod batch;
mod boundary;
mod filtered;
mod filtered_batch;
mod open;
mod points;
mod records;
mod refit;
mod scene;
mod sections;
mod single;
mod source;

pub use batch::{
    BVHC_RAYS_COHERENT, BVHC_RAYS_UNCHECKED, bvhc_any_hits, bvhc_any_hits_coherent, bvhc_any_hits_coherent_unchecked,
    bvhc_any_hits_unchecked, bvhc_closest_hit_columns, bvhc_closest_hits, bvhc_closest_hits_coherent,
    bvhc_closest_hits_coherent_unchecked, bvhc_closest_hits_unchecked,
};
pub use boundary::{
    BVHC_ERROR_ARGUMENT, BVHC_ERROR_INVALID, BVHC_ERROR_IO, BVHC_ERROR_MEMORY, BVHC_ERROR_NOT_IN_FILE,
    BVHC_ERROR_PANIC, BVHC_ERROR_RAY, BVHC_OK, BvhcFile, bvhc_error_message, bvhc_last_error_message, bvhc_status_name,
};
pub use filtered::{
    BVHC_FILTER_EVERY, BVHC_FILTER_NOT_OPAQUE, BvhcCandidate, BvhcFilter, bvhc_any_hit_filtered,
    bvhc_closest_hit_filtered, bvhc_triangle_flags,
};
pub use filtered_batch::{
    bvhc_any_hits_filtered, bvhc_any_hits_filtered_threads, bvhc_closest_hits_filtered,
    bvhc_closest_hits_filtered_threads,
};
pub use open::{bvhc_close, bvhc_open, bvhc_open_memory, bvhc_verify};
pub use points::{
    BvhcNearestPoint, BvhcPointFilter, bvhc_closest_point, bvhc_closest_points, bvhc_closest_points_filtered,
    bvhc_signed_distances, bvhc_winding_numbers,
};
pub use records::{BvhcHit, BvhcInstance, BvhcMesh, BvhcRay, BvhcSourceCorners};
pub use refit::{
    BvhcRefitReport, bvhc_move_instances, bvhc_move_instances_in_frame, bvhc_planned_cost_ratio,
    bvhc_rebuild_top_trees, bvhc_refit_mesh, bvhc_refit_source_vertices, bvhc_refit_triangles, bvhc_top_tree_cost,
    bvhc_write,
};
pub use scene::{
    bvhc_get_instance, bvhc_get_mesh, bvhc_instance_count, bvhc_mesh_count, bvhc_metadata_json, bvhc_scene_bounds,
    bvhc_source_id, bvhc_triangle_count, bvhc_triangle_vertices,
};
pub use sections::{BvhcSections, bvhc_get_sections, bvhc_source_range_of};
pub use single::{
    bvhc_any_hit, bvhc_any_hit_unchecked, bvhc_check_rays, bvhc_closest_hit, bvhc_closest_hit_unchecked, bvhc_spawn_ray,
};
pub use source::{bvhc_hit_source_corners, bvhc_triangle_source_vertices};
