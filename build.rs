//! Build script of the `bvhc` package. It does something only for the `embree4` benchmark feature: it tells the
//! linker where `scripts/embree4.sh` put Embree 4 (`target/embree4/lib`, or `$BVHC_EMBREE4_DIR/lib`), and gives
//! the benchmark binaries that folder as their run-time library path.

fn main() {
    println!("cargo:rerun-if-env-changed=BVHC_EMBREE4_DIR");
    println!("cargo:rerun-if-changed=build.rs");
    if std::env::var_os("CARGO_FEATURE_EMBREE4").is_none() {
        return;
    }
    let manifest = std::path::PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets it"));
    let root = std::env::var_os("BVHC_EMBREE4_DIR").map_or_else(|| manifest.join("target/embree4"), Into::into);
    let lib = root.join("lib");
    if !lib.join("libembree4.so").exists() {
        println!("cargo:warning=Embree 4 not found in {}: run scripts/embree4.sh first", lib.display());
    }
    println!("cargo:rustc-link-search=native={}", lib.display());
    println!("cargo:rustc-link-arg-benches=-Wl,-rpath,{}", lib.display());
}
