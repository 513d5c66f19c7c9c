//! What part of an input an import reads: the glTF scene, the pose (a glTF clip's time, or an OpenUSD stage's
//! time code) and the USD purposes kept.

use super::ClipSelector;

/// Which glTF scene to import.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SceneSelector {
    /// The scene at this index.
    Index(usize),
    /// The scene with this name.
    Name(String),
}

/// A glTF scene as it stands at a time of one of its animation clips (`--pose CLIP@SECONDS`), instead of its
/// default pose: the clip's node TRS and morph weight channels sampled at `seconds` (clamped to the clip's
/// keyframes), skins posed by the animated joints.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PoseSelector {
    /// The clip, by index in the file's `animations` or by name.
    pub clip: ClipSelector,
    /// Seconds into the clip.
    pub seconds: f64,
}

impl std::str::FromStr for PoseSelector {
    type Err = String;

    /// `CLIP@SECONDS`: the clip's index or name, then a time in seconds (`0@1.5`, `Run@0.25`).
    fn from_str(text: &str) -> Result<PoseSelector, String> {
        let (clip, seconds) = text.rsplit_once('@').ok_or_else(|| format!("'{text}' is not CLIP@SECONDS"))?;
        let seconds: f64 = seconds.parse().map_err(|_| format!("'{seconds}' is not a number of seconds"))?;
        if !seconds.is_finite() || seconds < 0.0 {
            return Err(format!("{seconds} seconds: a time from 0 on"));
        }
        let clip = match clip.parse::<usize>() {
            Ok(index) => ClipSelector::Index(index),
            Err(_) if !clip.is_empty() => ClipSelector::Name(clip.to_string()),
            Err(_) => return Err(format!("'{text}': no clip before '@'")),
        };
        Ok(PoseSelector { clip, seconds })
    }
}

/// A pose as the command line and Python spell it: `CLIP@SECONDS` for a glTF scene ([`PoseSelector`]), or a bare
/// number, a time code of an OpenUSD stage ([`ImportOptions::time_code`](super::ImportOptions::time_code)).
#[derive(Clone, Debug, PartialEq)]
pub enum Pose {
    /// A time of a glTF animation clip.
    Clip(PoseSelector),
    /// A time code of an OpenUSD stage.
    TimeCode(f64),
}

impl std::str::FromStr for Pose {
    type Err = String;

    fn from_str(text: &str) -> Result<Pose, String> {
        if text.contains('@') {
            return text.parse().map(Pose::Clip);
        }
        match text.trim().parse::<f64>() {
            Ok(code) if code.is_finite() => Ok(Pose::TimeCode(code)),
            _ => Err(format!("'{text}' is neither CLIP@SECONDS (glTF) nor a time code (USD)")),
        }
    }
}

/// The `purpose` values of an OpenUSD stage whose geometry an import keeps, besides `default` (always kept).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Purposes {
    /// `render`: final-quality geometry (kept by default).
    pub render: bool,
    /// `proxy`: lightweight stand-ins for interactive viewing.
    pub proxy: bool,
    /// `guide`: helper geometry (rigs, bounds) not meant to render.
    pub guide: bool,
}

impl Default for Purposes {
    fn default() -> Purposes {
        Purposes { render: true, proxy: false, guide: false }
    }
}

impl std::fmt::Display for Purposes {
    /// The list [`Purposes`]'s `FromStr` reads (`render,proxy`); `default` when none besides it is kept.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let kept: Vec<&str> = [(self.render, "render"), (self.proxy, "proxy"), (self.guide, "guide")]
            .into_iter()
            .filter_map(|(kept, name)| kept.then_some(name))
            .collect();
        if kept.is_empty() { f.write_str("default") } else { f.write_str(&kept.join(",")) }
    }
}

impl std::str::FromStr for Purposes {
    type Err = String;

    /// A comma-separated list of `render`, `proxy` and `guide` (`default` may be listed and is always kept).
    fn from_str(text: &str) -> Result<Purposes, String> {
        let mut purposes = Purposes { render: false, proxy: false, guide: false };
        for name in text.split(',').map(str::trim).filter(|n| !n.is_empty()) {
            match name {
                "default" => {}
                "render" => purposes.render = true,
                "proxy" => purposes.proxy = true,
                "guide" => purposes.guide = true,
                other => return Err(format!("'{other}' is not a USD purpose (default, render, proxy, guide)")),
            }
        }
        Ok(purposes)
    }
}
