//! A skinned glTF animated by refitting its `.bvh` each frame: what a renderer of characters does with bvhc.
//!
//! The scene is converted once with `--animation` for the clip it plays (the tree chosen for the clip's sampled
//! poses: flattened, without split references, as the refit needs), then for each frame the example poses the glTF itself ([`pose`]: animation channels, joint hierarchy,
//! linear-blend skinning), hands the posed vertices of each primitive to `BvhFile::refit` as positions per
//! source vertex (the file's `source_vertices` section maps them to its records), and renders the frame with
//! the loader's tracer: shaded by the geometric normal. Each frame is written as a PNG and all of them as one
//! animated PNG; the refit time, the refit tree's cost ratio and whether `RebuildPolicy` would convert anew (it
//! reads the ratio the clip's sampled poses were planned to reach) are printed per frame.
//!
//! With `--parts N` the clip is cut into `N` equal parts and converted once per part (`--animation-window` of
//! the part, stored in the pose of its middle): each frame refits and traces the tree of the part its time falls
//! in, switching trees as the clip plays (for deformations too large for one tree: `docs/animation.md`). The
//! frames are the same images: every tree holds the same triangles, and ties between hits are decided by the
//! format's rule, not by the tree.
//!
//! ```sh
//! cargo run --release --example skinned -- Fox/Fox.gltf frames/ [--clip 1] [--frames 24] [--parts 1] [--width 320] [--height 240]
//! ```

mod pose;

use std::path::{Path, PathBuf};
use std::time::Instant;

use bvhc::animation::{Animation, TimeWindow};
use bvhc::import::{ClipSelector, Pose, PoseSelector};
use bvhc::loader::{BvhFile, Hit, Ray, RebuildPolicy, RefitPositions, Trace};
use bvhc::options::Overrides;

struct Options {
    input: PathBuf,
    output: PathBuf,
    clip: usize,
    frames: usize,
    parts: usize,
    width: usize,
    height: usize,
    threads: usize,
}

fn options() -> Result<Options, String> {
    let mut args = std::env::args().skip(1);
    let threads = std::thread::available_parallelism().map_or(1, usize::from);
    let mut options = Options {
        input: PathBuf::new(),
        output: PathBuf::new(),
        clip: 0,
        frames: 24,
        parts: 1,
        width: 320,
        height: 240,
        threads,
    };
    let mut positional = Vec::new();
    while let Some(arg) = args.next() {
        let mut number = |name: &str| -> Result<usize, String> {
            args.next().ok_or(format!("{name} needs a value"))?.parse().map_err(|e| format!("{name}: {e}"))
        };
        match arg.as_str() {
            "--clip" => options.clip = number("--clip")?,
            "--frames" => options.frames = number("--frames")?,
            "--parts" => options.parts = number("--parts")?,
            "--width" => options.width = number("--width")?,
            "--height" => options.height = number("--height")?,
            "--threads" => options.threads = number("--threads")?,
            _ => positional.push(arg),
        }
    }
    let [input, output] = <[String; 2]>::try_from(positional).map_err(
        |_| "usage: skinned SCENE.gltf OUTPUT_DIR [--clip K] [--frames N] [--parts N] [--width W] [--height H] [--threads T]",
    )?;
    if options.frames == 0 || options.parts == 0 || options.width == 0 || options.height == 0 {
        return Err("--frames, --parts, --width and --height must be at least 1".to_string());
    }
    Ok(Options { input: input.into(), output: output.into(), ..options })
}

/// Rays from a camera in front of the box `min..max`, a little above, one a pixel, rows top down.
fn camera_rays(min: [f32; 3], max: [f32; 3], width: usize, height: usize) -> Vec<Ray> {
    let centre: [f32; 3] = std::array::from_fn(|a| 0.5 * (min[a] + max[a]));
    let size = (0..3).map(|a| max[a] - min[a]).fold(0.0f32, f32::max).max(f32::MIN_POSITIVE);
    let eye = [centre[0] + 0.3 * size, centre[1] + 0.2 * size, centre[2] + 1.35 * size];
    let forward = normalize(std::array::from_fn(|a| centre[a] - eye[a]));
    let right = normalize(cross(forward, [0.0, 1.0, 0.0]));
    let up = cross(right, forward);
    let half = 0.42f32;
    let aspect = width as f32 / height as f32;
    (0..width * height)
        .map(|p| {
            let x = ((p % width) as f32 + 0.5) / width as f32 * 2.0 - 1.0;
            let y = 1.0 - ((p / width) as f32 + 0.5) / height as f32 * 2.0;
            let d = std::array::from_fn(|a| forward[a] + half * (x * aspect * right[a] + y * up[a]));
            Ray::new(eye, normalize(d))
        })
        .collect()
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn normalize(v: [f32; 3]) -> [f32; 3] {
    let length = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(f32::MIN_POSITIVE);
    v.map(|c| c / length)
}

/// A grey level for a hit: lit by a light above the camera's right, by the unit normal's cosine, both sides.
fn shade(hit: &Option<Hit>) -> u8 {
    let Some(hit) = hit else { return 40 };
    let n = normalize(hit.normal);
    let light = normalize([0.5, 0.8, 0.6]);
    let cosine = (n[0] * light[0] + n[1] * light[1] + n[2] * light[2]).abs();
    (70.0 + 185.0 * cosine) as u8
}

/// The animated PNG of `frames` (grey, `width` x `height`), 12 frames a second, looping.
fn write_animation(path: &Path, frames: &[Vec<u8>], width: usize, height: usize) -> Result<(), String> {
    let file = std::fs::File::create(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width as u32, height as u32);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_animated(frames.len() as u32, 0).map_err(|e| e.to_string())?;
    encoder.set_frame_delay(1, 12).map_err(|e| e.to_string())?;
    let mut writer = encoder.write_header().map_err(|e| e.to_string())?;
    for frame in frames {
        writer.write_image_data(frame).map_err(|e| e.to_string())?;
    }
    writer.finish().map_err(|e| e.to_string())
}

/// One frame as a PNG.
fn write_frame(path: &Path, pixels: &[u8], width: usize, height: usize) -> Result<(), String> {
    let file = std::fs::File::create(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut encoder = png::Encoder::new(std::io::BufWriter::new(file), width as u32, height as u32);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.write_header().and_then(|mut w| w.write_image_data(pixels)).map_err(|e| e.to_string())
}

/// The scene converted for its clip: one tree for the whole clip, or with `parts > 1` one per equal part of it
/// (the part's window sampled, stored in the pose of its middle), with each part's first time.
fn convert(options: &Options) -> Result<Vec<(f64, BvhFile)>, Box<dyn std::error::Error>> {
    let clip = ClipSelector::Index(options.clip);
    let whole = Animation { clips: vec![clip.clone()], ..Animation::default() };
    if options.parts == 1 {
        let bvh = options.output.join("scene.bvh");
        let overrides = Overrides { animation: Some(whole), ..Overrides::default() };
        bvhc::Conversion::new(&options.input, &bvh).overrides(overrides).run()?;
        return Ok(vec![(f64::NEG_INFINITY, BvhFile::read(&bvh)?)]);
    }
    let clips = bvhc::import::animation_clips(&options.input, &Default::default())?;
    let span = clips.get(options.clip).ok_or(format!("the file has {} animation clips", clips.len()))?;
    let time = |share: f64| span.start + (span.end - span.start) * share;
    let mut parts = Vec::with_capacity(options.parts);
    for k in 0..options.parts {
        let window = TimeWindow {
            start: time(k as f64 / options.parts as f64),
            end: time((k + 1) as f64 / options.parts as f64),
        };
        let middle = PoseSelector { clip: clip.clone(), seconds: (window.start + window.end) / 2.0 };
        let animation = Animation { window: Some(window), ..whole.clone() };
        let overrides =
            Overrides { animation: Some(animation), pose: Some(Pose::Clip(middle)), ..Overrides::default() };
        let bvh = options.output.join(format!("scene-part{k}.bvh"));
        bvhc::Conversion::new(&options.input, &bvh).overrides(overrides).run()?;
        parts.push((if k == 0 { f64::NEG_INFINITY } else { window.start }, BvhFile::read(&bvh)?));
    }
    Ok(parts)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let options = options()?;
    std::fs::create_dir_all(&options.output)?;
    let mut parts = convert(&options)?;
    let scene = pose::Scene::read(&options.input, options.clip)?;
    if let Some(note) = &scene.note {
        println!("note: {note}");
    }
    // Every part's file holds the same triangles from the same source ranges, so one set of positions per source
    // vertex refits any of them.
    let ranges = parts[0].1.view().source_table().ok_or("the file has no source table")?.to_vec();
    let triangle_count = parts[0].1.view().triangles().len();
    // Every frame's positions first: the camera frames the whole animation.
    let mut poses = Vec::with_capacity(options.frames);
    for frame in 0..options.frames {
        let time = scene.duration * frame as f32 / options.frames as f32;
        let world = scene.pose(time);
        let positions: Vec<Option<Vec<[f32; 3]>>> = ranges
            .iter()
            .map(|r| scene.positions(r.node_index as usize, r.mesh_index as usize, r.primitive_index as usize, &world))
            .collect();
        poses.push((time, positions));
    }
    let (mut min, mut max) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in poses.iter().flat_map(|(_, ranges)| ranges.iter().flatten().flatten()) {
        min = std::array::from_fn(|a| min[a].min(p[a]));
        max = std::array::from_fn(|a| max[a].max(p[a]));
    }
    let rays = camera_rays(min, max, options.width, options.height);
    let mut frames = Vec::with_capacity(options.frames);
    let mut refit_times = Vec::with_capacity(options.frames);
    for (frame, (time, positions)) in poses.iter().enumerate() {
        // The tree of the part this time falls in: the last part that starts at or before it.
        let part = parts.iter().rposition(|(start, _)| *start <= f64::from(*time)).unwrap_or(0);
        let file = &mut parts[part].1;
        let slices: Vec<Option<&[[f32; 3]]>> = positions.iter().map(|p| p.as_deref()).collect();
        let start = Instant::now();
        let report = file.refit(RefitPositions::SourceVertices(&slices), options.threads)?;
        let refit_ms = start.elapsed().as_secs_f64() * 1e3;
        refit_times.push(refit_ms);
        let start = Instant::now();
        let mut hits = vec![None; rays.len()];
        file.view().tracer().closest_hits(&rays, &mut hits);
        let pixels: Vec<u8> = hits.iter().map(shade).collect();
        let render_ms = start.elapsed().as_secs_f64() * 1e3;
        write_frame(&options.output.join(format!("frame-{frame:03}.png")), &pixels, options.width, options.height)?;
        let rebuild = if RebuildPolicy::DEFAULT.should_rebuild(&report) { ", rebuild" } else { "" };
        let of_part = if options.parts > 1 { format!(" part {part}:") } else { String::new() };
        println!(
            "frame {frame:3} (t = {time:.2} s):{of_part} refit {refit_ms:.3} ms (cost ratio {:.3}, planned {:.3}{rebuild}), \
             render {render_ms:.1} ms",
            report.cost_ratio(),
            report.planned_cost_ratio.unwrap_or(1.0)
        );
        frames.push(pixels);
    }
    write_animation(&options.output.join("animation.png"), &frames, options.width, options.height)?;
    refit_times.sort_by(f64::total_cmp);
    println!(
        "refit: median {:.3} ms a frame for {triangle_count} triangles on {} threads; {} frames in {}",
        refit_times[refit_times.len() / 2],
        options.threads,
        frames.len(),
        options.output.join("animation.png").display()
    );
    Ok(())
}
