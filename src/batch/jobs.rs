//! Where a batch's jobs come from: a manifest of JSON lines (`{"input": PATH, "output": PATH, "options":
//! {NAME: VALUE}}`, the option names of the options table, paths relative to the manifest's folder), a
//! directory (every scene file below it) or a glob, each input's output named by a pattern.

use std::path::{Path, PathBuf};

use crate::import::SceneFormat;
use crate::options::{Kind, OptionValue, Settings};

/// One conversion of a batch.
#[derive(Clone, Debug, PartialEq)]
pub struct Job {
    /// Where the job came from: `manifest.jsonl:3` (its line) or the input's path.
    pub source: String,
    /// The scene.
    pub input: PathBuf,
    /// The `.bvh` file to write.
    pub output: PathBuf,
    /// The preset and options.
    pub settings: Settings,
}

/// A job that could not be read from its source (a bad manifest line): reported as failed, the others run.
#[derive(Clone, Debug, PartialEq)]
pub struct BadJob {
    /// `manifest.jsonl:3`.
    pub source: String,
    /// What is wrong, naming the key.
    pub error: String,
}

/// The settings of a manifest line's `options` object (or a Python job's `options` dict as JSON) over `base`:
/// every key a name of the options table, set in order; a path-valued option's relative path is against
/// `folder`.
pub fn options_over(base: &Settings, options: &serde_json::Value, folder: &Path) -> Result<Settings, String> {
    let mut settings = base.clone();
    let object = match options {
        serde_json::Value::Null => return Ok(settings),
        serde_json::Value::Object(object) => object,
        other => return Err(format!("\"options\": {other}: expected an object of option names and values")),
    };
    for (name, value) in object {
        let Some(value) = OptionValue::from_json(value).map_err(|e| format!("\"{name}\": {e}"))? else { continue };
        let value = match (crate::options::table::find(name).map(|s| s.kind), value) {
            (Some(Kind::Path), OptionValue::Text(path)) => OptionValue::from(folder.join(path).as_path()),
            (_, value) => value,
        };
        let shown = value.to_json();
        settings.set(name, value).map_err(|error| match error {
            crate::options::OptionsError::Invalid { why, .. } => format!("\"{name}\": {shown}: {why}"),
            other => other.to_string(),
        })?;
    }
    Ok(settings)
}

/// [`options_over`] the default settings.
pub fn options_of(options: &serde_json::Value, folder: &Path) -> Result<Settings, String> {
    options_over(&Settings::default(), options, folder)
}

/// One manifest line as a job: `input` and `output` strings (relative to `folder`), `options` an object.
pub fn job_of_line(line: &str, folder: &Path, base: &Settings, source: String) -> Result<Job, BadJob> {
    let bad = |error: String| BadJob { source: source.clone(), error };
    let value: serde_json::Value = serde_json::from_str(line).map_err(|e| bad(format!("not JSON: {e}")))?;
    let object =
        value.as_object().ok_or_else(|| bad("expected an object {\"input\", \"output\", \"options\"}".into()))?;
    if let Some(key) = object.keys().find(|k| !matches!(k.as_str(), "input" | "output" | "options")) {
        return Err(bad(format!("\"{key}\": not a key of a job (input, output, options)")));
    }
    let path = |key: &str| match object.get(key) {
        Some(serde_json::Value::String(path)) if !path.is_empty() => Ok(folder.join(path)),
        _ => Err(bad(format!("\"{key}\": expected a path (a non-empty string)"))),
    };
    let (input, output) = (path("input")?, path("output")?);
    let options = object.get("options").unwrap_or(&serde_json::Value::Null);
    let settings = options_over(base, options, folder).map_err(bad)?;
    Ok(Job { source, input, output, settings })
}

/// The largest manifest read (1 GiB: millions of jobs), so that its text's memory is bounded.
pub const MAX_MANIFEST_BYTES: u64 = 1 << 30;

/// The jobs of a manifest, in its order: one a non-empty line (`#` starts a comment line); a bad line is a
/// [`BadJob`].
pub fn read_manifest(path: &Path, base: &Settings) -> std::io::Result<Vec<Result<Job, BadJob>>> {
    let metadata = std::fs::metadata(path)?;
    if !metadata.is_file() {
        return Err(std::io::Error::other("not a regular file"));
    }
    if metadata.len() > MAX_MANIFEST_BYTES {
        let why = format!("{} bytes: a manifest holds at most {MAX_MANIFEST_BYTES} (split it)", metadata.len());
        return Err(std::io::Error::other(why));
    }
    let text = std::fs::read_to_string(path)?;
    let folder = path.parent().unwrap_or(Path::new(""));
    let lines = text.lines().enumerate().map(|(index, line)| (index, line.trim()));
    let lines = lines.filter(|(_, line)| !line.is_empty() && !line.starts_with('#'));
    Ok(lines
        .map(|(index, line)| job_of_line(line, folder, base, format!("{}:{}", path.display(), index + 1)))
        .collect())
}

/// The output of `input` by `pattern`: `{dir}` is the input's folder relative to `root` (`.` for `root`
/// itself), `{stem}` its file name without the scene extension (`.obj.gz` whole), `{name}` its file name.
pub fn output_for(input: &Path, root: &Path, pattern: &str) -> PathBuf {
    let name = input.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let lower = name.to_lowercase();
    let extension = [".obj.gz", ".ply.gz"]
        .into_iter()
        .find(|e| lower.ends_with(e))
        .map_or_else(|| name.rfind('.').map_or(0, |dot| name.len() - dot), str::len);
    let stem = &name[..name.len() - extension];
    let folder = input.parent().and_then(|p| p.strip_prefix(root).ok()).unwrap_or(Path::new(""));
    let folder = if folder.as_os_str().is_empty() { ".".to_string() } else { folder.to_string_lossy().into_owned() };
    PathBuf::from(pattern.replace("{dir}", &folder).replace("{stem}", stem).replace("{name}", &name))
}

/// Every scene file below `root` (by extension), sorted, symbolic links to folders not followed.
pub fn scenes_below(root: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut found = Vec::new();
    let mut folders = vec![root.to_path_buf()];
    while let Some(folder) = folders.pop() {
        for entry in std::fs::read_dir(&folder)? {
            let entry = entry?;
            let kind = entry.file_type()?;
            let path = entry.path();
            if kind.is_dir() {
                folders.push(path);
            } else if SceneFormat::from_file_name(&entry.file_name().to_string_lossy()).is_some() {
                found.push(path);
            }
        }
    }
    found.sort();
    Ok(found)
}

/// The scene files a glob names (`assets/**/*.glb`), sorted, and the folder before its first wildcard (what
/// `{dir}` is relative to).
pub fn scenes_matching(pattern: &str) -> Result<(Vec<PathBuf>, PathBuf), String> {
    let paths = glob::glob(pattern).map_err(|e| format!("{pattern}: not a glob: {e}"))?;
    let mut found = Vec::new();
    for path in paths {
        let path = path.map_err(|e| format!("{pattern}: {e}"))?;
        if path.is_file()
            && SceneFormat::from_file_name(&path.file_name().unwrap_or_default().to_string_lossy()).is_some()
        {
            found.push(path);
        }
    }
    found.sort();
    let literal: PathBuf = Path::new(pattern)
        .components()
        .take_while(|c| !c.as_os_str().to_string_lossy().contains(['*', '?', '[']))
        .collect();
    Ok((found, literal))
}

/// Whether `text` is a glob rather than a path (it holds `*`, `?` or `[`).
pub fn is_glob(text: &str) -> bool {
    text.contains(['*', '?', '['])
}
