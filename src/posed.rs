//! A converted file's triangle records placed as a re-exported asset places them: the pipeline's fast path for
//! a moved pose (`bvhc refit FILE --positions MESH`). The asset is the one the file was converted from, exported
//! again with moved vertices and the same topology (PLY, OBJ or glTF); it is imported as the conversion imported
//! it (the file's recorded glTF scene, every placement flattened, degenerate triangles kept so that a triangle
//! flattened by the new pose still has its place), and each record takes the positions of the imported triangle
//! with its source id (the `triangle_ids` section), the same primitive and, where the file records them
//! (`source_vertices`), the same source vertices in the same corners. Anything else is a different topology,
//! refused naming the range, triangle or vertex.

use std::path::Path;

use bvhc_loader::BvhView;
use bvhc_loader::format::SourceRange;

use crate::import::{ImportError, ImportLimits, ImportOptions, Instancing, PoseSelector, SceneSelector, import};

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

/// The positions of `view`'s triangle records (one triangle a record, in record order) in `asset`, imported
/// under `limits`, in the asset's default pose or, with `pose`, as it stands at that time of one of its
/// animation clips (a glTF's): see the module documentation. A two-level file is refused (its meshes' records are in each
/// mesh's own space, not where the asset places them).
pub fn record_positions(
    view: &BvhView<'_>,
    asset: &Path,
    limits: &ImportLimits,
    pose: Option<&PoseSelector>,
) -> Result<Vec<[[f32; 3]; 3]>, PosedError> {
    if view.two_level().is_some() {
        return Err(PosedError::File(
            "the file is two-level (each mesh stored once in its own space, placed by instances), but the asset's \
             triangles are read as the scene places them: convert the moved asset again, or refit the meshes \
             through the library (BvhFile::refit, each mesh's records in its own space)"
                .into(),
        ));
    }
    let (Some(ids), Some(ranges)) = (view.triangle_ids(), view.source_table()) else {
        return Err(PosedError::File(
            "the file has no triangle ids (converted with --no-ids), so its records cannot be matched to the \
             asset's triangles"
                .into(),
        ));
    };
    let options = ImportOptions {
        scene: recorded_scene(view)?,
        keep_degenerate: true,
        limits: limits.clone(),
        instancing: Instancing::Never,
        pose: pose.cloned(),
        ..ImportOptions::default()
    };
    let soup = import(asset, &options).map_err(PosedError::Import)?.soup;
    same_ranges(ranges, &soup.sources)?;
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
    Ok(positions)
}

/// The glTF scene the conversion imported, from the metadata's `build.import.scene` (`None`: the default).
fn recorded_scene(view: &BvhView<'_>) -> Result<Option<SceneSelector>, PosedError> {
    let Some(text) = view.metadata_str() else { return Ok(None) };
    let unreadable = |why: String| PosedError::File(format!("the file's metadata cannot be read: {why}"));
    let metadata: serde_json::Value =
        serde_json::from_str(text.map_err(|v| unreadable(v.to_string()))?).map_err(|e| unreadable(e.to_string()))?;
    let scene = &metadata["build"]["import"]["scene"];
    Ok(if let Some(index) = scene["index"].as_u64() {
        Some(SceneSelector::Index(index as usize))
    } else {
        scene["name"].as_str().map(|name| SceneSelector::Name(name.to_string()))
    })
}

/// The file's source ranges and the asset's name the same primitives with the same triangle counts.
fn same_ranges(file: &[SourceRange], asset: &[SourceRange]) -> Result<(), PosedError> {
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
    if file.len() != asset.len() {
        return Err(PosedError::Topology(format!(
            "the file has {} source ranges (primitives placed), the asset {}",
            file.len(),
            asset.len()
        )));
    }
    match file.iter().zip(asset).position(|(a, b)| key(a) != key(b)) {
        None => Ok(()),
        Some(k) => Err(PosedError::Topology(format!(
            "source range {k} is {} in the file but {} in the asset",
            describe(&file[k]),
            describe(&asset[k])
        ))),
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
