//! `format-spec/bvh.h` compiles as C11 with warnings denied, its static assertions hold, and a reader written
//! against it alone (`tests/c/read_bvh.c`) finds in the golden files what the Rust reader finds. SKIPPED where
//! the system has no C compiler (`.ci/run` installs one where it can); `CC` names another compiler.

use std::path::{Path, PathBuf};
use std::process::Command;

use bvhc::loader::format::{GpuNode, GpuSlot, GpuTriangle};
use bvhc::loader::{
    BvhFile, format::PackedNode, format::PackedTriangle, format::SourceRange, format::TrianglePacket4,
    format::WideNode8,
};

fn repository() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// The C reader compiled into `dir`, or why it could not be.
fn compile(dir: &Path) -> Result<PathBuf, String> {
    let compiler = std::env::var("CC").unwrap_or_else(|_| "cc".to_string());
    let binary = dir.join("read_bvh");
    let output = Command::new(&compiler)
        .args(["-std=c11", "-Wall", "-Wextra", "-pedantic", "-Werror", "-o"])
        .arg(&binary)
        .arg(repository().join("tests/c/read_bvh.c"))
        .output()
        .map_err(|e| format!("no C compiler ({compiler}: {e})"))?;
    assert!(
        output.status.success(),
        "bvh.h or read_bvh.c does not compile:\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    Ok(binary)
}

/// The reader's "key value" lines for `file` (none: only the layout sizes).
fn read(binary: &Path, file: Option<&Path>) -> Vec<(String, String)> {
    let output = Command::new(binary).args(file).output().unwrap();
    assert!(output.status.success(), "read_bvh fails: {}", String::from_utf8_lossy(&output.stderr));
    String::from_utf8(output.stdout)
        .unwrap()
        .lines()
        .map(|line| {
            let (key, value) = line.split_once(' ').unwrap();
            (key.to_string(), value.to_string())
        })
        .collect()
}

#[test]
fn the_c_header_compiles_and_reads_the_golden_files_as_the_rust_reader_does() {
    let dir = tempfile::tempdir().unwrap();
    let binary = match compile(dir.path()) {
        Ok(binary) => binary,
        Err(why) => {
            crate::skips::skipped(crate::skips::Needs::CCompiler, format!("bvh.h compiled and read from C ({why})"));
            return;
        }
    };
    let sizes = read(&binary, None);
    let expected_sizes = [
        ("sizeof_header", 64),
        ("sizeof_entry", 48),
        ("sizeof_node", size_of::<PackedNode>()),
        ("sizeof_triangle", size_of::<PackedTriangle>()),
        ("sizeof_source_range", size_of::<SourceRange>()),
        ("sizeof_wide_node", size_of::<WideNode8>()),
        ("sizeof_packet", size_of::<TrianglePacket4>()),
        ("sizeof_gpu_node", size_of::<GpuNode>()),
        ("sizeof_gpu_triangle", size_of::<GpuTriangle>()),
    ];
    let expected_sizes: Vec<(String, String)> =
        expected_sizes.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
    assert_eq!(sizes, expected_sizes);
    for name in ["quad-v1.0.bvh", "quad-v1.1.bvh", "split-v1.1.bvh", "gpu-v1.4.bvh"] {
        let path = repository().join("fixtures/golden").join(name);
        let file = BvhFile::read(&path).unwrap();
        let view = file.view();
        let (major, minor) = view.version();
        let wide = view.wide_sections();
        let gpu = view.gpu_sections();
        let slots = || gpu.iter().flat_map(|g| g.nodes.iter().flat_map(|n| (0..8).map(move |s| n.slot(s))));
        let gpu_slots = |keep: fn(&GpuSlot) -> bool| slots().filter(keep).count();
        let gpu_slots_sum =
            || slots().map(|s| if let GpuSlot::Leaf { count, .. } = s { count } else { 0 }).sum::<u32>();
        let leaf_packets: u32 = wide
            .iter()
            .flat_map(|w| w.nodes.iter().flat_map(|n| n.child))
            .filter(|&c| c != bvhc::loader::format::EMPTY_SLOT && c & bvhc::loader::format::LEAF_BIT != 0)
            .map(|c| WideNode8::leaf_packets(c).1)
            .sum();
        let expected = [
            ("version", format!("{major}.{minor}")),
            ("split_references", u8::from(view.has_split_references()).to_string()),
            ("node_count", view.nodes().len().to_string()),
            ("triangle_count", view.triangles().len().to_string()),
            ("wide_node_count", wide.map_or(0, |w| w.nodes.len()).to_string()),
            ("packet_count", wide.map_or(0, |w| w.packets.len()).to_string()),
            ("leaf_count", view.nodes().iter().filter(|n| n.is_leaf()).count().to_string()),
            ("leaf_packets", leaf_packets.to_string()),
            ("gpu_node_count", gpu.map_or(0, |g| g.nodes.len()).to_string()),
            ("gpu_triangle_count", gpu.map_or(0, |g| g.triangles.len()).to_string()),
            ("gpu_inner_slots", gpu_slots(|s| matches!(s, GpuSlot::Inner(_))).to_string()),
            ("gpu_leaf_triangles", gpu_slots_sum().to_string()),
        ];
        let found: Vec<(String, String)> = read(&binary, Some(&path)).into_iter().skip(sizes.len()).collect();
        let expected: Vec<(String, String)> = expected.into_iter().map(|(k, v)| (k.to_string(), v)).collect();
        assert_eq!(found, expected, "{name}");
    }
}

#[test]
fn the_c_header_states_the_current_version_and_rules() {
    // Checked on the text, so it holds without a C compiler too.
    let header = include_str!("../../format-spec/bvh.h");
    let minor = bvhc::loader::format::VERSION_MINOR;
    assert!(header.contains(&format!("#define BVH_VERSION_MINOR {minor} ")), "BVH_VERSION_MINOR is {minor}");
    assert!(header.contains(&format!("(format-spec/bvh-1.md,\n * version 1.{minor})")), "the comment's version");
    let last = bvhc::loader::Rule::ALL.len();
    assert!(header.contains(&format!("V1-V10 (and V11-V{last} to trust")), "the comment names V11-V{last}");
    for declared in ["BvhMeshRecord", "BvhInstanceRecord", "BvhGpuNode", "BvhGpuTriangle"] {
        assert!(header.contains(&format!("}} {declared};")), "{declared} is declared");
    }
}
