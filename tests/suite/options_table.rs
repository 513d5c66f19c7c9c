//! The options table reaches every door: each option's example value, set by name ([`Settings::set`]), by
//! `Conversion::set`, as the command line's flag and as a `bvhc batch` manifest's key, resolves to the same
//! options under every preset that accepts it, and changes them under at least one; `docs/cli.md` holds the
//! table `bvhc options --list --markdown` prints. (Python's keywords: `crates/bvhc-py/tests/test_bvhc.py`.)

use std::path::Path;
use std::process::Command;

use bvhc::convert::metadata::BuildRecord;
use bvhc::options::{Kind, OPTIONS, OptionValue, Preset, Settings};

fn bvhc(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_bvhc")).args(args).output().expect("bvhc runs")
}

/// Options that take effect only with another: `animation_poses` and `animation_window` with `animation`.
fn companions(name: &str) -> &'static [(&'static str, bool)] {
    match name {
        "animation_poses" | "animation_window" => &[("animation", true)],
        _ => &[],
    }
}

/// The example value of an option, a path made to point at a real ray file in `dir`.
fn example(name: &str, value: OptionValue, dir: &Path) -> OptionValue {
    match (bvhc::options::table::find(name).unwrap().kind, value) {
        (Kind::Path, OptionValue::Text(file)) => OptionValue::Text(dir.join(file).to_string_lossy().into_owned()),
        (_, value) => value,
    }
}

#[test]
fn every_option_reaches_every_door_with_the_same_meaning() {
    let dir = tempfile::tempdir().unwrap();
    // 64 rays from above the origin, straight down: a valid ray file for `train_rays`.
    let mut rays = Vec::new();
    for i in 0..64 {
        for v in [i as f32 * 0.01, 0.0, 5.0, 0.0, 0.0, -1.0, 0.0, f32::INFINITY] {
            rays.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(dir.path().join("rays.bin"), rays).unwrap();
    let input = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/scenes/teapot.obj");
    let mut names = std::collections::BTreeSet::new();
    for spec in OPTIONS {
        assert!(names.insert(spec.name), "{}: named twice", spec.name);
        let value = example(spec.name, (spec.example)(), dir.path());
        let mut changed = false;
        for preset in Preset::ALL {
            let mut settings = Settings::new(preset);
            let mut conversion = bvhc::Conversion::new(&input, dir.path().join("x.bvh")).preset(preset);
            let mut flags = vec!["options".to_string()];
            if spec.name != "preset" {
                flags.extend(["--preset".to_string(), preset.name().to_string()]);
            }
            let mut line = serde_json::Map::new();
            line.insert("preset".into(), preset.name().into());
            for (name, value) in companions(spec.name)
                .iter()
                .map(|&(n, v)| (n, OptionValue::Bool(v)))
                .chain([(spec.name, value.clone())])
            {
                settings.set(name, value.clone()).unwrap_or_else(|e| panic!("{name}: {e}"));
                conversion = conversion.set(name, value.clone()).unwrap();
                let option = bvhc::options::table::find(name).unwrap();
                flags.push(option.flag());
                // A switch, and `--animation` for every clip, are flags without a value.
                if option.kind != Kind::Switch && value != OptionValue::Bool(true) {
                    flags.push(value.to_text());
                }
                line.insert(name.to_string(), value.to_json());
            }
            // The manifest's options object reads to the same settings.
            let manifest = bvhc::batch::options_of(&serde_json::Value::Object(line), dir.path()).unwrap();
            assert_eq!(manifest, settings, "{}: the manifest's key under {}", spec.name, preset.name());
            let args: Vec<&str> = flags.iter().map(String::as_str).collect();
            let run = bvhc(&args);
            let Ok(resolved) = settings.resolve() else {
                assert_eq!(run.status.code(), Some(2), "{args:?}: refused as the library refuses it");
                assert!(conversion.resolved_options().is_err());
                continue;
            };
            assert!(run.status.success(), "{args:?}: {}", String::from_utf8_lossy(&run.stderr));
            let printed: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
            assert_eq!(printed, BuildRecord::of(&resolved).to_value(), "{args:?}");
            assert_eq!(conversion.resolved_options().unwrap(), resolved, "{}: Conversion::set", spec.name);
            changed |= resolved != preset.options();
        }
        assert!(changed, "{}: its example changes the options under no preset", spec.name);
    }
}

#[test]
fn the_docs_hold_the_options_table_and_bad_names_and_values_are_refused_by_name() {
    let docs = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/cli.md")).unwrap();
    let table = bvhc::options::listing::markdown();
    assert!(docs.contains(&table), "docs/cli.md: paste the output of `bvhc options --list --markdown`:\n{table}");
    let run = bvhc(&["options", "--list", "--markdown"]);
    assert_eq!(String::from_utf8_lossy(&run.stdout), table);
    let listed: serde_json::Value = serde_json::from_slice(&bvhc(&["options", "--list", "--json"]).stdout).unwrap();
    assert_eq!(listed.as_array().unwrap().len(), OPTIONS.len());

    let mut settings = Settings::default();
    assert_eq!(
        settings.set("bogus", true).unwrap_err().to_string(),
        "bogus: not a conversion option (`bvhc options --list` lists them)"
    );
    let error = settings.set("split_budget", 9.0).unwrap_err().to_string();
    assert!(error.starts_with("split_budget: expected a fraction from 0 to 4"), "{error}");
    assert!(settings.set("no_splits", 3i64).unwrap_err().to_string().contains("expected true or false"));
    assert!(settings.set("splits", "no").unwrap_err().to_string().contains("expected true or false"));
    assert!(settings.set("max_leaf_size", -1i64).is_err() && settings.set("max_leaf_size", 2.5).is_err());
    assert!(settings.set("selection", "best").unwrap_err().to_string().contains("one of comb, sum, min, area, random"));
    // The positive name of a `no_*` switch is its inverse.
    settings.set("splits", false).unwrap();
    let mut negative = Settings::default();
    negative.set("no_splits", true).unwrap();
    assert_eq!(settings, negative);
    let run = bvhc(&["options", "--max-leaf-size", "four"]);
    assert_eq!(run.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&run.stderr).contains("invalid value 'four' for '--max-leaf-size'"));
}
