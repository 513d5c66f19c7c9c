//! The C API (`crates/bvhc-capi`): a C program built against `include/bvhc.h` and linked with the static
//! library opens, verifies and traces a converted teapot (closest hit, any hit, batches, spawned rays, source
//! corners) with the same hit records as the Rust API, bit for bit; the header's structs have the Rust structs' sizes and it
//! declares exactly the library's exported functions. SKIPPED without a C compiler or without the library
//! (`.ci/run` builds it with `cargo build --release -p bvhc-capi`).

use bvhc_loader::Trace;
use std::path::{Path, PathBuf};
use std::process::Command;

use bvhc::loader::{BvhFile, Ray};
use bvhc_capi::{BvhcHit, BvhcInstance, BvhcMesh, BvhcRay, BvhcSourceCorners};

use crate::cli::{bvhc, teapot};
use crate::common::random_rays;

const HEADER: &str = include_str!("../../crates/bvhc-capi/include/bvhc.h");
/// Every source file of the C API crate.
fn sources() -> Vec<String> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("crates/bvhc-capi/src");
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    files.sort();
    files
        .iter()
        .filter(|f| f.extension().is_some_and(|e| e == "rs"))
        .map(|f| std::fs::read_to_string(f).unwrap())
        .collect()
}

#[test]
fn the_header_declares_every_exported_function_and_nothing_else() {
    let sources = sources();
    // Functions marked `#[unsafe(no_mangle)]`, and the names given to the batch calls' declaring macros (the
    // first `bvhc_` name of each invocation after its doc comment).
    let mut exported: Vec<&str> = sources
        .iter()
        .flat_map(|source| source.split("#[unsafe(no_mangle)]").skip(1))
        .filter_map(|rest| rest.split("fn ").nth(1)?.split('(').next())
        .filter(|name| !name.starts_with('$'))
        .collect();
    let invocations = sources.iter().flat_map(|source| source.split("_entry!(\n").skip(1));
    exported.extend(invocations.filter_map(|rest| {
        let line = rest.lines().map(str::trim).find(|line| !line.starts_with("///"))?;
        line.strip_suffix(',').filter(|name| name.starts_with("bvhc_"))
    }));
    assert!(exported.len() >= 30, "{exported:?}");
    // Every `bvhc_name(` outside comments and the header's own `static inline` readers (whose bodies it holds,
    // over `bvhc_sections`) is a declaration.
    let inline: Vec<&str> = HEADER
        .lines()
        .filter_map(|l| l.strip_prefix("static inline "))
        .filter_map(|rest| rest.split('(').next()?.rsplit([' ', '*']).next())
        .collect();
    assert!(inline.contains(&"bvhc_sections_source_range"), "{inline:?}");
    let code = HEADER.lines().filter(|l| {
        let l = l.trim_start();
        !l.starts_with('*') && !l.starts_with("/*") && !inline.iter().any(|name| l.contains(&format!("{name}(")))
    });
    let mut declared: Vec<&str> = code
        .flat_map(|line| line.match_indices("bvhc_").map(move |(at, _)| &line[at..]))
        .filter_map(|rest| {
            let name = &rest[..rest.find(|c: char| !c.is_ascii_alphanumeric() && c != '_').unwrap_or(rest.len())];
            rest[name.len()..].starts_with('(').then_some(name)
        })
        .collect();
    declared.sort_unstable();
    exported.sort_unstable();
    assert_eq!(declared, exported, "the header declares exactly the exported functions");
    assert_eq!(size_of::<BvhcRay>(), 32);
    assert_eq!(size_of::<BvhcHit>(), 40);
    assert_eq!(size_of::<BvhcSourceCorners>(), 44);
    assert_eq!(size_of::<BvhcInstance>(), 112);
    assert_eq!(size_of::<BvhcMesh>(), 8);
    assert_eq!(size_of::<bvhc_capi::BvhcCandidate>(), 56);
    assert_eq!(size_of::<bvhc_capi::BvhcSections>(), 56);
    assert_eq!(size_of::<bvhc_capi::BvhcRefitReport>(), 40);
    assert_eq!(size_of::<bvhc_capi::BvhcNearestPoint>(), 40);
}

/// The static library beside the test binary (target/<profile>/libbvhc_capi.a), if built.
fn static_library() -> Option<PathBuf> {
    let exe = std::env::current_exe().ok()?;
    let profile = exe.parent()?.parent()?;
    Some(profile.join("libbvhc_capi.a")).filter(|p| p.is_file())
}

/// Builds `tests/c/<program>.c` against `library` into `dir`.
fn compile(dir: &Path, library: &Path, program: &str) -> Result<PathBuf, String> {
    let compiler = std::env::var("CC").unwrap_or_else(|_| "cc".to_string());
    let binary = dir.join(program);
    let output = Command::new(&compiler)
        .args(["-std=c11", "-Wall", "-Wextra", "-pedantic", "-Werror"])
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("tests/c/{program}.c")))
        .arg(library)
        .args(["-lpthread", "-ldl", "-lm", "-o"])
        .arg(&binary)
        .output()
        .map_err(|e| format!("no C compiler ({compiler}: {e})"))?;
    assert!(output.status.success(), "{program}.c does not build:\n{}", String::from_utf8_lossy(&output.stderr));
    Ok(binary)
}

/// The C program `program` built against the static library, or `None` after reporting the skip.
pub(crate) fn c_program(dir: &Path, program: &str) -> Option<PathBuf> {
    let Some(library) = static_library() else {
        crate::skips::skipped(
            crate::skips::Needs::Build,
            format!("{program}.c against the C library (libbvhc_capi.a not built: cargo build --release -p bvhc-capi)"),
        );
        return None;
    };
    match compile(dir, &library, program) {
        Ok(binary) => Some(binary),
        Err(why) => {
            crate::skips::skipped(crate::skips::Needs::CCompiler, format!("{program}.c against the C library ({why})"));
            None
        }
    }
}

#[test]
fn a_c_program_traces_with_the_same_hits_as_rust() {
    let dir = tempfile::tempdir().unwrap();
    let Some(binary) = c_program(dir.path(), "capi_trace") else { return };
    let bvh = dir.path().join("teapot.bvh");
    assert!(bvhc(&[&teapot(), &"-o", &bvh, &"-q"]).status.success());
    let mut rays = random_rays(61, 3000, 3.0);
    rays.push(Ray::new([0.0, 1.5, 10.0], [0.0, 0.0, -1.0]));
    let hits = same_hits_in_c_and_rust(&binary, &bvh, &rays, dir.path());
    assert!(hits > 300, "{hits} of {} rays hit", rays.len());
    // A two-level file (format 1.3): the hit records carry the instance, and spawned rays leave it.
    let (scene, sources) =
        crate::instances::two_level(&crate::instances::test_meshes(), &crate::instances::test_placements(), true);
    let two_level = dir.path().join("instances.bvh");
    std::fs::write(&two_level, crate::instances::write_two_level(&scene, &sources).unwrap().as_bytes()).unwrap();
    let hits = same_hits_in_c_and_rust(&binary, &two_level, &random_rays(62, 3000, 4.0), dir.path());
    assert!(hits > 300, "{hits} of 3000 rays hit the instances");
}

/// Runs the C program on `bvh` and `rays` and checks its lines against the Rust tracer's; returns the hits.
fn same_hits_in_c_and_rust(binary: &Path, bvh: &Path, rays: &[Ray], dir: &Path) -> usize {
    let ray_file = dir.join("rays.bin");
    let bytes: Vec<u8> = rays
        .iter()
        .flat_map(|r| r.origin.into_iter().chain(r.direction).chain([r.t_min, r.t_max]).flat_map(f32::to_le_bytes))
        .collect();
    std::fs::write(&ray_file, bytes).unwrap();
    let run = Command::new(binary).arg(bvh).arg(&ray_file).output().unwrap();
    assert!(run.status.success(), "capi_trace exit {:?}: {}", run.status.code(), String::from_utf8_lossy(&run.stderr));
    let stdout = String::from_utf8(run.stdout).unwrap();
    let mut lines = stdout.lines();
    assert_eq!(lines.next(), Some("sizeof_ray 32"));
    assert_eq!(lines.next(), Some("sizeof_hit 40"));
    assert_eq!(lines.next(), Some("sizeof_source_corners 44"));
    let file = BvhFile::read(bvh).unwrap();
    let view = file.view();
    let tracer = view.tracer();
    let mut hits = 0;
    for (ray, line) in rays.iter().zip(lines) {
        let any = u8::from(tracer.any_hit(ray));
        let expected = match tracer.closest_hit(ray) {
            None => format!("miss {any}"),
            Some(hit) => {
                hits += 1;
                let [nx, ny, nz] = hit.normal.map(f32::to_bits);
                let corners = view.source_corners(&hit).expect("the file has source vertices");
                let [s0, s1, s2] = corners.vertices;
                format!(
                    "hit {:08x} {:08x} {:08x} {nx:08x} {ny:08x} {nz:08x} {} {} {} {any} {s0} {s1} {s2} {} {:08x} {} {}",
                    hit.t.to_bits(),
                    hit.u.to_bits(),
                    hit.v.to_bits(),
                    hit.triangle_index,
                    hit.source_triangle_id.unwrap_or(u32::MAX),
                    u8::from(hit.front_face),
                    corners.range.mesh_index,
                    corners.weights[0].to_bits(),
                    hit.instance_index.unwrap_or(u32::MAX),
                    corners.node_index()
                )
            }
        };
        assert_eq!(line, expected, "{ray:?}");
    }
    hits
}

#[test]
fn a_c_program_reads_what_the_file_holds_and_its_errors_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let Some(binary) = c_program(dir.path(), "capi_scene") else { return };
    let one_level = dir.path().join("teapot.bvh");
    assert!(bvhc(&[&teapot(), &"-o", &one_level, &"-q"]).status.success());
    let (scene, sources) =
        crate::instances::two_level(&crate::instances::test_meshes(), &crate::instances::test_placements(), true);
    let two_level = dir.path().join("instances.bvh");
    std::fs::write(&two_level, crate::instances::write_two_level(&scene, &sources).unwrap().as_bytes()).unwrap();
    for bvh in [&one_level, &two_level] {
        let metadata = dir.path().join("metadata.json");
        let run = Command::new(&binary).arg(bvh).arg(&metadata).output().unwrap();
        let stdout = String::from_utf8(run.stdout).unwrap();
        assert!(run.status.success(), "{}: {}", bvh.display(), String::from_utf8_lossy(&run.stderr));
        assert_eq!(stdout.lines().last(), Some("checks ok"));
        assert_eq!(stdout, expected_scene_lines(bvh) + "checks ok\n", "{}", bvh.display());
        let file = BvhFile::read(bvh).unwrap();
        assert_eq!(std::fs::read(&metadata).unwrap(), file.view().metadata_bytes().unwrap_or_default());
    }
}

/// What `capi_scene.c` prints for `bvh`, from the Rust API.
fn expected_scene_lines(bvh: &Path) -> String {
    use std::fmt::Write;
    let file = BvhFile::read(bvh).unwrap();
    let view = file.view();
    let hex =
        |values: &mut dyn Iterator<Item = f32>| values.map(|v| format!(" {:08x}", v.to_bits())).collect::<String>();
    let mut out = String::new();
    let (min, max) = view.scene_box().unwrap();
    writeln!(out, "bounds{}", hex(&mut min.into_iter().chain(max))).unwrap();
    let (meshes, instances) = view.two_level().map_or((&[][..], &[][..]), |s| (s.meshes, s.instances));
    writeln!(out, "meshes {}", meshes.len()).unwrap();
    for (i, mesh) in meshes.iter().enumerate() {
        writeln!(out, "mesh {i} {} {}", mesh.first_triangle, mesh.triangle_count).unwrap();
    }
    writeln!(out, "instances {}", instances.len()).unwrap();
    for (i, instance) in instances.iter().enumerate() {
        let maps = instance.object_to_world.iter().chain(&instance.world_to_object).flatten().copied();
        let (mesh, node, gpu) = (instance.mesh_index, instance.node_index, instance.gpu_instance_index);
        writeln!(out, "instance {i}{} {mesh} {node} {gpu}", hex(&mut maps.into_iter())).unwrap();
    }
    for (i, triangle) in view.triangles().iter().enumerate() {
        let source = match view.source_vertices() {
            Some(all) => all[i].indices.map(|s| s.to_string()).join(" "),
            None => "-".to_string(),
        };
        writeln!(out, "triangle {i}{} {source}", hex(&mut triangle.vertices.into_iter().flatten())).unwrap();
    }
    out
}

#[test]
fn a_c_filter_gets_the_hits_of_rusts_filtered_tracer_and_is_asked_about_not_opaque_triangles_only() {
    let dir = tempfile::tempdir().unwrap();
    let Some(binary) = c_program(dir.path(), "capi_filter") else { return };
    let one_level = crate::common::write_wide_file(&crate::common::random_triangles(5501, 500, 1.0), 4);
    let (scene, sources) =
        crate::instances::two_level(&crate::instances::test_meshes(), &crate::instances::test_placements(), true);
    let two_level = crate::instances::write_two_level(&scene, &sources).unwrap();
    // A converted scene, with its source table and source vertices (which the candidates carry).
    let teapot_path = dir.path().join("teapot-plain.bvh");
    assert!(bvhc(&[&teapot(), &"-o", &teapot_path, &"-q", &"--preset", &"fast"]).status.success());
    let teapot_file = BvhFile::read(&teapot_path).unwrap();
    assert!(teapot_file.view().source_vertices().is_some());
    let teapot_rays = random_rays(5504, 1500, 3.0);
    for (name, plain, rays) in [
        ("one-level", one_level, random_rays(5502, 1500, 1.5)),
        ("two-level", two_level, random_rays(5503, 1500, 4.0)),
        ("teapot", teapot_file, teapot_rays),
    ] {
        let flagged =
            crate::filters::with_flags(&plain, &crate::filters::flags_by_id(plain.view().triangle_ids().unwrap()));
        let bvh = dir.path().join(format!("{name}.bvh"));
        std::fs::write(&bvh, flagged.as_bytes()).unwrap();
        let ray_file = dir.path().join("rays.bin");
        let bytes: Vec<u8> = rays
            .iter()
            .flat_map(|r| r.origin.into_iter().chain(r.direction).chain([r.t_min, r.t_max]).flat_map(f32::to_le_bytes))
            .collect();
        std::fs::write(&ray_file, bytes).unwrap();
        let run = Command::new(&binary).arg(&bvh).arg(&ray_file).output().unwrap();
        assert!(run.status.success(), "capi_filter exit {:?} on {name}", run.status.code());
        let stdout = String::from_utf8(run.stdout).unwrap();
        let tracer = flagged.view().tracer();
        let filtered = tracer.filtered(&crate::filters::accepts, bvhc::loader::filter::FilterScope::NotOpaque);
        let mut expected = String::new();
        let mut changed = 0;
        for ray in &rays {
            let hit = filtered.closest_hit(ray);
            changed += usize::from(hit.map(|h| h.t) != tracer.closest_hit(ray).map(|h| h.t));
            expected += &match hit {
                Some(hit) => format!("hit {:08x} {}\n", hit.t.to_bits(), hit.triangle_index),
                None => "miss\n".to_string(),
            };
            expected += &format!("any {}\n", u8::from(filtered.any_hit(ray)));
        }
        let (lines, last) = stdout.rsplit_once("asked ").unwrap();
        assert_eq!(lines, expected, "{name}");
        let (asked, rest) = last.trim().split_once(" opaque ").unwrap();
        let (opaque, wrong) = rest.split_once(" wrong ").unwrap();
        assert!(asked.parse::<u64>().unwrap() > 100 && opaque == "0", "{name}: asked {asked}, of them opaque {opaque}");
        assert_eq!(wrong, "0", "{name}: candidates whose source primitive or vertices disagree with the file's arrays");
        assert!(changed > 20, "{name}: the filter changed {changed} rays");
    }
}
