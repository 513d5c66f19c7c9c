//! The installed C library (`scripts/install-c-library.sh`, which `.ci/run` runs into
//! `target/c-library/prefix`): its files, its SONAME, no GPU code in it, and `examples/c/trace.c` built exactly as
//! a user builds it, through pkg-config (shared and static) and through CMake's `find_package(bvhc)`, tracing
//! what the Rust API traces. SKIPPED without the installed prefix, a C compiler, pkg-config or CMake.

use bvhc_loader::Trace;
use std::path::{Path, PathBuf};
use std::process::Command;

use bvhc::loader::{BvhFile, Ray};

use crate::skips::{Needs, skipped};

/// The install prefix `.ci/run` fills (`BVHC_C_PREFIX` overrides it).
fn prefix() -> Option<PathBuf> {
    let default = || {
        let exe = std::env::current_exe().ok()?;
        Some(exe.parent()?.parent()?.parent()?.join("c-library/prefix"))
    };
    let prefix = std::env::var_os("BVHC_C_PREFIX").map(PathBuf::from).or_else(default)?;
    prefix.join("lib/pkgconfig/bvhc.pc").is_file().then_some(prefix)
}

fn example() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/c/trace.c")
}

fn run(command: &mut Command) -> Result<String, String> {
    let output = command.output().map_err(|e| format!("{command:?}: {e}"))?;
    let text = |bytes: &[u8]| String::from_utf8_lossy(bytes).into_owned();
    match output.status.success() {
        true => Ok(text(&output.stdout)),
        false => Err(format!("{command:?} failed: {}{}", text(&output.stdout), text(&output.stderr))),
    }
}

/// What `trace.c` prints about the hits on `bvh`, from the Rust API: the hit count and the nearest hit's
/// triangle and instance.
fn expected(bvh: &Path) -> (String, String) {
    const GRID: usize = 64;
    let file = BvhFile::read(bvh).unwrap();
    let (min, max) = file.view().scene_box().unwrap();
    let rays: Vec<Ray> = (0..GRID * GRID)
        .map(|k| {
            let (i, j) = ((k % GRID) as f32, (k / GRID) as f32);
            let x = min[0] + (max[0] - min[0]) * (i + 0.5) / GRID as f32;
            let z = min[2] + (max[2] - min[2]) * (j + 0.5) / GRID as f32;
            Ray::new([x, max[1] + 1.0, z], [0.0, -1.0, 0.0])
        })
        .collect();
    let mut hits = vec![None; rays.len()];
    file.view().tracer().closest_hits(&rays, &mut hits);
    let found: Vec<_> = hits.iter().flatten().collect();
    let nearest = found.iter().fold(None, |best: Option<&&bvhc::loader::Hit>, hit| match best {
        Some(b) if b.t <= hit.t => Some(b),
        _ => Some(hit),
    });
    let nearest = nearest.expect("some ray hits");
    let instance = nearest.instance_index.map_or(-1, |i| i as i64);
    (
        format!("{} of {} rays hit", found.len(), GRID * GRID),
        format!(
            "triangle {}, source id {}, instance {instance}",
            nearest.triangle_index,
            nearest.source_triangle_id.unwrap()
        ),
    )
}

fn check_output(output: &str, bvh: &Path) {
    let (count, nearest) = expected(bvh);
    assert!(output.contains(&count), "{output}\nexpected {count}");
    assert!(output.contains(&nearest), "{output}\nexpected {nearest}");
    assert!(output.contains("the way up from it is"), "{output}");
    // Through an instance, the source names the placing glTF node (the mesh's own ranges name none).
    if !nearest.ends_with("instance -1") {
        assert!(output.contains("source: node ") && !output.contains("source: node -1"), "{output}");
    }
}

#[test]
fn the_installed_library_has_its_abi_name_no_gpu_code_and_builds_the_example_through_pkg_config_and_cmake() {
    let Some(prefix) = prefix() else {
        skipped(Needs::Build, "the installed C library (PREFIX=target/c-library/prefix scripts/install-c-library.sh)");
        return;
    };
    let lib = prefix.join("lib");
    for file in ["libbvhc.so", "libbvhc.so.0.1", "libbvhc.so.0.1.0", "libbvhc.a", "cmake/bvhc/bvhcConfig.cmake"] {
        assert!(lib.join(file).exists(), "{} is missing", lib.join(file).display());
    }
    assert!(
        std::fs::read(prefix.join("include/bvhc.h")).unwrap()
            == include_bytes!("../../crates/bvhc-capi/include/bvhc.h"),
        "{} differs from crates/bvhc-capi/include/bvhc.h: the installed library is stale, run the install script again",
        prefix.join("include/bvhc.h").display()
    );
    // No GPU code: neither wgpu nor naga (whose panic messages and paths would name them) is linked in.
    let shared = std::fs::read(lib.join("libbvhc.so.0.1.0")).unwrap();
    for gpu in [&b"wgpu"[..], b"naga"] {
        assert!(
            !shared.windows(gpu.len()).any(|w| w == gpu),
            "the C library contains {}",
            String::from_utf8_lossy(gpu)
        );
    }
    assert!(shared.len() < 4 << 20, "the shared library is {} bytes", shared.len());
    let soname = b"libbvhc.so.0.1\0";
    assert!(shared.windows(soname.len()).any(|w| w == soname), "the SONAME libbvhc.so.0.1 is not in the library");

    let dir = tempfile::tempdir().unwrap();
    let bvh = dir.path().join("teapot.bvh");
    assert!(crate::cli::bvhc(&[&crate::cli::teapot(), &"-o", &bvh, &"-q"]).status.success());
    // Nine teapots placed by the nodes of one GLB, converted two-level: hits name an instance and its node.
    let glb = crate::convert_instances::teapot_grid(dir.path(), 9);
    let two_level = dir.path().join("teapots.bvh");
    assert!(crate::cli::bvhc(&[&glb, &"-o", &two_level, &"-q", &"--instancing", &"always"]).status.success());

    let pkg_config = |args: &[&str]| {
        run(Command::new("pkg-config").args(args).arg("bvhc").env("PKG_CONFIG_PATH", lib.join("pkgconfig")))
    };
    let flags = match pkg_config(&["--cflags", "--libs"]) {
        Ok(flags) => flags,
        Err(why) => return skipped(Needs::Tools, format!("the C example through pkg-config ({why})")),
    };
    assert!(flags.contains(&format!("-I{}", prefix.join("include").display())), "{flags}");
    let compiler = std::env::var("CC").unwrap_or_else(|_| "cc".to_string());
    let shared_binary = dir.path().join("trace");
    let build = run(Command::new(&compiler)
        .args(["-std=c11", "-Wall", "-Wextra", "-pedantic", "-Werror"])
        .arg(example())
        .args(flags.split_whitespace())
        .arg("-o")
        .arg(&shared_binary));
    if let Err(why) = build {
        if why.contains("No such file") && !why.contains("trace.c") {
            return skipped(Needs::CCompiler, format!("the C example ({why})"));
        }
        panic!("examples/c/trace.c does not build through pkg-config: {why}");
    }
    // The prefix is not a system one: the program finds libbvhc.so through the rpath bvhc.pc adds, with no
    // LD_LIBRARY_PATH (as a newcomer runs it).
    for file in [&bvh, &two_level] {
        let output = run(Command::new(&shared_binary).arg(file).env_remove("LD_LIBRARY_PATH")).unwrap();
        check_output(&output, file);
    }
    // Linked statically (pkg-config --static adds the private libraries): no library needed at run time.
    let static_flags = pkg_config(&["--cflags", "--libs", "--static"]).unwrap();
    let static_binary = dir.path().join("trace-static");
    let static_flags = static_flags.replace("-lbvhc", &lib.join("libbvhc.a").display().to_string());
    run(Command::new(&compiler).arg(example()).args(static_flags.split_whitespace()).arg("-o").arg(&static_binary))
        .unwrap();
    check_output(&run(Command::new(&static_binary).arg(&two_level)).unwrap(), &two_level);

    // CMake: find_package(bvhc 0.1) and the imported target.
    let project = dir.path().join("cmake-project");
    std::fs::create_dir_all(&project).unwrap();
    std::fs::write(
        project.join("CMakeLists.txt"),
        format!(
            "cmake_minimum_required(VERSION 3.16)\nproject(trace C)\nfind_package(bvhc 0.1 REQUIRED)\n\
             add_executable(trace \"{}\")\ntarget_link_libraries(trace bvhc::bvhc)\n",
            example().display()
        ),
    )
    .unwrap();
    let build_dir = project.join("build");
    let configure = Command::new("cmake")
        .arg("-S")
        .arg(&project)
        .arg("-B")
        .arg(&build_dir)
        .arg(format!("-DCMAKE_PREFIX_PATH={}", prefix.display()))
        .output();
    match configure {
        Err(why) => return skipped(Needs::Tools, format!("the C example through CMake (cmake: {why})")),
        Ok(output) => assert!(output.status.success(), "cmake: {}", String::from_utf8_lossy(&output.stderr)),
    }
    run(Command::new("cmake").arg("--build").arg(&build_dir)).unwrap();
    // CMake builds with the imported target's rpath: it runs without LD_LIBRARY_PATH too.
    let output = run(Command::new(build_dir.join("trace")).arg(&bvh).env_remove("LD_LIBRARY_PATH")).unwrap();
    check_output(&output, &bvh);
}
