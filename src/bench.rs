//! `portalview bench`: raw obvhs traversal against the whole renderer, and the cost of each
//! strategy, on the built-in scenes. Multithreaded like the renderer, so the rays/s compare.

use anyhow::Result;
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::time::{Duration, Instant};

use crate::cli::{BenchArgs, render_for};
use crate::light::Strategy;
use crate::render::integrator::{Integrator, RenderSettings};
use crate::sampling::Rng;
use crate::scene::{Scene, builtin};

/// Rays for the raw measurement: the camera's primary rays, and shadow rays from their hits
/// towards random points on the lights.
struct RaySet {
    primary: Vec<(Vec3, Vec3)>,
    shadow: Vec<(Vec3, Vec3, f32)>,
}

fn ray_set(scene: &Scene, size: u32) -> RaySet {
    let g = &scene.geometry;
    let mut rng = Rng::new(1, 2);
    let mut primary = Vec::new();
    let mut shadow = Vec::new();
    for y in 0..size {
        for x in 0..size {
            let ndc = (Vec2::new(x as f32, y as f32) + rng.uniform2()) / size as f32;
            let (o, d) = scene.camera.ray(ndc, 1.0);
            primary.push((o, d));
            let Some(hit) = g.bvh.closest_hit(o, d, 0.0, f32::INFINITY) else {
                continue;
            };
            let p = o + d * hit.t * 0.9999;
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
    RaySet { primary, shadow }
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
        let closest = rays_per_second(&rays.primary, budget, |&(o, d)| {
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
