//! The skinned-animation example (`examples/skinned`) on the shared Fox: it converts the scene, refits it to
//! each posed frame (positions per source vertex), and writes the frames and an animated PNG of them; the
//! frames differ (the fox runs) and each shows it; with a tree per part of the clip (`--parts`), switched as it
//! plays, the same images. SKIPPED without the shared scenes.

use std::process::Command;

fn decode(path: &std::path::Path) -> (png::Info<'static>, Vec<u8>) {
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
    reader.next_frame(&mut pixels).unwrap();
    (reader.info().clone(), pixels)
}

#[test]
fn the_skinned_example_refits_and_renders_each_frame_of_the_fox() {
    let exe = std::env::current_exe().unwrap();
    let example = exe.parent().and_then(|deps| deps.parent()).map(|profile| profile.join("examples/skinned"));
    let Some(example) = example.filter(|path| path.is_file()) else {
        crate::skips::skipped(crate::skips::Needs::Build, "the skinned example (not built beside the tests)");
        return;
    };
    let Some(fox) = crate::common::scene("khr-fox/Fox.gltf") else { return };
    let dir = tempfile::tempdir().unwrap();
    let run = Command::new(&example)
        .arg(&fox)
        .arg(dir.path())
        .args(["--clip", "2", "--frames", "4", "--width", "64", "--height", "48"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{}{stdout}", String::from_utf8_lossy(&run.stderr));
    assert_eq!(stdout.lines().filter(|l| l.starts_with("frame ") && l.contains("refit")).count(), 4, "{stdout}");
    assert!(stdout.contains("refit: median") && stdout.contains("576 triangles"), "{stdout}");
    let frames: Vec<Vec<u8>> = (0..4).map(|k| decode(&dir.path().join(format!("frame-{k:03}.png"))).1).collect();
    for frame in &frames {
        let lit = frame.iter().filter(|&&p| p != 40).count();
        assert!(lit > 50 && lit < frame.len() / 2, "the fox fills part of the frame ({lit} pixels)");
    }
    assert!(frames.windows(2).all(|pair| pair[0] != pair[1]), "each frame poses the fox anew");
    let (info, first) = decode(&dir.path().join("animation.png"));
    assert_eq!(info.animation_control().map(|a| a.num_frames), Some(4));
    assert_eq!(first, frames[0]);
    // A tree per third of the clip, switched as it plays: each frame names its part, and the images are the
    // same (the same triangles in every tree; ties decided by the format's rule, not by the tree).
    let parts = tempfile::tempdir().unwrap();
    let run = Command::new(&example)
        .arg(&fox)
        .arg(parts.path())
        .args(["--clip", "2", "--frames", "4", "--parts", "3", "--width", "64", "--height", "48"])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{}{stdout}", String::from_utf8_lossy(&run.stderr));
    let used: Vec<&str> =
        stdout.lines().filter_map(|l| l.split(": part ").nth(1)).filter_map(|l| l.split(':').next()).collect();
    assert_eq!(used, ["0", "0", "1", "2"], "{stdout}");
    for k in 0..3 {
        let part = bvhc::loader::BvhFile::read(parts.path().join(format!("scene-part{k}.bvh"))).unwrap();
        let metadata: serde_json::Value = serde_json::from_str(part.view().metadata_str().unwrap().unwrap()).unwrap();
        assert!(metadata["build"]["animation"]["window"].is_object(), "part {k} records its window");
    }
    let switched: Vec<Vec<u8>> = (0..4).map(|k| decode(&parts.path().join(format!("frame-{k:03}.png"))).1).collect();
    assert_eq!(switched, frames, "the same images with the parts' trees");
}
