//! The memory-mapped way in: the same bytes and view as reading the file.

use bvhc_loader::Trace;
use bvhc_loader::{BvhFile, MappedBvh, Ray, format::PackedNode, format::PackedTriangle, write::BvhWriter};

#[test]
fn a_mapped_file_views_the_same_bytes_as_a_read_one() {
    let triangles = [
        PackedTriangle { vertices: [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] },
        PackedTriangle { vertices: [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 1.0, 1.0]] },
    ];
    let nodes = [
        PackedNode { min: [0.0; 3], max: [1.0; 3], index: 1, count: 0 },
        PackedNode { min: [0.0; 3], max: [1.0, 1.0, 0.0], index: 0, count: 1 },
        PackedNode { min: [0.0, 0.0, 1.0], max: [1.0; 3], index: 1, count: 1 },
    ];
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("two.bvh");
    let written = BvhWriter::new(&nodes, &triangles).metadata("{}").write_atomic(&path).unwrap();
    #[allow(unsafe_code)]
    // SAFETY: the file lives in a private temporary directory and nothing writes to it while it is mapped.
    let mapped = unsafe { MappedBvh::open(&path) }.unwrap();
    let read = BvhFile::read(&path).unwrap();
    assert_eq!(mapped.as_bytes(), written.as_bytes());
    assert_eq!(read.as_bytes(), written.as_bytes());
    let view = mapped.view();
    view.verify().unwrap();
    assert_eq!(view.nodes(), &nodes[..]);
    let hit = view.tracer().closest_hit(&Ray::new([0.1, 0.1, 2.0], [0.0, 0.0, -1.0])).unwrap();
    assert_eq!((hit.t, hit.triangle_index, hit.source_triangle_id), (1.0, 1, None));
}

#[test]
fn mapping_a_missing_file_names_it() {
    #[allow(unsafe_code)]
    // SAFETY: the file does not exist, so nothing is mapped.
    let error = unsafe { MappedBvh::open(std::path::Path::new("/nonexistent/x.bvh")) }.unwrap_err();
    assert!(error.to_string().contains("/nonexistent/x.bvh"), "{error}");
}
