//! Scene import: a `.gltf`, `.glb`, `.obj`, `.ply`, `.obj.gz` or `.ply.gz` file, or an OpenUSD stage (`.usd`,
//! `.usda`, `.usdc`, `.usdz`) -> a [`TriangleSoup`] in
//! world space with provenance, the list of every file read, and a report of what was skipped.
//!
//! ```no_run
//! let import = bvhc::import::import(std::path::Path::new("scene.gltf"), &Default::default())?;
//! for file in &import.files_read {
//!     println!("cargo:rerun-if-changed={}", file.display());
//! }
//! println!("{} triangles, {} degenerate dropped", import.soup.triangles.len(), import.report.degenerate());
//! # Ok::<(), bvhc::import::ImportError>(())
//! ```

mod gltf;
pub mod inputs;
mod instancing;
mod opacity;
mod limits;
pub mod memory;
mod obj;
mod obj_text;
mod ply;
mod polygon;
mod report;
mod selectors;
mod soup;
mod usd;

use std::path::{Path, PathBuf};

pub use gltf::{ClipSelector, ClipSpan};

pub use instancing::{AUTO_MIN_SAVED_TRIANGLES, InstancedMesh, Instancing, MeshPlacement};
pub use limits::ImportLimits;
pub use opacity::Opacity;
pub use report::ImportReport;
pub use selectors::{Pose, PoseSelector, Purposes, SceneSelector};
pub use soup::{Provenance, TriangleSoup, is_zero_area};
pub use usd::{StageRecord, TIME_CODES_CLIP};

use soup::SoupBuilder;

/// Import options; the defaults suit conversion.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ImportOptions {
    /// The glTF scene to import; default: the file's default scene, else scene 0.
    pub scene: Option<SceneSelector>,
    /// The pose of a glTF scene: a time of an animation clip; default (`None`): the default pose (every node's
    /// own transform and morph weights, skins posed by their joints' default transforms).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pose: Option<PoseSelector>,
    /// Keep degenerate triangles (repeated index or zero area) instead of dropping them; they are counted
    /// either way.
    pub keep_degenerate: bool,
    /// The resource budget (not recorded in output files: it changes whether an import succeeds, never what it
    /// produces).
    #[serde(skip)]
    pub limits: ImportLimits,
    /// Follow glTF buffer URIs that leave the input's folder (`../`, absolute paths). Off by default: an
    /// untrusted asset must not copy bytes of other files into the output.
    #[serde(skip)]
    pub allow_buffers_outside_input_folder: bool,
    /// Which glTF meshes placed more than once stay instanced (recorded in output files by the conversion's
    /// `build` object, not here).
    #[serde(skip)]
    pub instancing: Instancing,
    /// The animation clips (indices) of a conversion for an animation (`--animation` on a glTF): a mesh placed by
    /// a node these clips move (a translation, rotation or scale channel on the node or an ancestor) is stored
    /// once in its object space and placed by instances, whose transforms a refit moves, under
    /// [`Instancing::Always`] (other modes decide as without an animation), unless some node poses it for itself
    /// (a skin, or morph weights of its own or that these clips animate: those deform, and are flattened); the
    /// placements record whether their node moves. Empty: none.
    #[serde(skip)]
    pub moving_clips: Vec<usize>,
    /// Which triangles the file marks not opaque (recorded by the conversion's `build` object, not here).
    #[serde(skip)]
    pub opacity: Opacity,
    /// The time code an OpenUSD stage is read at (`--pose TIME` on a USD input): time-sampled transforms,
    /// points, visibility and point-instancer attributes interpolated there; `None`: the default time, which
    /// reads authored default values only (USD's `UsdTimeCode::Default()`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time_code: Option<f64>,
    /// Which USD purposes besides `default` are imported (`render` by default; `proxy` and `guide` on request).
    #[serde(skip)]
    pub purposes: Purposes,
}

/// The file formats bvhc reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneFormat {
    /// glTF 2.0 JSON.
    Gltf,
    /// glTF 2.0 binary container.
    Glb,
    /// Wavefront OBJ, optionally gzipped.
    Obj,
    /// Stanford PLY, optionally gzipped.
    Ply,
    /// An OpenUSD stage: a `.usd`, `.usda` or `.usdc` layer, or a `.usdz` package.
    Usd,
}

impl SceneFormat {
    /// The format for a file name, from its extension (case-insensitive); also whether it is gzipped.
    pub fn from_file_name(name: &str) -> Option<(SceneFormat, bool)> {
        let lower = name.to_lowercase();
        let (stem, gzipped) = match lower.strip_suffix(".gz") {
            Some(stem) => (stem, true),
            None => (lower.as_str(), false),
        };
        let format = match stem.rsplit_once('.').map(|(_, ext)| ext) {
            Some("gltf") if !gzipped => SceneFormat::Gltf,
            Some("glb") if !gzipped => SceneFormat::Glb,
            Some("obj") => SceneFormat::Obj,
            Some("ply") => SceneFormat::Ply,
            Some("usd" | "usda" | "usdc" | "usdz") if !gzipped => SceneFormat::Usd,
            _ => return None,
        };
        Some((format, gzipped))
    }
}

/// A scene ready for building: triangles, the files read to get them, and what was skipped.
#[derive(Clone, Debug, PartialEq)]
pub struct Import {
    /// World-space triangles with provenance.
    pub soup: TriangleSoup,
    /// Every file read, the input first (a build script declares them with `cargo:rerun-if-changed`).
    pub files_read: Vec<PathBuf>,
    /// Counts of what was read, skipped and dropped.
    pub report: ImportReport,
    /// The input's format.
    pub format: SceneFormat,
    /// What a USD stage records (prim paths, units), for an OpenUSD input.
    pub stage: Option<StageRecord>,
    /// The meshes kept instanced (glTF and USD): their object-space triangles in the soup and their placements;
    /// every other triangle of the soup is in world space. Empty for a flattened scene.
    pub instanced: Vec<InstancedMesh>,
}

/// What kind of failure an [`ImportError`] is (the command line maps it to its exit code).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum ErrorKind {
    /// The file's content breaks a rule of its format (or of bvhc's import).
    Invalid,
    /// A file could not be read: missing, unreadable, a directory, a FIFO or device, a read error.
    Unreadable,
    /// The input exceeds a limit of [`ImportLimits`] (or memory ran out).
    Limit,
}

/// Why a scene could not be imported: the file, the part of it (mesh/primitive/accessor, line) and the rule.
#[derive(Debug, thiserror::Error)]
#[error("{}: {location}: {message}", path.display())]
pub struct ImportError {
    /// The file.
    pub path: PathBuf,
    /// Where in the file, e.g. `mesh 2 primitive 0` or `line 17`.
    pub location: String,
    /// What is wrong.
    pub message: String,
    /// The kind of failure.
    pub kind: ErrorKind,
}

/// A problem found inside a glTF buffer, accessor, primitive or extension, before its location (mesh,
/// primitive, node) is attached: its kind and its message.
#[derive(Debug)]
pub(crate) struct Problem {
    kind: ErrorKind,
    message: String,
}

impl Problem {
    pub(crate) fn of_kind(kind: ErrorKind, message: String) -> Problem {
        Problem { kind, message }
    }

    /// An import limit was exceeded (the message says which and how to raise it).
    pub(crate) fn limit(message: String) -> Problem {
        Problem::of_kind(ErrorKind::Limit, message)
    }

    /// The same problem with `prefix` put before its message (e.g. `"accessor 3: "`).
    pub(crate) fn prefixed(self, prefix: &str) -> Problem {
        Problem { message: format!("{prefix}{}", self.message), ..self }
    }

    /// The problem located in the file.
    pub(crate) fn at(self, location: &str) -> Located {
        Located::of_kind(self.kind, location, self.message)
    }
}

/// A broken rule of the format.
impl From<String> for Problem {
    fn from(message: String) -> Problem {
        Problem::of_kind(ErrorKind::Invalid, message)
    }
}

impl From<&str> for Problem {
    fn from(message: &str) -> Problem {
        Problem::from(message.to_string())
    }
}

/// An error inside a file, before the file's path is attached.
#[derive(Debug)]
pub(crate) struct Located {
    location: String,
    message: String,
    kind: ErrorKind,
}

impl Located {
    /// A broken rule of the file's format.
    pub(crate) fn new(location: &str, message: String) -> Located {
        Located::of_kind(ErrorKind::Invalid, location, message)
    }

    pub(crate) fn of_kind(kind: ErrorKind, location: &str, message: String) -> Located {
        Located { location: location.to_string(), message, kind }
    }

    pub(crate) fn kind(&self) -> ErrorKind {
        self.kind
    }

    pub(crate) fn message(&self) -> &str {
        &self.message
    }

    /// The same error with its message rewritten.
    pub(crate) fn with_message(self, rewrite: impl FnOnce(&str) -> String) -> Located {
        Located { message: rewrite(&self.message), ..self }
    }
}

/// Imports the scene at `path` (format from the extension), refusing a scene whose conversion would exceed the
/// memory budget at [`memory::BYTES_PER_TRIANGLE`].
pub fn import(path: &Path, options: &ImportOptions) -> Result<Import, ImportError> {
    import_for_peak(path, options, memory::BYTES_PER_TRIANGLE)
}

/// Every animation clip of the glTF file at `path`, with the span of its keyframes (none for a file without
/// animations); an OpenUSD stage has one, its authored time codes ([`usd::TIME_CODES_CLIP`]: start to end, in
/// seconds at its time codes a second; none without an authored range); an OBJ or PLY file, which has no
/// animation, is refused.
pub fn animation_clips(path: &Path, options: &ImportOptions) -> Result<Vec<ClipSpan>, ImportError> {
    let error =
        |e: Located| ImportError { path: path.to_path_buf(), location: e.location, message: e.message, kind: e.kind };
    let format = input_format(path).map_err(error)?;
    if let Some((SceneFormat::Usd, _)) = format {
        return usd::clips(path, options).map_err(error);
    }
    let Some((SceneFormat::Gltf | SceneFormat::Glb, gzipped)) = format else {
        return Err(error(Located::new(
            "animations",
            "only a glTF file or an OpenUSD stage has animation clips (.gltf, .glb, .usd, .usda, .usdc, .usdz)"
                .to_string(),
        )));
    };
    let bytes = limits::read_regular_file(path, gzipped, options.limits.max_input_bytes).map_err(error)?;
    gltf::clips(path, &bytes, options).map_err(error)
}

/// The format of the input at `path` from its file name (`None`: not a scene extension), after checking that
/// it is a file that can be read at all: a missing input, or one that is a directory, is an unreadable input
/// whatever its name says (exit 3 on the command line), not an unsupported file type.
fn input_format(path: &Path) -> Result<Option<(SceneFormat, bool)>, Located> {
    let metadata = std::fs::metadata(path)
        .map_err(|e| Located::of_kind(ErrorKind::Unreadable, "file", format!("cannot read: {e}")))?;
    if metadata.is_dir() {
        return Err(Located::of_kind(ErrorKind::Unreadable, "file", "cannot read: a directory".to_string()));
    }
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    Ok(SceneFormat::from_file_name(&name))
}

/// Room the parsers need beyond the file's bytes before they start (checked by a probe, see [`import_for_peak`]).
const PARSE_HEADROOM: usize = 64 << 20;

/// [`import`] for a conversion whose peak is estimated at `peak_bytes_per_triangle` bytes a placed triangle
/// (more when it compares candidate trees): the scene is refused before its triangles are held when that peak
/// would exceed [`ImportLimits::max_memory`].
pub fn import_for_peak(
    path: &Path,
    options: &ImportOptions,
    peak_bytes_per_triangle: u64,
) -> Result<Import, ImportError> {
    let error =
        |e: Located| ImportError { path: path.to_path_buf(), location: e.location, message: e.message, kind: e.kind };
    let (format, gzipped) = input_format(path).map_err(error)?.ok_or_else(|| {
        error(Located::new(
            "file name",
            "unsupported file type (expected .gltf, .glb, .obj, .ply, .obj.gz, .ply.gz, .usd, .usda, .usdc or .usdz)"
                .to_string(),
        ))
    })?;
    if format == SceneFormat::Usd {
        return import_stage(path, options, peak_bytes_per_triangle);
    }
    if options.time_code.is_some() {
        let message = "a time code poses an OpenUSD stage; a glTF pose is CLIP@SECONDS".to_string();
        return Err(error(Located::new("pose", message)));
    }
    let bytes = limits::read_regular_file(path, gzipped, options.limits.max_input_bytes).map_err(error)?;
    // Parsing allocates many small blocks that cannot report failure: stop here, with an error, when the file's
    // bytes left too little room for them (an address-space limit just above the file's size).
    crate::fallible::probe(PARSE_HEADROOM, "parsing").map_err(|e| {
        error(Located::of_kind(ErrorKind::Limit, "file", format!("{e} after reading {} bytes", bytes.len())))
    })?;
    let mut builder = SoupBuilder::new(options.keep_degenerate, &options.limits, peak_bytes_per_triangle);
    let mut files_read = vec![path.to_path_buf()];
    let mut instanced = Vec::new();
    let result = match format {
        SceneFormat::Gltf | SceneFormat::Glb => {
            gltf::read(path, &bytes, options, &mut builder).map(|(more, meshes)| {
                files_read.extend(more);
                instanced = meshes;
            })
        }
        _ if options.pose.is_some() => {
            Err(Located::new("pose", "an OBJ or PLY file has no animation to pose (--pose is for glTF)".to_string()))
        }
        SceneFormat::Obj => obj::read(&bytes, &options.limits, &mut builder),
        SceneFormat::Ply => ply::read(&bytes, &options.limits, &mut builder),
        SceneFormat::Usd => Err(Located::new("file", "a USD stage is read by its own importer".to_string())),
    };
    result.map_err(error)?;
    Ok(finish(builder, files_read, format, instanced, None))
}

/// [`import_for_peak`] for an OpenUSD stage, whose layers the USD reader opens itself (each held to the byte
/// limit as it is opened).
fn import_stage(path: &Path, options: &ImportOptions, peak_bytes_per_triangle: u64) -> Result<Import, ImportError> {
    let error =
        |e: Located| ImportError { path: path.to_path_buf(), location: e.location, message: e.message, kind: e.kind };
    if options.pose.is_some() && options.time_code.is_some() {
        let message = "both a clip time and a time code: pose a stage by one of them".to_string();
        return Err(error(Located::new("pose", message)));
    }
    let mut builder = SoupBuilder::new(options.keep_degenerate, &options.limits, peak_bytes_per_triangle);
    let (more, instanced, stage) = usd::read(path, options, &mut builder).map_err(error)?;
    let files_read = std::iter::once(path.to_path_buf()).chain(more).collect();
    Ok(finish(builder, files_read, SceneFormat::Usd, instanced, Some(stage)))
}

/// The import of what `builder` holds.
fn finish(
    builder: SoupBuilder,
    files_read: Vec<PathBuf>,
    format: SceneFormat,
    instanced: Vec<InstancedMesh>,
    stage: Option<StageRecord>,
) -> Import {
    let (soup, mut report) = builder.finish();
    let in_meshes: usize = instanced.iter().map(|m| m.triangles.len()).sum();
    report.placed_triangles = (soup.triangles.len() - in_meshes) as u64
        + instanced.iter().map(|m| (m.triangles.len() * m.placements.len()) as u64).sum::<u64>();
    report.instanced_meshes = instanced.len() as u64;
    Import { soup, files_read, report, format, instanced, stage }
}
