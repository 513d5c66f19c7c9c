//! What an entry of the options table ([`super::table::OPTIONS`]) says about one option: its name at every door,
//! its stage, what it takes, its help, its parser and where resolved options show its value.

use super::value::OptionValue;
use super::{ConvertOptions, Preset, Settings};

/// The stage of the conversion an option belongs to (the command line's help headings).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Stage {
    /// The preset every other option overrides.
    Preset,
    /// Reading the scene.
    Import,
    /// Choosing the tree for an animation.
    Animation,
    /// The initial builder.
    Build,
    /// Split references.
    Splits,
    /// Reinsertion.
    Optimize,
    /// Leaves, the wide collapse and ray tuning.
    LeafLayout,
    /// Sections written.
    Output,
}

impl Stage {
    /// The heading of the command line's help.
    pub fn heading(self) -> &'static str {
        match self {
            Stage::Preset => "Preset",
            Stage::Import => "Import",
            Stage::Animation => "Animation",
            Stage::Build => "Build",
            Stage::Splits => "Splits",
            Stage::Optimize => "Optimize",
            Stage::LeafLayout => "Leaf layout",
            Stage::Output => "Output",
        }
    }
}

/// What an option takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A switch: a flag without a value on the command line, `true` in a manifest or from Python.
    Switch,
    /// A whole number from 0.
    Count,
    /// A finite number.
    Number,
    /// One of these names.
    Choice(&'static [&'static str]),
    /// Text in the form `value_name` says.
    Text,
    /// A file's path (a manifest's relative path is against the manifest's folder).
    Path,
}

impl Kind {
    /// The kind's name in `bvhc options --list` and the docs.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Switch => "switch",
            Kind::Count => "count",
            Kind::Number => "number",
            Kind::Choice(_) => "choice",
            Kind::Text => "text",
            Kind::Path => "path",
        }
    }
}

/// One option: its name at every door, what it takes, its parser and where the resolved options show it.
pub struct OptionSpec {
    /// The manifest's key and Python's keyword; the command line's flag is `--` and this with `-` for `_`.
    pub name: &'static str,
    /// The stage it belongs to.
    pub stage: Stage,
    /// What it takes.
    pub kind: Kind,
    /// The value's placeholder in help (`FRACTION`); empty for a switch.
    pub value_name: &'static str,
    /// What it does.
    pub help: &'static str,
    /// For a `no_*` switch, the positive name also accepted with a boolean (`splits: false` is `no_splits: true`).
    pub inverse: Option<&'static str>,
    /// A value the doors' tests give it (one every preset accepts).
    pub example: fn() -> OptionValue,
    /// Reads `value` into the settings.
    pub(super) set: fn(&mut Settings, &OptionValue) -> Result<(), String>,
    /// The option's value in resolved options (a preset's default in `bvhc options --list`).
    pub shown: fn(&ConvertOptions) -> String,
}

impl OptionSpec {
    /// The command line's flag: `--` and the name with `-` for `_`.
    pub fn flag(&self) -> String {
        format!("--{}", self.name.replace('_', "-"))
    }

    /// The option's value under each preset, `fast`, `balanced`, `max-quality`.
    pub fn defaults(&self) -> [String; 3] {
        Preset::ALL.map(|preset| (self.shown)(&preset.options()))
    }
}
