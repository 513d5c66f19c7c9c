//! Ambient occlusion of any `.bvh` file, baked into a PNG: what a renderer built on `bvhc-loader` looks like.
//!
//! One camera ray a pixel (traced as coherent packets of 8 neighbouring pixels), then `--samples` cosine-weighted
//! occlusion rays from each hit, spawned with `Tracer::surface(..).spawn(..)`: `t_min = 0` and no epsilon, at any
//! scale; a row's occlusion rays go in one batch call, which traces each 8 rays of one hit (the same origin) as a
//! packet. Rows run in parallel with rayon; the tracer is shared by reference. Pixels are white where nothing is
//! within `--radius` (default: a fifth of the scene's size) above the surface, black where every ray is blocked.
//! The camera looks at the scene's box from the front, a little above and to the right; `--zoom` brings it closer.
//!
//! With `--gltf SCENE.gltf` (the glTF the file was converted from), materials with `alphaMode` `MASK` or `BLEND`
//! cut their triangles out where their base colour's alpha says so ([`cutouts`]): camera and occlusion rays are
//! traced through `Tracer::filtered(&filter, FilterScope::NotOpaque)`, which asks the filter only about the
//! triangles the converter marked not opaque; the rest of the scene traces as without a filter.
//!
//! ```sh
//! bvhc fixtures/scenes/teapot.obj -o teapot.bvh
//! cargo run --release --example ao -- teapot.bvh ao.png [--width 640] [--height 480] [--samples 16]
//! bvhc vase/GlassVaseFlowers.gltf -o vase.bvh
//! cargo run --release --example ao -- vase.bvh vase.png --gltf vase/GlassVaseFlowers.gltf
//! ```

mod cutouts;

use bvhc_loader::Trace;
use std::path::PathBuf;
use std::time::Instant;

use bvhc::loader::{
    BvhFile, BvhView, FilteredTracer, Hit, HitFilter, Ray, Tracer, filter::Candidate, filter::FilterScope,
};
use rand::{RngExt, SeedableRng};
use rayon::prelude::*;

struct Options {
    input: String,
    output: String,
    width: usize,
    height: usize,
    samples: usize,
    radius: Option<f32>,
    zoom: f32,
    gltf: Option<PathBuf>,
}

fn options() -> Result<Options, String> {
    let mut args = std::env::args().skip(1);
    let mut options = Options {
        input: String::new(),
        output: String::new(),
        width: 640,
        height: 480,
        samples: 16,
        radius: None,
        zoom: 1.0,
        gltf: None,
    };
    let mut positional = Vec::new();
    while let Some(arg) = args.next() {
        let mut value = |name: &str| args.next().ok_or_else(|| format!("{name} needs a value"));
        match arg.as_str() {
            "--width" => options.width = value("--width")?.parse().map_err(|e| format!("--width: {e}"))?,
            "--height" => options.height = value("--height")?.parse().map_err(|e| format!("--height: {e}"))?,
            "--samples" => options.samples = value("--samples")?.parse().map_err(|e| format!("--samples: {e}"))?,
            "--radius" => options.radius = Some(value("--radius")?.parse().map_err(|e| format!("--radius: {e}"))?),
            "--zoom" => options.zoom = value("--zoom")?.parse().map_err(|e| format!("--zoom: {e}"))?,
            "--gltf" => options.gltf = Some(value("--gltf")?.into()),
            _ => positional.push(arg),
        }
    }
    let [input, output] = <[String; 2]>::try_from(positional).map_err(
        |_| "usage: ao INPUT.bvh OUTPUT.png [--width W] [--height H] [--samples N] [--radius R] [--zoom Z] [--gltf SOURCE.gltf]",
    )?;
    if options.width == 0 || options.height == 0 || options.samples == 0 {
        return Err("--width, --height and --samples must be at least 1".to_string());
    }
    if !(options.zoom.is_finite() && options.zoom > 0.0) {
        return Err("--zoom must be a positive number".to_string());
    }
    Ok(Options { input, output, ..options })
}

/// Camera rays for a view from outside the scene's box, looking at its center from the front, a little above.
fn camera_rays(min: [f32; 3], max: [f32; 3], zoom: f32, width: usize, height: usize) -> Vec<Ray> {
    let center: [f32; 3] = std::array::from_fn(|a| 0.5 * (min[a] + max[a]));
    let size = (0..3).map(|a| max[a] - min[a]).fold(0.0f32, f32::max) / zoom;
    let eye = [center[0] + 0.6 * size, center[1] + 0.5 * size, center[2] + 1.4 * size];
    let forward = normalize(std::array::from_fn(|a| center[a] - eye[a]));
    let right = normalize(cross(forward, [0.0, 1.0, 0.0]));
    let up = cross(right, forward);
    let half_height = (0.5f32 * 40f32.to_radians()).tan();
    let half_width = half_height * width as f32 / height as f32;
    // In groups of 8 pixels along a row, as the coherent entry point wants them.
    (0..height)
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .map(|(x, y)| {
            let sx = (2.0 * (x as f32 + 0.5) / width as f32 - 1.0) * half_width;
            let sy = (1.0 - 2.0 * (y as f32 + 0.5) / height as f32) * half_height;
            Ray::new(eye, std::array::from_fn(|a| forward[a] + sx * right[a] + sy * up[a]))
        })
        .collect()
}

fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn normalize(v: [f32; 3]) -> [f32; 3] {
    let length = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|c| c / length)
}

/// What the renderer asks of the scene: the plain tracer, or one that filters candidates through cut-outs.
trait Scene: Sync {
    fn tracer(&self) -> &Tracer<'_>;
    fn closest_hits(&self, rays: &[Ray], hits: &mut [Option<Hit>]);
    fn any_hits(&self, rays: &[Ray], occluded: &mut [bool]);
}

impl Scene for Tracer<'_> {
    fn tracer(&self) -> &Tracer<'_> {
        self
    }
    fn closest_hits(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        self.closest_hits_coherent(rays, hits);
    }
    fn any_hits(&self, rays: &[Ray], occluded: &mut [bool]) {
        Trace::any_hits(self, rays, occluded);
    }
}

/// A filtered tracer with the plain one it came from (for `surface`).
struct Filtered<'t, 'a, 'f, F: ?Sized>(&'t Tracer<'a>, FilteredTracer<'a, 'f, F>);

impl<F: HitFilter + Sync + ?Sized> Scene for Filtered<'_, '_, '_, F> {
    fn tracer(&self) -> &Tracer<'_> {
        self.0
    }
    fn closest_hits(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        self.1.closest_hits(rays, hits);
    }
    fn any_hits(&self, rays: &[Ray], occluded: &mut [bool]) {
        self.1.any_hits(rays, occluded);
    }
}

/// Each hit's fraction of `samples` cosine-weighted rays that nothing blocks within `radius`: the rays of every
/// hit of a row traced in one batch call, each hit's rays consecutive and sharing their origin bit for bit (from
/// `spawn`), so the batch call traces each 8 of them as a packet.
fn ambient(scene: &dyn Scene, hits: &[&Hit], samples: usize, radius: f32, rng: &mut rand_pcg::Pcg64Mcg) -> Vec<f32> {
    let mut rays = Vec::with_capacity(hits.len() * samples);
    for hit in hits {
        let surface = scene.tracer().surface(hit).expect("the hit is this tracer's");
        rays.extend((0..samples).map(|_| {
            let direction = surface.cosine_direction([rng.random(), rng.random()]);
            Ray { t_max: radius, ..surface.spawn(direction).expect("a unit direction") }
        }));
    }
    let mut occluded = vec![false; rays.len()];
    scene.any_hits(&rays, &mut occluded);
    occluded.chunks(samples.max(1)).map(|o| o.iter().filter(|&&o| !o).count() as f32 / samples as f32).collect()
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let options = options()?;
    let file = BvhFile::read(&options.input)?;
    let view = file.view();
    let tracer = view.tracer();
    let (pixels, traced, seconds) = match &options.gltf {
        None => render(&tracer, &view, &options)?,
        Some(gltf) => {
            let cutouts = cutouts::Cutouts::read(gltf)?;
            let tests = cutouts.alpha_tests();
            let masks = tests.iter().filter(|(.., test)| matches!(test, cutouts::AlphaTest::Mask { .. })).count();
            println!(
                "{}: {masks} primitives with alphaMode MASK, {} with BLEND (stochastic)",
                gltf.display(),
                tests.len() - masks
            );
            let keeps = |candidate: &Candidate<'_>| cutouts.keeps(&view, candidate);
            render(&Filtered(&tracer, tracer.filtered(&keeps, FilterScope::NotOpaque)), &view, &options)?
        }
    };
    let (width, height) = (options.width, options.height);
    let mut encoder = png::Encoder::new(
        std::io::BufWriter::new(std::fs::File::create(&options.output)?),
        width as u32,
        height as u32,
    );
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.write_header()?.write_image_data(&pixels)?;
    println!(
        "{}: {width}x{height}, {} occlusion rays a hit, {traced} rays in {seconds:.2} s ({:.2} Mrays/s on {} threads)",
        options.output,
        options.samples,
        traced as f64 / seconds / 1e6,
        rayon::current_num_threads()
    );
    Ok(())
}

/// The picture's grey pixels, the number of rays traced and the seconds it took.
fn render(scene: &dyn Scene, view: &BvhView<'_>, options: &Options) -> Result<(Vec<u8>, usize, f64), String> {
    let Some((min, max)) = view.scene_box() else { return Err("the scene is empty".into()) };
    let size = (0..3).map(|a| max[a] - min[a]).fold(0.0f32, f32::max);
    let radius = options.radius.unwrap_or(0.2 * size);
    let (width, height) = (options.width, options.height);
    let rays = camera_rays(min, max, options.zoom, width, height);
    let clock = Instant::now();
    let rows: Vec<(Vec<u8>, usize)> = rays
        .par_chunks(width)
        .enumerate()
        .map(|(y, row)| {
            let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(y as u64);
            let mut hits = vec![None; row.len()];
            scene.closest_hits(row, &mut hits);
            let found: Vec<&Hit> = hits.iter().flatten().collect();
            let traced = row.len() + found.len() * options.samples;
            let mut open = ambient(scene, &found, options.samples, radius, &mut rng).into_iter();
            let pixels = hits
                .iter()
                .map(|hit| match hit {
                    None => 40,
                    Some(_) => (255.0 * open.next().unwrap_or(0.0)) as u8,
                })
                .collect();
            (pixels, traced)
        })
        .collect();
    let seconds = clock.elapsed().as_secs_f64();
    let traced: usize = rows.iter().map(|(_, n)| n).sum();
    Ok((rows.into_iter().flat_map(|(row, _)| row).collect(), traced, seconds))
}
