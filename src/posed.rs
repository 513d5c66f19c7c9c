//! A converted file's triangle records placed as a re-exported asset places them: the pipeline's fast path for
//! a moved pose (`bvhc refit FILE --positions MESH`). The asset is the one the file was converted from, exported
//! again with moved vertices and the same topology (PLY, OBJ or glTF); it is imported as the conversion imported
//! it (the file's recorded glTF scene; a one-level file's placements flattened, a two-level file's meshes
//! instanced as its metadata records; degenerate triangles kept so that a triangle flattened by the new pose
//! still has its place), and each record takes the positions of the imported triangle with its source id (the
//! `triangle_ids` section), the same primitive and, where the file records them (`source_vertices`), the same
//! source vertices in the same corners; a two-level file's instances take their nodes' transforms
//! ([`placed_pose`]). Anything else is a different topology, refused naming the range, triangle or vertex.

use std::path::Path;

use bvhc_loader::format::{Affine3x4, NO_INDEX, SourceRange};
use bvhc_loader::{BvhFile, BvhView, BvhViewMut, RefitPositions, RefitReport, TwoLevelSections};

use crate::import::inputs::{InputEntry, input_entries};
use crate::import::{
    ImportError, ImportLimits, ImportOptions, InstancedMesh, Instancing, PoseSelector, SceneSelector, import,
};

/// Why an asset's positions cannot be given to a file's records.
#[derive(Debug)]
#[non_exhaustive]
pub enum PosedError {
    /// The asset cannot be imported.
    Import(ImportError),
    /// The file cannot name its records' triangles (no ids), or its metadata cannot be read.
    File(String),
    /// The asset's triangles are not the file's: another count, primitive or vertex (the message says where).
    Topology(String),
}

impl std::fmt::Display for PosedError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PosedError::Import(error) => write!(f, "{error}"),
            PosedError::File(why) => write!(f, "{why}"),
            PosedError::Topology(why) => write!(f, "the asset's topology differs from the file's: {why}"),
        }
    }
}

impl std::error::Error for PosedError {}

/// A converted file's records and instances as its asset places them in one pose ([`placed_pose`]).
#[derive(Clone, Debug, PartialEq)]
pub struct PlacedPose {
    /// Each triangle record's corners, in record order: a one-level file's in world space, a two-level file's in
    /// its mesh's own space (an instanced mesh's records keep their object-space positions).
    pub positions: Vec<[[f32; 3]; 3]>,
    /// A two-level file's instances that a glTF node places, each with the node's transform in the pose, in
    /// instance order (empty for a one-level file; the flattened mesh's identity instance is not among them).
    pub instances: Vec<(u32, Affine3x4)>,
    /// Every file the asset's import read, the asset first (a glTF's buffers after it): what a refit must not
    /// write over.
    pub files_read: Vec<std::path::PathBuf>,
    /// Where the positions came from, as a refit file's metadata records it ([`PlacedPose::rewritten`]).
    pub record: RefitRecord,
}

/// bvhc's metadata key `refit` (`format-spec/bvh-1.md` 5.5): the asset a refit file's records were posed from,
/// while the file's `inputs` and `build` still describe the conversion its tree was built for.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RefitRecord {
    /// The asset's files as a conversion records its inputs (names relative to the asset's folder, content
    /// hashes), the asset first.
    pub inputs: Vec<InputEntry>,
    /// The clip and time, absent for the asset's default pose.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pose: Option<PoseSelector>,
}

impl RefitRecord {
    /// `view` (refit to this record's pose) laid out anew as `BvhView::rewritten` lays it out (costs
    /// recomputed, checksums made, verified), its metadata recording the pose as the key `refit` (a `refit` the
    /// file had goes): what `bvhc refit` and Python's `Scene.write` after `Scene.pose` ship. A pose that is the
    /// conversion's own (the same files with the same hashes as `inputs`, and the pose of `build.import.pose`,
    /// or the default one where that is absent) records nothing, so a file refit back to its own asset has its
    /// converted bytes again.
    pub fn rewritten(&self, view: &BvhView<'_>) -> Result<BvhFile, bvhc_loader::Error> {
        let unwritable = |e: serde_json::Error| bvhc_loader::Error::Unwritable(format!("metadata refit: {e}"));
        let record = serde_json::to_value(self).map_err(unwritable)?;
        let converted: Option<serde_json::Value> =
            view.metadata_str().and_then(|text| text.ok()).and_then(|text| serde_json::from_str(text).ok());
        let own = converted.is_some_and(|metadata| {
            let null = serde_json::Value::Null;
            let pose = metadata.pointer("/build/import/pose").unwrap_or(&null);
            metadata.get("inputs") == record.get("inputs") && pose == record.get("pose").unwrap_or(&null)
        });
        // Members in the order the struct declares them (a `Value` would sort them).
        let text = serde_json::to_string(self).map_err(unwritable)?;
        view.rewritten_recording("refit", (!own).then_some(text.as_str()))
    }
}

impl PlacedPose {
    /// Refits `file` to the pose on `threads` threads. A one-level file: its records moved ([`BvhFile::refit`]). A
    /// two-level file: each mesh placed as it stands (the flattened geometry, which the pose deforms) refit to its
    /// records' positions ([`BvhFile::refit_mesh`]), and each instanced mesh only where its positions differ from
    /// the file's records (an asset exported with the shared mesh's vertices moved; the meshes an animation moves
    /// rigidly never differ, so their trees are left as they are and cost one comparison of their records), then
    /// the instances placed anew ([`BvhFile::move_instances_in_frame`], which refits the top trees). The checksums
    /// are left as a refit leaves them (`BvhFile::rewritten` makes a copy that verifies). Returns the refit's
    /// report (a two-level file's states no cost).
    pub fn apply(&self, file: &mut BvhFile, threads: usize) -> Result<RefitReport, bvhc_loader::Error> {
        self.apply_in_place(&mut file.view_mut(), threads)
    }

    /// `view` (refit to this pose by [`PlacedPose::apply`]) laid out anew, the pose recorded
    /// ([`RefitRecord::rewritten`]): what `bvhc refit` ships.
    pub fn rewritten(&self, view: &BvhView<'_>) -> Result<BvhFile, bvhc_loader::Error> {
        self.record.rewritten(view)
    }

    /// [`PlacedPose::apply`] on a file's bytes borrowed in place (a binding's writable array, a private map).
    pub fn apply_in_place(&self, file: &mut BvhViewMut<'_>, threads: usize) -> Result<RefitReport, bvhc_loader::Error> {
        let Some(sections) = file.view().two_level() else {
            return file.refit(RefitPositions::Triangles(&self.positions), threads);
        };
        let records = file.view().triangles();
        if self.positions.len() != records.len() {
            let (given, count) = (self.positions.len(), records.len());
            return Err(bvhc_loader::Error::Refit(format!("{given} positions for {count} triangle records")));
        }
        // The meshes placed by an instance that no node places hold the flattened geometry.
        let mut flattened = vec![false; sections.meshes.len()];
        for instance in sections.instances.iter().filter(|i| i.node_index == NO_INDEX) {
            if let Some(flag) = flattened.get_mut(instance.mesh_index as usize) {
                *flag = true;
            }
        }
        let mut moving: Vec<(u32, std::ops::Range<usize>)> = Vec::new();
        for (index, mesh) in sections.meshes.iter().enumerate() {
            let first = (mesh.first_triangle as usize).min(records.len());
            let range = first..first.saturating_add(mesh.triangle_count as usize).min(records.len());
            let differs = || {
                let given = &self.positions[range.clone()];
                records[range.clone()].iter().zip(given).any(|(r, p)| r.vertices != *p)
            };
            if flattened[index] || differs() {
                moving.push((index as u32, range));
            }
        }
        // Nothing moved but instances: no mesh refit, and no cost is stated.
        let mut report = RefitReport::default();
        for (mesh, range) in moving {
            report = file.refit_mesh(mesh, &self.positions[range], threads)?;
        }
        if !self.instances.is_empty() {
            file.move_instances_in_frame(&self.instances)?;
        }
        Ok(report)
    }
}

/// The positions of `view`'s triangle records (one triangle a record, in record order) in `asset`, imported
/// under `limits`, in the asset's default pose or, with `pose`, as it stands at that time of one of its
/// animation clips (a glTF's): see the module documentation. A two-level file is refused: its instances move
/// too, which [`placed_pose`] gives.
pub fn record_positions(
    view: &BvhView<'_>,
    asset: &Path,
    limits: &ImportLimits,
    pose: Option<&PoseSelector>,
) -> Result<Vec<[[f32; 3]; 3]>, PosedError> {
    if view.two_level().is_some() {
        return Err(PosedError::File(
            "the file is two-level (meshes in their own spaces, placed by instances): its pose is its records' \
             positions and its instances' transforms (bvhc::posed::placed_pose)"
                .into(),
        ));
    }
    Ok(placed_pose(view, asset, limits, pose)?.positions)
}

/// `view`'s records and instances as `asset` (imported under `limits`) places them in its default pose or, with
/// `pose`, at that time of one of its animation clips. The asset is imported as the conversion imported it:
/// its recorded scene, and for a two-level file its recorded instancing and the clips an animation's tree was
/// chosen for (which keep the meshes they move instanced), so that the same primitives are placed with the same
/// source ids; each record takes its triangle's positions, each instance that a glTF node places the node's
/// transform in the pose (matched by node and `EXT_mesh_gpu_instancing` instance). Refused, naming what differs:
/// another topology, an instance the asset does not place as one in that pose (a moving node whose transform
/// is singular there), a file without ids.
pub fn placed_pose(
    view: &BvhView<'_>,
    asset: &Path,
    limits: &ImportLimits,
    pose: Option<&PoseSelector>,
) -> Result<PlacedPose, PosedError> {
    let (Some(ids), Some(ranges)) = (view.triangle_ids(), view.source_table()) else {
        return Err(PosedError::File(
            "the file has no triangle ids (converted with --no-ids), so its records cannot be matched to the \
             asset's triangles"
                .into(),
        ));
    };
    let metadata = metadata(view)?;
    let two_level = view.two_level();
    let (instancing, moving_clips) = match two_level {
        None => (Instancing::Never, Vec::new()),
        Some(_) => recorded_instancing(&metadata)?,
    };
    let options = ImportOptions {
        scene: recorded_scene(&metadata),
        keep_degenerate: true,
        limits: limits.clone(),
        instancing,
        moving_clips,
        pose: pose.cloned(),
        ..ImportOptions::default()
    };
    let imported = import(asset, &options).map_err(PosedError::Import)?;
    let files_read = imported.files_read;
    let inputs = input_entries(asset, &files_read)
        .map_err(|e| PosedError::File(format!("{}: its files cannot be hashed: {e}", asset.display())))?;
    let record = RefitRecord { inputs, pose: pose.cloned() };
    let soup = imported.soup;
    same_ranges_as_file(ranges, &soup.sources)?;
    let id_count = ranges.last().map_or(0, |r| r.first_source_triangle as usize + r.source_triangle_count as usize);
    let mut triangle_of_id = vec![u32::MAX; id_count];
    for (triangle, &id) in soup.source_ids.iter().enumerate() {
        if let Some(slot) = triangle_of_id.get_mut(id as usize) {
            *slot = triangle as u32;
        }
    }
    let corners = view.source_vertices();
    let mut positions = Vec::with_capacity(ids.len());
    for (record, &id) in ids.iter().enumerate() {
        let triangle = triangle_of_id.get(id as usize).copied().filter(|&t| t != u32::MAX);
        let Some(triangle) = triangle.map(|t| t as usize) else {
            return Err(PosedError::Topology(format!("{}: triangle {id} is not in the asset", range_name(view, id))));
        };
        if let Some(corners) = corners {
            let (file, asset) = (corners[record].indices, soup.source_vertices[triangle]);
            if file != asset {
                return Err(PosedError::Topology(format!(
                    "{}: triangle {id} has the vertices {file:?} in the file but {asset:?} in the asset",
                    range_name(view, id)
                )));
            }
        }
        positions.push(soup.vertices(triangle));
    }
    let instances = match two_level {
        None => Vec::new(),
        Some(sections) => instance_transforms(&sections, &imported.instanced)?,
    };
    Ok(PlacedPose { positions, instances, files_read, record })
}

/// The transform in the pose of each of the file's instances that a glTF node places (`instanced`: the asset's
/// instanced meshes in the pose), by node and `EXT_mesh_gpu_instancing` instance.
fn instance_transforms(
    sections: &TwoLevelSections<'_>,
    instanced: &[InstancedMesh],
) -> Result<Vec<(u32, Affine3x4)>, PosedError> {
    let mut placed = std::collections::HashMap::new();
    for placement in instanced.iter().flat_map(|mesh| &mesh.placements) {
        placed.insert((placement.node_index, placement.gpu_instance_index), placement.object_to_world);
    }
    let mut transforms = Vec::new();
    for (index, instance) in sections.instances.iter().enumerate() {
        if instance.node_index == NO_INDEX {
            continue;
        }
        let key = (instance.node_index, instance.gpu_instance_index);
        let Some(&object_to_world) = placed.get(&key) else {
            return Err(PosedError::Topology(format!(
                "instance {index} (node {}) is not placed as an instance in the asset's pose (a transform \
                 singular there, or another scene)",
                instance.node_index
            )));
        };
        transforms.push((index as u32, object_to_world));
    }
    Ok(transforms)
}

/// The file's metadata as JSON (`Null` without a metadata section).
fn metadata(view: &BvhView<'_>) -> Result<serde_json::Value, PosedError> {
    let Some(text) = view.metadata_str() else { return Ok(serde_json::Value::Null) };
    let unreadable = |why: String| PosedError::File(format!("the file's metadata cannot be read: {why}"));
    serde_json::from_str(text.map_err(|v| unreadable(v.to_string()))?).map_err(|e| unreadable(e.to_string()))
}

/// The glTF scene the conversion imported, from the metadata's `build.import.scene` (`None`: the default).
fn recorded_scene(metadata: &serde_json::Value) -> Option<SceneSelector> {
    let scene = &metadata["build"]["import"]["scene"];
    if let Some(index) = scene["index"].as_u64() {
        Some(SceneSelector::Index(index as usize))
    } else {
        scene["name"].as_str().map(|name| SceneSelector::Name(name.to_string()))
    }
}

/// How a two-level file's conversion instanced: the metadata's `two_level.instancing`, and the clips of its
/// `animation` (which kept the meshes they move instanced).
fn recorded_instancing(metadata: &serde_json::Value) -> Result<(Instancing, Vec<usize>), PosedError> {
    let instancing = match metadata["two_level"]["instancing"].as_str() {
        Some("always") => Instancing::Always,
        Some("auto") => Instancing::Auto,
        other => {
            return Err(PosedError::File(format!(
                "the metadata's two_level.instancing is {other:?}, not 'auto' or 'always', so the asset cannot be \
                 imported as the conversion imported it"
            )));
        }
    };
    let clips = metadata["animation"]["clips"].as_array().map_or(&[][..], Vec::as_slice);
    let moving_clips = clips.iter().filter_map(|clip| clip["index"].as_u64()).map(|i| i as usize).collect();
    Ok((instancing, moving_clips))
}

/// The file's source ranges and the asset's name the same primitives with the same triangle counts.
fn same_ranges_as_file(file: &[SourceRange], asset: &[SourceRange]) -> Result<(), PosedError> {
    same_ranges(file, asset, ("the file", "the asset")).map_err(PosedError::Topology)
}

/// Whether two imports' source ranges (`first`, `second`, named `names` in messages) place the same primitives
/// (node, mesh, primitive, instance) with the same triangle counts and ids; else the first difference in words.
pub(crate) fn same_ranges(first: &[SourceRange], second: &[SourceRange], names: (&str, &str)) -> Result<(), String> {
    let key = |r: &SourceRange| {
        (
            r.first_source_triangle,
            r.source_triangle_count,
            r.node_index,
            r.mesh_index,
            r.primitive_index,
            r.instance_index,
        )
    };
    if first.len() != second.len() {
        return Err(format!(
            "{} has {} source ranges (primitives placed), {} {}",
            names.0,
            first.len(),
            names.1,
            second.len()
        ));
    }
    match first.iter().zip(second).position(|(a, b)| key(a) != key(b)) {
        None => Ok(()),
        Some(k) => Err(format!(
            "source range {k} is {} in {} but {} in {}",
            describe(&first[k]),
            names.0,
            describe(&second[k]),
            names.1
        )),
    }
}

/// A source range in words: its primitive and its triangle count.
fn describe(range: &SourceRange) -> String {
    let field = |name: &str, value: u32| {
        if value == bvhc_loader::format::NO_INDEX { String::new() } else { format!("{name} {value}, ") }
    };
    format!(
        "{}{}{}{}{} triangles from id {}",
        field("node", range.node_index),
        field("mesh", range.mesh_index),
        field("primitive", range.primitive_index),
        field("instance", range.instance_index),
        range.source_triangle_count,
        range.first_source_triangle
    )
}

/// "source range k (node n, mesh m, ...)" for the range holding `id`.
fn range_name(view: &BvhView<'_>, id: u32) -> String {
    let ranges = view.source_table().unwrap_or(&[]);
    let k = ranges.partition_point(|r| r.first_source_triangle <= id).saturating_sub(1);
    ranges.get(k).map_or(format!("source id {id}"), |r| format!("source range {k} ({})", describe(r)))
}
