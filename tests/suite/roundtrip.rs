//! write -> open -> traverse equals the in-memory tree; files on disk through every way in.

use bvhc::loader::{BvhFile, BvhView, Error, Rule, Tracer, format::PackedNode, write::BvhWriter};
use bvhc_loader::Trace;

use crate::common::*;

#[test]
fn written_file_holds_the_in_memory_tree_and_traces_identically() {
    let triangles = random_triangles(1, 3000, 10.0);
    for max_leaf_size in [1, 4, 8] {
        let tree = packed_tree(&triangles, max_leaf_size);
        let file = write_file(&tree);
        let view = file.view();
        view.verify().unwrap();
        assert_eq!(view.nodes(), &tree.nodes[..]);
        assert_eq!(view.triangles(), &tree.triangles[..]);
        assert_eq!(view.triangle_ids(), Some(&tree.triangle_ids[..]));
        assert_eq!(view.metadata_str().unwrap().unwrap(), METADATA);
        let in_memory = Tracer::new(&tree.nodes, &tree.triangles, Some(&tree.triangle_ids));
        for ray in random_rays(2, 2000, 10.0) {
            assert_eq!(view.tracer().closest_hit(&ray), in_memory.closest_hit(&ray));
            assert_eq!(view.tracer().any_hit(&ray), in_memory.any_hit(&ray));
        }
    }
}

#[test]
fn the_same_input_gives_the_same_bytes() {
    let triangles = random_triangles(3, 500, 1.0);
    let first = write_file(&packed_tree(&triangles, 4));
    let second = write_file(&packed_tree(&triangles, 4));
    assert_eq!(first.as_bytes(), second.as_bytes());
}

#[test]
fn files_on_disk_read_and_map_to_the_same_view() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.bvh");
    let tree = packed_tree(&random_triangles(4, 700, 5.0), 2);
    let written = BvhWriter::new(&tree.nodes, &tree.triangles).write_atomic(&path).unwrap();
    let read = BvhFile::read(&path).unwrap();
    assert_eq!(read.as_bytes(), written.as_bytes());
    read.view().verify().unwrap();
    // The memory-mapped way in is tested in the loader crate's own tests (the only crate allowed `unsafe`).
    let names: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(names, ["scene.bvh"], "no temporary file is left behind");
}

#[test]
fn a_failed_write_leaves_the_previous_file_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.bvh");
    std::fs::write(&path, b"previous").unwrap();
    let bad_root = PackedNode { min: [0.0; 3], max: [1.0; 3], index: 0, count: 0 };
    let error = BvhWriter::new(&[bad_root], &[]).write_atomic(&path).unwrap_err();
    assert!(error.rule().is_some(), "{error}");
    assert_eq!(std::fs::read(&path).unwrap(), b"previous");
    let missing_dir = dir.path().join("no/such/dir/scene.bvh");
    let tree = packed_tree(&random_triangles(5, 10, 1.0), 1);
    let error = BvhWriter::new(&tree.nodes, &tree.triangles).write_atomic(&missing_dir).unwrap_err();
    assert!(matches!(error, Error::Io { .. }) && error.to_string().contains("no/such/dir"), "{error}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn empty_and_single_triangle_scenes() {
    let empty = BvhWriter::new(&[], &[]).build().unwrap();
    assert!(empty.view().nodes().is_empty());
    assert_eq!(empty.view().tracer().closest_hit(&random_rays(1, 1, 1.0)[0]), None);
    let one = [[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]];
    let tree = packed_tree(&one, 1);
    assert_eq!(tree.nodes.len(), 1);
    let file = write_file(&tree);
    let hit = file.view().tracer().closest_hit(&bvhc::loader::Ray::new([0.2, 0.3, 2.0], [0.0, 0.0, -1.0])).unwrap();
    assert_eq!((hit.t, hit.triangle_index, hit.source_triangle_id), (2.0, 0, Some(0)));
    assert!((hit.u - 0.2).abs() < 1e-6 && (hit.v - 0.3).abs() < 1e-6, "{hit:?}");
}

#[test]
fn unaligned_bytes_are_refused_with_a_hint_and_copied_by_from_bytes() {
    let file = write_file(&packed_tree(&random_triangles(6, 50, 1.0), 2));
    let mut shifted = vec![0u8; file.as_bytes().len() + 1];
    shifted[1..].copy_from_slice(file.as_bytes());
    let error = BvhView::open(&shifted[1..]).unwrap_err();
    assert!(matches!(error, Error::Misaligned { .. }) && error.to_string().contains("from_bytes"), "{error}");
    let copy = BvhFile::from_bytes(&shifted[1..]).unwrap();
    assert_eq!(copy.view().nodes(), file.view().nodes());
}

#[test]
fn the_writer_refuses_a_tree_that_breaks_a_rule() {
    let tree = packed_tree(&random_triangles(7, 40, 1.0), 1);
    let mut nodes = tree.nodes.clone();
    nodes[3].max[0] += 100.0;
    let error = BvhWriter::new(&nodes, &tree.triangles).build().unwrap_err();
    assert_eq!(error.rule(), Some(Rule::ChildInParent), "{error}");
}

#[test]
fn the_streamed_file_has_the_bytes_of_the_laid_out_one() {
    // The conversion streams sections from their slices (`write_unverified`) instead of laying the file out in
    // memory (`build`); both must give the same bytes, with and without wide sections and for an empty scene.
    for (seed, count) in [(1u64, 0usize), (2, 1), (3, 57), (4, 600)] {
        let triangles = random_triangles(seed, count, 10.0);
        let tree = packed_tree(&triangles, 4);
        let ranges = single_source_range(tree.triangles.len());
        let wide = wide_sections_for(&tree, &triangles);
        for with_wide in [false, true] {
            let mut writer = BvhWriter::new(&tree.nodes, &tree.triangles).triangle_ids(&tree.triangle_ids);
            if count > 0 {
                writer = writer.source_table(&ranges);
            }
            if with_wide && count > 0 {
                writer = writer.metadata(METADATA_1_1).wide(wide.nodes(), wide.packets());
            }
            let laid_out = writer.build().unwrap();
            let mut streamed = Vec::new();
            let byte_len = writer.write_unverified(&mut streamed, std::path::Path::new("memory")).unwrap();
            assert_eq!(byte_len as usize, streamed.len());
            assert!(streamed == laid_out.as_bytes(), "seed {seed}, wide {with_wide}");
        }
    }
}

/// A sink that fails as a full disk does after `room` bytes.
struct FullDisk {
    room: usize,
}

impl std::io::Write for FullDisk {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        if self.room == 0 {
            return Err(std::io::Error::from(std::io::ErrorKind::StorageFull));
        }
        let taken = bytes.len().min(self.room);
        self.room -= taken;
        Ok(taken)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[test]
fn a_full_disk_is_an_io_error_naming_the_output() {
    // The command line maps `Error::Io` to exit 3 (checked by hand on a 1 MiB tmpfs: exit 3, nothing left).
    let triangles = random_triangles(5, 200, 10.0);
    let tree = packed_tree(&triangles, 4);
    let writer = BvhWriter::new(&tree.nodes, &tree.triangles);
    for room in [0, 10, 300] {
        let error = writer.write_unverified(&mut FullDisk { room }, std::path::Path::new("out/scene.bvh")).unwrap_err();
        match &error {
            Error::Io { path, source } => {
                assert_eq!(path, std::path::Path::new("out/scene.bvh"));
                assert_eq!(source.kind(), std::io::ErrorKind::StorageFull);
            }
            other => panic!("room {room}: expected an I/O error, got {other}"),
        }
        assert!(error.to_string().starts_with("out/scene.bvh: "), "{error}");
    }
}
