//! `bvhc render`: a picture of a `.bvh` file through the loader's own traversal kernel, one primary ray per
//! pixel, parallel over rows (deterministic). Shading: the geometric normal as color, lit from the eye; or a
//! heat map of traversal steps per pixel.

use bvhc::loader::{BvhFile, PackedTriangle, Ray, TraversalStats};
use rayon::prelude::*;

use super::args::RenderArgs;
use super::output::print;
use super::{Exit, fail, loader_exit};

type Vec3 = [f32; 3];

fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}
fn dot(a: Vec3, b: Vec3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn normalize(a: Vec3) -> Vec3 {
    let length = dot(a, a).sqrt();
    if length > 0.0 { a.map(|c| c / length) } else { [0.0, 0.0, 1.0] }
}

/// Eye and target: parsed from `--camera`, or looking at the scene's box from above and to the side.
fn camera(args: &RenderArgs, min: Vec3, max: Vec3) -> Result<(Vec3, Vec3), String> {
    if let Some(text) = &args.camera {
        let values: Vec<f32> = text
            .split(',')
            .map(|v| v.trim().parse::<f32>())
            .collect::<Result<_, _>>()
            .map_err(|_| format!("--camera '{text}': expected six numbers ex,ey,ez,tx,ty,tz"))?;
        let [ex, ey, ez, tx, ty, tz] = values[..] else {
            return Err(format!("--camera '{text}': expected six numbers ex,ey,ez,tx,ty,tz"));
        };
        return Ok(([ex, ey, ez], [tx, ty, tz]));
    }
    let center: Vec3 = std::array::from_fn(|a| 0.5 * (min[a] + max[a]));
    let radius = 0.5 * dot(sub(max, min), sub(max, min)).sqrt();
    let direction = normalize([0.9, 0.6, 1.3]);
    // A 45 degree field of view sees a sphere of this radius whole from 2.6 radii; the box rarely fills it.
    Ok((std::array::from_fn(|a| center[a] + direction[a] * radius * 2.0), center))
}

/// A color ramp for the heat map: blue, cyan, green, yellow, red.
fn heat(t: f32) -> Vec3 {
    let t = t.clamp(0.0, 1.0) * 4.0;
    let stops: [Vec3; 5] = [[0.1, 0.1, 0.6], [0.0, 0.7, 0.9], [0.1, 0.8, 0.2], [1.0, 0.9, 0.1], [0.9, 0.1, 0.1]];
    let i = (t as usize).min(3);
    let f = t - i as f32;
    std::array::from_fn(|c| stops[i][c] * (1.0 - f) + stops[i + 1][c] * f)
}

fn shade(triangle: &PackedTriangle, direction: Vec3) -> Vec3 {
    let [v0, v1, v2] = triangle.vertices;
    let mut normal = normalize(cross(sub(v1, v0), sub(v2, v0)));
    if dot(normal, direction) > 0.0 {
        normal = normal.map(|c| -c);
    }
    let light = 0.25 + 0.75 * -dot(normal, direction);
    std::array::from_fn(|c| (0.5 + 0.5 * normal[c]) * light)
}

/// Renders and writes the PNG.
pub fn render(args: &RenderArgs) -> Exit {
    if bvhc::convert::is_same_file(&args.output, &args.file) {
        return fail(
            Exit::Io,
            format!("{}: the output is the input .bvh file; choose another output path", args.output.display()),
        );
    }
    let file = match BvhFile::read(&args.file) {
        Ok(file) => file,
        Err(e) => return fail(loader_exit(&e), format!("{}: {e}", args.file.display())),
    };
    let view = file.view();
    if let Err(v) = view.verify() {
        return fail(Exit::InvalidInput, format!("{}: invalid .bvh file: {v}", args.file.display()));
    }
    let (width, height) = (args.width.clamp(1, 16384) as usize, args.height.clamp(1, 16384) as usize);
    let (min, max) = view.nodes().first().map_or(([0.0; 3], [1.0; 3]), |root| (root.min, root.max));
    let (eye, target) = match camera(args, min, max) {
        Ok(camera) => camera,
        Err(message) => return fail(Exit::InvalidInput, message),
    };
    let forward = normalize(sub(target, eye));
    let right = normalize(cross(forward, [0.0, 1.0, 0.0]));
    let up = cross(right, forward);
    let half_height = (22.5f32).to_radians().tan();
    let half_width = half_height * width as f32 / height as f32;
    let tracer = view.tracer();
    let mut steps = vec![0u32; width * height];
    let mut pixels = vec![0u8; width * height * 3];
    pixels.par_chunks_mut(width * 3).zip(steps.par_chunks_mut(width)).enumerate().for_each(|(y, (row, row_steps))| {
        for x in 0..width {
            let sx = (2.0 * (x as f32 + 0.5) / width as f32 - 1.0) * half_width;
            let sy = (1.0 - 2.0 * (y as f32 + 0.5) / height as f32) * half_height;
            let direction = normalize(std::array::from_fn(|a| forward[a] + sx * right[a] + sy * up[a]));
            let mut stats = TraversalStats::default();
            let hit = tracer.closest_hit_counted(&Ray::new(eye, direction), &mut stats);
            row_steps[x] = stats.node_visits as u32;
            let color = match hit {
                Some(hit) => shade(&view.triangles()[hit.triangle_index as usize], direction),
                None => [0.12, 0.12, 0.14],
            };
            for c in 0..3 {
                row[3 * x + c] = (color[c].clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
            }
        }
    });
    if args.heatmap {
        let most = steps.iter().copied().max().unwrap_or(1).max(1) as f32;
        for (pixel, &s) in pixels.chunks_exact_mut(3).zip(&steps) {
            let color = heat(s as f32 / most);
            for c in 0..3 {
                pixel[c] = (color[c] * 255.0 + 0.5) as u8;
            }
        }
    }
    let mut png_bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut png_bytes, width as u32, height as u32);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let written = encoder.write_header().and_then(|mut writer| writer.write_image_data(&pixels));
    if let Err(error) = written {
        return fail(Exit::Internal, format!("PNG encoding failed: {error}"));
    }
    if let Err(error) = bvhc::loader::write_atomic(&args.output, &png_bytes) {
        return fail(Exit::Io, error);
    }
    let mean = steps.iter().map(|&s| u64::from(s)).sum::<u64>() as f64 / steps.len() as f64;
    let summary =
        format!("{}: {width} x {height}, {mean:.1} traversal steps per pixel on average\n", args.output.display());
    print(&summary, Exit::Success)
}
