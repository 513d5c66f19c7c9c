//! The options table as `bvhc options --list` prints it, as JSON (`--list --json`, Python's
//! `bvhc.options_table()`) and as the Markdown table of `docs/cli.md` (a test holds the page to it).

use super::spec::{Kind, OptionSpec};
use super::table::OPTIONS;

/// Every option as JSON: name, flag, stage, kind, choices, value name, help, the positive name of a `no_*`
/// switch, an example value, and what each preset sets.
pub fn to_json() -> serde_json::Value {
    OPTIONS.iter().map(spec_json).collect()
}

fn spec_json(spec: &OptionSpec) -> serde_json::Value {
    let [fast, balanced, max_quality] = spec.defaults();
    let choices: &[&str] = match spec.kind {
        Kind::Choice(names) => names,
        _ => &[],
    };
    serde_json::json!({
        "name": spec.name,
        "flag": spec.flag(),
        "stage": spec.stage,
        "kind": spec.kind.name(),
        "choices": choices,
        "value_name": spec.value_name,
        "help": spec.help,
        "inverse": spec.inverse,
        "example": (spec.example)().to_json(),
        "defaults": {"fast": fast, "balanced": balanced, "max-quality": max_quality},
    })
}

/// The table of `docs/cli.md`: one row an option with its flag, manifest and Python name, what it takes, each
/// preset's value and its help.
pub fn markdown() -> String {
    let mut out = String::from(
        "| Flag (manifest key, Python keyword) | Takes | fast | balanced | max-quality | What it does |\n\
         |---|---|---|---|---|---|\n",
    );
    for spec in OPTIONS {
        let [fast, balanced, max_quality] = spec.defaults();
        let takes = match spec.kind {
            Kind::Switch => "switch".to_string(),
            Kind::Choice(names) => names.join(" \\| "),
            _ => format!("{} `{}`", spec.kind.name(), spec.value_name.replace('|', "\\|")),
        };
        let names = match spec.inverse {
            Some(positive) => format!("`{}` (`{}`, `{positive}`)", spec.flag(), spec.name),
            None => format!("`{}` (`{}`)", spec.flag(), spec.name),
        };
        let help = spec.help.replace('|', "\\|");
        out.push_str(&format!("| {names} | {takes} | {fast} | {balanced} | {max_quality} | {help} |\n"));
    }
    out
}

/// A plain listing for a terminal: name, flag, what it takes and the presets' values.
pub fn text() -> String {
    let mut out = String::new();
    for spec in OPTIONS {
        let [fast, balanced, max_quality] = spec.defaults();
        let takes = match spec.kind {
            Kind::Choice(names) => names.join("|"),
            Kind::Switch => "switch".to_string(),
            _ => spec.value_name.to_string(),
        };
        out.push_str(&format!(
            "{:<22} {:<24} {:<12} {takes}\n{:<22} fast: {fast}; balanced: {balanced}; max-quality: {max_quality}\n",
            spec.name,
            spec.flag(),
            spec.stage.heading(),
            ""
        ));
    }
    out
}
