//! `bvhc render`: a picture of a `.bvh` file through the loader's own traversal kernel, one primary ray per
//! pixel, parallel over rows (deterministic). Shading: the geometric normal as color, lit from the eye; or a
//! heat map of traversal steps per pixel.

use bvhc::loader::{TraversalStats, format::PackedTriangle};
use bvhc_loader::Trace;
use glam::Vec3;
use rayon::prelude::*;

use super::args::RenderArgs;
use super::info::read_verified;
use super::legend::{Canvas, draw_heat_legend};
use super::output::print;
use super::view;
use super::{Exit, fail};

/// A color ramp for the heat map: blue, cyan, green, yellow, red.
pub fn heat(t: f32) -> [f32; 3] {
    let t = t.clamp(0.0, 1.0) * 4.0;
    let stops =
        [[0.1, 0.1, 0.6], [0.0, 0.7, 0.9], [0.1, 0.8, 0.2], [1.0, 0.9, 0.1], [0.9, 0.1, 0.1]].map(Vec3::from_array);
    let i = (t as usize).min(3);
    stops[i].lerp(stops[i + 1], t - i as f32).to_array()
}

/// The geometric normal as a color, lit from the eye.
fn shade(triangle: &PackedTriangle, direction: Vec3) -> [f32; 3] {
    let mut normal = view::geometric_normal(triangle).normalize_or(Vec3::Z);
    if normal.dot(direction) > 0.0 {
        normal = -normal;
    }
    let light = 0.25 + 0.75 * -normal.dot(direction);
    ((0.5 + 0.5 * normal) * light).to_array()
}

/// Renders and writes the PNG.
pub fn render(args: &RenderArgs) -> Exit {
    if bvhc::convert::files::is_same_file(&args.output, &args.file) {
        return fail(
            Exit::Io,
            format!("{}: the output is the input .bvh file; choose another output path", args.output.display()),
        );
    }
    let file = match read_verified(&args.file) {
        Ok(file) => file,
        Err(exit) => return exit,
    };
    let view = file.view();
    let (width, height) = (args.width.clamp(1, 16384) as usize, args.height.clamp(1, 16384) as usize);
    let (min, max) = view.scene_box().map_or((Vec3::ZERO, Vec3::ONE), |(min, max)| (min.into(), max.into()));
    // Camera rays are finite by construction (the camera is checked, the directions normalized); an extreme
    // camera whose rays overflow gets unspecified pixels rather than a panic.
    let tracer = view.tracer().trusting_rays();
    let (camera, inside) = match args.camera {
        Some(camera) => (camera, false),
        None => view::default_camera(&tracer, view.triangles(), min, max),
    };
    let mut steps = vec![0u32; width * height];
    let mut pixels = vec![0u8; width * height * 3];
    pixels.par_chunks_mut(width * 3).zip(steps.par_chunks_mut(width)).enumerate().for_each(|(y, (row, row_steps))| {
        for x in 0..width {
            let ray = camera.primary_ray(x, y, width, height);
            let mut stats = TraversalStats::default();
            let hit = tracer.closest_hit_counted(&ray, &mut stats);
            row_steps[x] = stats.node_visits as u32;
            let color = match hit {
                Some(hit) => shade(&view.triangles()[hit.triangle_index as usize], Vec3::from_array(ray.direction)),
                None => [0.12, 0.12, 0.14],
            };
            for c in 0..3 {
                row[3 * x + c] = (color[c].clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
            }
        }
    });
    let mut legend = String::new();
    if args.heatmap {
        let most = steps.iter().copied().max().unwrap_or(1).max(1);
        for (pixel, &s) in pixels.chunks_exact_mut(3).zip(&steps) {
            let color = heat(s as f32 / most as f32);
            for c in 0..3 {
                pixel[c] = (color[c] * 255.0 + 0.5) as u8;
            }
        }
        let mut canvas = Canvas { pixels: &mut pixels, width, height };
        let drawn = draw_heat_legend(&mut canvas, most, heat);
        legend = format!(
            "; heat map from blue (0 steps) through cyan, green, yellow to red ({most} steps){}",
            if drawn { ", legend at the bottom" } else { "" }
        );
    }
    let mut png_bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut png_bytes, width as u32, height as u32);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let written = encoder.write_header().and_then(|mut writer| writer.write_image_data(&pixels));
    if let Err(error) = written {
        return fail(Exit::Internal, format!("PNG encoding failed: {error}"));
    }
    if let Err(error) = super::output::write_output(&args.output, &png_bytes) {
        return fail(Exit::Io, error);
    }
    let mean = steps.iter().map(|&s| u64::from(s)).sum::<u64>() as f64 / steps.len() as f64;
    let where_from = if inside { "from inside the scene's box" } else { "from outside" };
    let [ex, ey, ez] = camera.eye.to_array();
    let [tx, ty, tz] = camera.target.to_array();
    let summary = format!(
        "{}: {width} x {height}, {mean:.1} traversal steps per pixel on average; camera {where_from}: --camera {ex},{ey},{ez},{tx},{ty},{tz}{legend}\n",
        args.output.display()
    );
    print(&summary, Exit::Success)
}
