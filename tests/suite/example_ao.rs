//! The ambient-occlusion example (`examples/ao.rs`) runs on a fixture and bakes a plausible picture: the
//! teapot's pixels are mostly unoccluded within a fifth of its size (mean well above one half), which spawning
//! secondary rays at the hit point itself (half of them meeting their own triangle) would not give.

use std::process::Command;

use crate::cli::{bvhc, teapot};

#[test]
fn the_ao_example_bakes_the_teapot() {
    // Examples are built beside the test binary's `deps` folder: target/<profile>/examples/ao.
    let exe = std::env::current_exe().unwrap();
    let example = exe.parent().and_then(|deps| deps.parent()).map(|profile| profile.join("examples/ao"));
    let Some(example) = example.filter(|path| path.is_file()) else {
        crate::skips::skipped(
            crate::skips::Needs::Build,
            "the ao example (not built beside the tests; cargo test builds it)",
        );
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let bvh = dir.path().join("teapot.bvh");
    assert!(bvhc(&[&teapot(), &"-o", &bvh, &"-q"]).status.success());
    let png = dir.path().join("ao.png");
    let run = Command::new(&example)
        .arg(&bvh)
        .arg(&png)
        .args(["--width", "160", "--height", "120", "--samples", "16"])
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    assert!(String::from_utf8_lossy(&run.stdout).contains("Mrays/s"));
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&png).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut pixels = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut pixels).unwrap();
    assert_eq!((info.width, info.height), (160, 120));
    // Background pixels are 40; the teapot's are its ambient light.
    let lit: Vec<f64> = pixels.iter().filter(|&&p| p != 40).map(|&p| f64::from(p) / 255.0).collect();
    assert!(lit.len() > 1000, "the teapot covers the picture's middle ({} pixels)", lit.len());
    let mean = lit.iter().sum::<f64>() / lit.len() as f64;
    assert!(mean > 0.75, "mean ambient light {mean}");
}
