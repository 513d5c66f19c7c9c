//! Gives the shared library its ABI name: `libbvhc.so.<major>.<minor>` on Linux (0.x versions break their ABI at
//! each minor version, as Cargo's semver rules say), the name `scripts/install-c-library.sh` installs it
//! under, so programs linked against the installed library load that version and no other.

fn main() {
    let major = std::env::var("CARGO_PKG_VERSION_MAJOR").unwrap_or_default();
    let minor = std::env::var("CARGO_PKG_VERSION_MINOR").unwrap_or_default();
    let abi = if major == "0" { format!("0.{minor}") } else { major };
    match std::env::var("CARGO_CFG_TARGET_OS").as_deref() {
        Ok("linux") | Ok("freebsd") | Ok("netbsd") | Ok("openbsd") => {
            println!("cargo:rustc-cdylib-link-arg=-Wl,-soname,libbvhc.so.{abi}");
        }
        Ok("macos") => println!("cargo:rustc-cdylib-link-arg=-Wl,-install_name,@rpath/libbvhc.{abi}.dylib"),
        _ => {}
    }
    println!("cargo:rerun-if-changed=build.rs");
}
