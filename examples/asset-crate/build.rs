//! Converts the teapot fixture into `OUT_DIR/teapot.bvh` at build time and declares every input it read, so
//! cargo reruns this script only when the scene changes. The conversion is skipped when the output is
//! already up to date.

use std::path::PathBuf;

fn main() {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let input = manifest.join("../../fixtures/scenes/teapot.obj");
    let output = PathBuf::from(std::env::var("OUT_DIR").expect("set by cargo")).join("teapot.bvh");
    let outcome = bvhc::Conversion::new(&input, &output)
        .preset(bvhc::Preset::Fast)
        .run()
        .unwrap_or_else(|error| panic!("converting {}: {error}", input.display()));
    for file in &outcome.files_read {
        println!("cargo:rerun-if-changed={}", file.display());
    }
}
