//! The runtime crate stays lean: with default features `bvhc-loader` depends on bytemuck, xxhash-rust and (for
//! `MappedBvh`) memmap2 only; the writer's dependencies are behind the `write` feature, and nothing needs a
//! proc-macro. (`cargo tree -p bvhc-loader -e normal` lists five crates: the loader, those three and libc.)

#[test]
fn the_loader_depends_on_what_reading_and_tracing_need() {
    let manifest: toml_lite::Manifest = toml_lite::read(include_str!("../../crates/bvhc-loader/Cargo.toml"));
    let required: Vec<&str> = manifest.dependencies.iter().filter(|d| !d.optional).map(|d| d.name.as_str()).collect();
    assert_eq!(required, ["bytemuck", "xxhash-rust"], "non-optional dependencies");
    assert_eq!(manifest.default_features, ["mmap"]);
    for writer_only in ["tempfile", "libc"] {
        assert!(manifest.dependencies.iter().any(|d| d.name == writer_only && d.optional), "{writer_only} is optional");
    }
    let workspace = include_str!("../../Cargo.toml");
    let bytemuck = workspace.lines().find(|l| l.starts_with("bytemuck =")).expect("bytemuck in the workspace");
    assert!(!bytemuck.contains("derive"), "no proc-macro derive: {bytemuck}");
}

/// Just enough TOML for the manifest above: `[dependencies]`-like tables and `default = [...]`.
mod toml_lite {
    pub struct Dependency {
        pub name: String,
        pub optional: bool,
    }

    pub struct Manifest {
        pub dependencies: Vec<Dependency>,
        pub default_features: Vec<String>,
    }

    pub fn read(text: &str) -> Manifest {
        let mut manifest = Manifest { dependencies: Vec::new(), default_features: Vec::new() };
        let mut table = "";
        for line in text.lines().map(str::trim).filter(|l| !l.is_empty() && !l.starts_with('#')) {
            if line.starts_with('[') {
                table = line;
                continue;
            }
            let Some((key, value)) = line.split_once('=') else { continue };
            let (key, value) = (key.trim(), value.trim());
            if table.ends_with("dependencies]") && !table.contains("dev-") {
                manifest.dependencies.push(Dependency {
                    name: key.split('.').next().unwrap_or(key).to_string(),
                    optional: value.contains("optional = true"),
                });
            } else if table == "[features]" && key == "default" {
                manifest.default_features =
                    value.trim_matches(['[', ']']).split(',').map(|f| f.trim().trim_matches('"').to_string()).collect();
            }
        }
        manifest
    }
}
