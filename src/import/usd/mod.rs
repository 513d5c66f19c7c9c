//! OpenUSD stages (`.usd`, `.usda`, `.usdc`, `.usdz`) as triangles, composed by the `openusd` crate: sublayers,
//! references, payloads (all loaded), variant selections as authored, inherits and specializes. What USD's
//! renderers draw is imported: `UsdGeomMesh` prims that are active, defined and visible, of the purposes asked
//! for (`default` and `render` unless told otherwise), placed by their `Xformable` ancestors
//! ([`xform`]), triangulated as Hydra triangulates them ([`mesh`]); native instances (instanceable prims) and
//! `PointInstancer` placements are expanded, or kept as instances of their prototype under the import's
//! [`Instancing`](super::Instancing) policy ([`walk`]). A layer that cannot be composed is refused with the layer
//! and the prim that referenced it, except MaterialX documents (`.mtlx`), which hold materials only: those are
//! listed in the stage's record ([`StageRecord::unread_material_layers`]) instead.

mod emit;
mod mesh;
mod resolver;
mod skel;
mod walk;
mod xform;

use std::cell::RefCell;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::rc::Rc;

use openusd::pcp;
use openusd::sdf::Value;
use openusd::usd::{PrimPredicate, Stage, TimeCode};

use super::instancing::InstancedMesh;
use super::soup::SoupBuilder;
use super::{ErrorKind, ImportOptions, Located};

/// What a conversion records about a USD stage (the metadata's `usd` object): the prim paths that source ranges
/// and instances name, the stage's units, and what was not read.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct StageRecord {
    /// Prim paths; a source range's `node_index` and `mesh_index` and an instance's node index count in it.
    pub prims: Vec<String>,
    /// The stage's `metersPerUnit`, where authored (recorded, not applied).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub meters_per_unit: Option<f64>,
    /// The stage's `upAxis`, where authored (recorded, not applied).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub up_axis: Option<String>,
    /// MaterialX documents that references named and that were not read (they hold materials, never geometry),
    /// relative to the stage's folder.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub unread_material_layers: Vec<String>,
}

/// Imports the stage at `path`: its triangles into `builder`, the meshes kept instanced, every file read, and
/// the stage's record.
pub(super) fn read(
    path: &Path,
    options: &ImportOptions,
    builder: &mut SoupBuilder,
) -> Result<(Vec<PathBuf>, Vec<InstancedMesh>, StageRecord), Located> {
    let (stage, opened, canonical) = open_stage(path, options)?;
    let mut paths = Vec::new();
    guarded("stage", || {
        stage
            .traverse(PrimPredicate::DEFAULT_PROXIES, |p| paths.push(p.clone()))
            .map_err(|e| Located::new("stage", format!("{e:#}")))
    })?;
    let mut record = StageRecord::default();
    check_composition(&stage, &canonical, &mut record)?;
    let time_code = match &options.pose {
        Some(pose) => Some(clip_time_code(&stage, pose)?),
        None => options.time_code,
    };
    if let Some(code) = time_code
        && !code.is_finite()
    {
        return Err(Located::new("pose", format!("time code {code} is not finite")));
    }
    let time = time_code.map(TimeCode::new);
    record.meters_per_unit = match stage.stage_metadata("metersPerUnit") {
        Ok(Some(Value::Double(m))) => Some(m),
        Ok(Some(Value::Float(m))) => Some(f64::from(m)),
        _ => None,
    };
    record.up_axis = match stage.stage_metadata("upAxis") {
        Ok(Some(Value::Token(t))) => Some(t.as_str().to_string()),
        Ok(Some(Value::String(s))) => Some(s),
        _ => None,
    };
    let scene = guarded("stage", || walk::collect(&stage, &paths, time, options))?;
    let instanced = guarded("stage", || emit::emit(&stage, &scene, time, options, builder, &mut record))?;
    let files = opened.borrow().files.clone();
    let files_read = files.iter().filter(|f| **f != canonical).map(|f| respelled(f, &canonical, path)).collect();
    Ok((files_read, instanced, record))
}

/// Opens the stage at `path` through a [`resolver::BoundedResolver`]; returns it, what the resolver opened, and
/// the stage's canonical path, which the resolver's paths are spelled from (it resolves each layer to its
/// canonical path, so a stage reached through a symbolic link or `..` is opened by its canonical path too).
fn open_stage(
    path: &Path,
    options: &ImportOptions,
) -> Result<(Stage, Rc<RefCell<resolver::Opened>>, PathBuf), Located> {
    let canonical =
        std::fs::canonicalize(path).map_err(|e| Located::of_kind(ErrorKind::Unreadable, "file", e.to_string()))?;
    let root = canonical.to_str().ok_or_else(|| Located::new("file name", "is not UTF-8".to_string()))?;
    let (resolver, opened) = resolver::BoundedResolver::new(options.limits.max_input_bytes);
    let stage = guarded("stage", || {
        Stage::builder().resolver(resolver).open(root).map_err(|e| Located::new("stage", format!("{e:#}")))
    })?;
    Ok((stage, opened, canonical))
}

/// `file`, a layer's canonical path, spelled from the folder of `given` (the stage's path as the caller spelled
/// it) as it lies from the folder of `canonical` (the stage's canonical path): the names the metadata records are
/// then the same however the stage's path was spelled.
fn respelled(file: &Path, canonical: &Path, given: &Path) -> PathBuf {
    let canonical_folder = canonical.parent().unwrap_or(Path::new("/"));
    let given_folder = given.parent().unwrap_or(Path::new(""));
    let shared = canonical_folder.components().zip(file.components()).take_while(|(a, b)| a == b).count();
    let ups = canonical_folder.components().count() - shared;
    let mut spelled = given_folder.to_path_buf();
    spelled.extend(std::iter::repeat_n(Path::new(".."), ups));
    spelled.extend(file.components().skip(shared));
    spelled
}

/// The name of a stage's one animation clip: its authored time codes, from `startTimeCode` to `endTimeCode`, a
/// time in it in seconds being the time code over `timeCodesPerSecond`.
pub const TIME_CODES_CLIP: &str = "time codes";

/// The stage's animation clips: [`TIME_CODES_CLIP`] where it authors a time range, else none.
pub(super) fn clips(path: &Path, options: &ImportOptions) -> Result<Vec<super::ClipSpan>, Located> {
    let (stage, _, _) = open_stage(path, options)?;
    let rate = stage.time_codes_per_second();
    let (start, end) = (stage.start_time_code(), stage.end_time_code());
    let authored = stage.has_authored_time_code_range();
    if !(authored && rate > 0.0 && start.is_finite() && end.is_finite() && start <= end) {
        return Ok(Vec::new());
    }
    Ok(vec![super::ClipSpan {
        index: 0,
        name: Some(TIME_CODES_CLIP.to_string()),
        start: start / rate,
        end: end / rate,
    }])
}

/// The time code of a clip time on a stage: its one clip ([`TIME_CODES_CLIP`], index 0) at `seconds` is time code
/// `seconds * timeCodesPerSecond`.
fn clip_time_code(stage: &Stage, pose: &super::PoseSelector) -> Result<f64, Located> {
    match &pose.clip {
        super::ClipSelector::Index(0) => {}
        super::ClipSelector::Name(name) if name == TIME_CODES_CLIP => {}
        other => {
            let message = format!(
                "an OpenUSD stage has one clip, its time codes (0 or \"{TIME_CODES_CLIP}\"), not {other:?}; or pose it \
                 at a time code (--pose TIME)"
            );
            return Err(Located::new("pose", message));
        }
    }
    Ok(pose.seconds * stage.time_codes_per_second())
}

/// Runs `f`, turning a panic inside the USD library (a malformed layer it does not check) into an error.
fn guarded<T>(location: &str, f: impl FnOnce() -> Result<T, Located>) -> Result<T, Located> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(result) => result,
        Err(panic) => {
            let why = panic
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| panic.downcast_ref::<&str>().copied())
                .unwrap_or("no message");
            Err(Located::new(location, format!("the USD reader failed on a malformed layer ({why})")))
        }
    }
}

/// Refuses a stage that could not be composed (a layer missing, unreadable or malformed, an arc cycle, ...),
/// naming the layer and the prim; MaterialX references are recorded as unread instead.
fn check_composition(stage: &Stage, input: &Path, record: &mut StageRecord) -> Result<(), Located> {
    let base = input.parent().unwrap_or(Path::new(""));
    for error in stage.composition_errors() {
        if let pcp::Error::UnresolvedLayer { asset_path, .. } = &error
            && is_material_x(asset_path)
        {
            let name = crate::import::inputs::relative_name(base, Path::new(asset_path));
            if !record.unread_material_layers.contains(&name) {
                record.unread_material_layers.push(name);
            }
            continue;
        }
        let kind = match error {
            pcp::Error::UnresolvedLayer { .. } => ErrorKind::Unreadable,
            _ => ErrorKind::Invalid,
        };
        return Err(Located::of_kind(kind, "composition", error.to_string()));
    }
    record.unread_material_layers.sort();
    Ok(())
}

/// Whether an asset path names a MaterialX document (materials only, never geometry).
fn is_material_x(asset_path: &str) -> bool {
    asset_path.to_ascii_lowercase().ends_with(".mtlx")
}
