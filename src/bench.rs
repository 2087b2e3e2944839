//! `portalview bench`: raw obvhs traversal against the whole renderer, and the cost of each
//! strategy, on the built-in scenes. Multithreaded like the renderer, so the rays/s compare.

use anyhow::Result;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::time::{Duration, Instant};

use crate::cli::{BenchArgs, render_for};
use crate::light::Strategy;
use crate::render::integrator::{Integrator, RenderSettings};
use crate::sampling::{Frame, Rng, sample_cosine_hemisphere};
use crate::scene::{Scene, builtin};

/// Rays for the raw measurement, of the kinds the renderer traces: the camera's primary rays
/// and cosine-distributed bounce rays from their hits (closest hit), and shadow rays from the
/// hits towards random points on the lights (occlusion).
struct RaySet {
    closest: Vec<(Vec3, Vec3)>,
    shadow: Vec<(Vec3, Vec3, f32)>,
}

fn ray_set(scene: &Scene, size: u32) -> RaySet {
    let g = &scene.geometry;
    let mut rng = Rng::new(1, 2);
    let mut closest = Vec::new();
    let mut shadow = Vec::new();
    for y in 0..size {
        for x in 0..size {
            let ndc = (Vec2::new(x as f32, y as f32) + rng.uniform2()) / size as f32;
            let (o, d) = scene.camera.ray(ndc, 1.0);
            closest.push((o, d));
            let Some(hit) = g.bvh.closest_hit(o, d, 0.0, f32::INFINITY) else {
                continue;
            };
            let tri = &g.triangles[hit.triangle as usize];
            let ng = tri.geometric_normal();
            let ng = if ng.dot(d) > 0.0 { -ng } else { ng };
            let p = Integrator::offset(o + d * hit.t, ng);
            let bounce = Frame::from_normal(ng).to_world(sample_cosine_hemisphere(rng.uniform2()));
            closest.push((p, bounce));
            let light = &g.lights[(rng.next_u32() as usize) % g.lights.len().max(1)];
            if let Some(y) = light.sample_point(rng.uniform2()) {
                let v = y.p - p;
                let dist = v.length();
                if dist > 0.0 {
                    shadow.push((p, v / dist, dist * 0.9999));
                }
            }
        }
    }
    RaySet { closest, shadow }
}

/// Rays per second of `trace` over `rays`, repeated for `budget`, on all cores.
fn rays_per_second<T: Sync>(rays: &[T], budget: Duration, trace: impl Fn(&T) -> f32 + Sync) -> f64 {
    let start = Instant::now();
    let mut count = 0usize;
    let mut sink = 0.0f32;
    while start.elapsed() < budget {
        sink += rays
            .par_chunks(1024)
            .map(|c| c.iter().map(&trace).sum::<f32>())
            .sum::<f32>();
        count += rays.len();
    }
    // Keep the traversal from being optimised away.
    std::hint::black_box(sink);
    count as f64 / start.elapsed().as_secs_f64()
}

pub fn run(args: &BenchArgs) -> Result<()> {
    let budget = Duration::from_secs_f64(args.seconds);
    println!(
        "portalview bench: {} threads, {}x{} px, {:.1} s per measurement",
        rayon::current_num_threads(),
        args.size,
        args.size,
        args.seconds
    );
    println!();
    println!(
        "| scene | triangles | raw closest-hit Mrays/s | raw occlusion Mrays/s | raw mix Mrays/s | renderer (light) Mrays/s | renderer / raw mix |"
    );
    println!("|---|---|---|---|---|---|---|");
    for name in builtin::NAMES {
        let scene = Scene::open(name)?;
        let bvh = &scene.geometry.bvh;
        let rays = ray_set(&scene, args.size);
        let closest = rays_per_second(&rays.closest, budget, |&(o, d)| {
            bvh.raw_closest_t(o.into(), d.into()).min(1e30)
        });
        let occlusion = rays_per_second(&rays.shadow, budget, |&(o, d, t)| {
            bvh.occluded(o, d, 0.0, t) as u8 as f32
        });
        // Compare like with like: the renderer's own mix of ray kinds, at raw speed.
        let integrator = Integrator::new(
            &scene,
            RenderSettings {
                strategy: Strategy::Light,
                ..RenderSettings::default()
            },
        );
        let (_, stats, elapsed) = render_for(&integrator, args.size, args.size, budget);
        let renderer = stats.rays() as f64 / elapsed.as_secs_f64();
        let closest_share =
            (stats.camera_rays + stats.bounce_rays) as f64 / stats.rays().max(1) as f64;
        let raw_mix = 1.0 / (closest_share / closest + (1.0 - closest_share) / occlusion);
        println!(
            "| {name} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.0}% |",
            bvh.triangle_count(),
            closest / 1e6,
            occlusion / 1e6,
            raw_mix / 1e6,
            renderer / 1e6,
            100.0 * renderer / raw_mix
        );
    }
    println!();
    println!("| scene | strategy | M samples/s | ns per light sample | shadow rays per sample |");
    println!("|---|---|---|---|---|");
    for name in builtin::NAMES {
        let scene = Scene::open(name)?;
        for strategy in Strategy::ALL {
            let integrator = Integrator::new(
                &scene,
                RenderSettings {
                    strategy,
                    ..RenderSettings::default()
                },
            );
            let (film, stats, elapsed) = render_for(&integrator, args.size, args.size, budget);
            let samples = film.spp as f64 * film.pixel_count() as f64;
            println!(
                "| {name} | {} | {:.3} | {:.0} | {:.2} |",
                strategy.name(),
                samples / elapsed.as_secs_f64() / 1e6,
                stats.sampling_ns as f64 / stats.light_samples().max(1) as f64,
                stats.shadow_rays as f64 / samples,
            );
        }
    }
    Ok(())
}

/// The viewer, headless: egui frames at 60 Hz on a 1280×800 screen while the worker renders
/// the lampshade with every core, then portal edits timed to their first preview frame.
pub fn run_ui(args: &BenchArgs) -> Result<()> {
    use crate::app::PortalViewApp;
    let ctx = egui::Context::default();
    let mut app = PortalViewApp::new(&ctx, None, Some("lampshade".into()))?;
    let input = || egui::RawInput {
        screen_rect: Some(egui::Rect::from_min_size(
            egui::Pos2::ZERO,
            egui::vec2(1280.0, 800.0),
        )),
        ..Default::default()
    };
    // One UI frame: layout and painting (`show`), then tessellation, as eframe does before
    // handing triangles to the GPU.
    let frame = |app: &mut PortalViewApp| {
        let start = Instant::now();
        let output = ctx.run_ui(input(), |ui| app.show(ui));
        std::hint::black_box(ctx.tessellate(output.shapes, output.pixels_per_point));
        start.elapsed()
    };
    let warm = Instant::now();
    while app.frame().is_none_or(|f| f.preview) && warm.elapsed() < Duration::from_secs(30) {
        frame(&mut app);
        std::thread::sleep(Duration::from_millis(16));
    }
    let budget = Duration::from_secs_f64(args.seconds.max(1.0));
    let mut times = Vec::new();
    let start = Instant::now();
    while start.elapsed() < budget {
        times.push(frame(&mut app).as_secs_f64() * 1e3);
        std::thread::sleep(Duration::from_millis(16));
    }
    times.sort_by(f64::total_cmp);
    let spp = app.frame().map_or(0, |f| f.spp);
    println!(
        "UI frame time over {} frames while rendering ({spp} spp reached): mean {:.2} ms, median {:.2} ms, 95th percentile {:.2} ms, max {:.2} ms",
        times.len(),
        times.iter().sum::<f64>() / times.len().max(1) as f64,
        percentile(&times, 0.5),
        percentile(&times, 0.95),
        percentile(&times, 1.0),
    );
    // Portal edits: nudge the top portal and wait for the preview of the new placement.
    let mut latencies = Vec::new();
    for k in 0..20 {
        let Some(mut pose) = app.editor.pose(0) else {
            break;
        };
        pose.center.x += if k % 2 == 0 { 0.01 } else { -0.01 };
        app.editor.set_pose(0, pose);
        app.apply_portal_edit();
        app.first_frame_latency = None;
        let edited = Instant::now();
        while app.first_frame_latency.is_none() && edited.elapsed() < Duration::from_secs(10) {
            frame(&mut app);
            std::thread::sleep(Duration::from_millis(2));
        }
        latencies.push(edited.elapsed().as_secs_f64() * 1e3);
        // Let full-resolution passes run between edits, as between a user's drags.
        let settle = Instant::now();
        while settle.elapsed() < Duration::from_millis(300) {
            frame(&mut app);
            std::thread::sleep(Duration::from_millis(16));
        }
    }
    latencies.sort_by(f64::total_cmp);
    println!(
        "portal edit to first preview over {} edits: median {:.1} ms, 95th percentile {:.1} ms, max {:.1} ms",
        latencies.len(),
        percentile(&latencies, 0.5),
        percentile(&latencies, 0.95),
        percentile(&latencies, 1.0),
    );
    Ok(())
}

/// The `q` quantile of sorted values (nearest rank).
fn percentile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    sorted[((q * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len()) - 1]
}
