//! What each pixel's primary ray sees in terms of the method: the antishadow region of its
//! hit point for every portal, and the technique the antishadow mode uses there. The viewer's
//! overlays and pixel inspector read this; it is computed once per scene, camera and size.

use glam::{Vec2, Vec3};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};

use super::integrator::Integrator;
use crate::light::antishadow::Region;
use crate::light::estimator::LightSampler;
use crate::light::sky::SkySampler;
use crate::light::{Strategy, Technique};
use crate::scene::Scene;

/// Per-pixel classification of primary hits, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct PrimaryBuffer {
    pub width: u32,
    pub height: u32,
    /// Area-light portals, then window portals (`scene.portals`, then `scene.windows`).
    pub portal_count: usize,
    /// `regions[pixel * portal_count + j]`: the hit point's region for portal `j` (for a
    /// window: antiantumbra in front of it, where it sees the sky through it, else behind);
    /// `None` where the ray hits nothing.
    pub regions: Vec<Option<Region>>,
    /// The region summarising all portals (the one the antishadow mode weights most).
    pub combined: Vec<Option<Region>>,
    /// The technique the antishadow mode's portal share uses at the hit (`None`: it samples
    /// the light alone, or the pixel sees nothing).
    pub technique: Vec<Option<Technique>>,
    /// Hit points (for the inspector).
    pub points: Vec<Option<Vec3>>,
    /// How many lights carry 90% of the light tree's pick probability at the hit
    /// ([`lights_for_share`]; `None` where the ray hits nothing or no light can be picked).
    pub spread: Vec<Option<u32>>,
}

impl PrimaryBuffer {
    /// `brute_force` classifies each portal's regions with the independent brute-force
    /// classifier instead of the precomputed planes (a debug view: slower, and the two must
    /// agree except within a hair of the planes).
    pub fn compute(scene: &Scene, width: u32, height: u32, brute_force: bool) -> PrimaryBuffer {
        let rows = classified_rows(scene, width, height, brute_force, None);
        Self::from_rows(scene, width, height, rows)
    }

    /// [`Self::compute`], given up (`None`) as soon as `cancel` is set: in a room of many
    /// lights and portals it takes seconds, and a camera move must not wait for it.
    pub fn compute_cancellable(
        scene: &Scene,
        width: u32,
        height: u32,
        brute_force: bool,
        cancel: &AtomicBool,
    ) -> Option<PrimaryBuffer> {
        let rows = classified_rows(scene, width, height, brute_force, Some(cancel));
        (!cancel.load(Ordering::Relaxed)).then(|| Self::from_rows(scene, width, height, rows))
    }

    /// The buffer of the classified pixels, row by row.
    fn from_rows(scene: &Scene, width: u32, height: u32, rows: Vec<Vec<PixelClass>>) -> Self {
        let portal_count = scene.portals.len() + scene.windows.len();
        let n = (width * height) as usize;
        let mut buffer = PrimaryBuffer {
            width,
            height,
            portal_count,
            regions: Vec::with_capacity(n * portal_count),
            combined: Vec::with_capacity(n),
            technique: Vec::with_capacity(n),
            points: Vec::with_capacity(n),
            spread: Vec::with_capacity(n),
        };
        for (point, regions, combined, technique, spread) in rows.into_iter().flatten() {
            buffer.points.push(point);
            buffer.spread.push(spread);
            buffer.regions.extend(regions);
            buffer.combined.push(combined);
            buffer.technique.push(technique);
        }
        buffer
    }

    /// The region of pixel `i` for `portal` (or combined when `None`).
    pub fn region(&self, i: usize, portal: Option<usize>) -> Option<Region> {
        match portal {
            Some(j) if j < self.portal_count => self.regions[i * self.portal_count + j],
            Some(_) => None,
            None => self.combined.get(i).copied().flatten(),
        }
    }

    /// Share of the pixels that see something, per region (indexed like `Region::ALL`).
    pub fn shares(&self, portal: Option<usize>) -> [f32; 5] {
        let mut counts = [0usize; 5];
        let mut total = 0;
        for i in 0..self.combined.len() {
            if let Some(r) = self.region(i, portal) {
                total += 1;
                if let Some(k) = Region::ALL.iter().position(|&a| a == r) {
                    counts[k] += 1;
                }
            }
        }
        counts.map(|c| c as f32 / total.max(1) as f32)
    }
}

/// Every pixel's primary hit classified, a row per image row; rows started after `cancel` is
/// set are left empty.
fn classified_rows(
    scene: &Scene,
    width: u32,
    height: u32,
    brute_force: bool,
    cancel: Option<&AtomicBool>,
) -> Vec<Vec<PixelClass>> {
    let sampler = LightSampler::new(scene, Strategy::Antishadow, None);
    let sky = SkySampler::new(scene, Strategy::Antishadow, None);
    let aspect = width as f32 / height as f32;
    (0..height)
        .into_par_iter()
        .map(|y| {
            if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                return Vec::new();
            }
            (0..width)
                .map(|x| {
                    let ndc = (Vec2::new(x as f32, y as f32) + 0.5)
                        / Vec2::new(width as f32, height as f32);
                    classify_ray(scene, (&sampler, &sky), ndc, aspect, brute_force)
                })
                .collect()
        })
        .collect()
}

/// One pixel: hit point, region per portal, combined region, technique, selection spread.
type PixelClass = (
    Option<Vec3>,
    Vec<Option<Region>>,
    Option<Region>,
    Option<Technique>,
    Option<u32>,
);

/// The share of the pick probability [`PrimaryBuffer::spread`] counts lights for.
pub const SPREAD_SHARE: f32 = 0.9;

/// The fewest lights whose pick probabilities at `x` (normal `n`) sum to `share` of the
/// total: 1 where one light takes nearly every sample, the number of lights where the
/// picks are even. `None` where no light can be picked.
pub fn lights_for_share(sampler: &LightSampler, x: Vec3, n: Vec3, share: f32) -> Option<u32> {
    let mut p: Vec<f32> = sampler
        .tree()
        .probabilities(x, n)
        .into_iter()
        .map(|(_, p)| p)
        .filter(|&p| p > 0.0)
        .collect();
    let total: f32 = p.iter().sum();
    if total.is_nan() || total <= 0.0 {
        return None;
    }
    p.sort_by(|a, b| b.total_cmp(a));
    let mut sum = 0.0;
    for (k, q) in p.iter().enumerate() {
        sum += q;
        if sum >= share * total {
            return Some(k as u32 + 1);
        }
    }
    Some(p.len() as u32)
}

fn classify_ray(
    scene: &Scene,
    (sampler, sky): (&LightSampler, &SkySampler),
    ndc: Vec2,
    aspect: f32,
    brute_force: bool,
) -> PixelClass {
    let (o, d) = scene.camera.ray(ndc, aspect);
    let g = &scene.geometry;
    // Through thin glass, to the surface the path tracer shades behind it.
    let Some(hit) = g.closest_hit_through_panes(o, d, 0.0, f32::INFINITY) else {
        return (
            None,
            vec![None; scene.portals.len() + scene.windows.len()],
            None,
            None,
            None,
        );
    };
    let tri = &g.triangles[hit.triangle as usize];
    let (p, _) = tri.point(hit.bary);
    let ng = tri.geometric_normal();
    // Classify where shading happens: just off the surface, on the camera's side.
    let n = if ng.dot(d) > 0.0 { -ng } else { ng };
    let x = Integrator::offset(p, n, g.scale());
    let classify = |portal: &crate::light::portal::Portal| {
        if brute_force {
            portal.classify_brute_force(x)
        } else {
            portal.planes.classify(x)
        }
    };
    let window_region = |w: &crate::light::window::Window| {
        Some(if w.in_front(x) {
            Region::Antiantumbra
        } else {
            Region::Behind
        })
    };
    let regions: Vec<Option<Region>> = scene
        .portals
        .iter()
        .map(|p| Some(classify(p)))
        .chain(scene.windows.iter().map(window_region))
        .collect();
    let mut best: Option<(f32, Region, Option<Technique>)> = None;
    for light in 0..g.lights.len() {
        let ctx = sampler.context(scene, light, x);
        if !ctx.has_portals {
            continue;
        }
        let top = ctx
            .terms()
            .iter()
            .max_by(|a, b| a.weight.total_cmp(&b.weight));
        let weight = sampler.light_probability(light, x, n) * top.map_or(0.0, |t| t.weight);
        if best.is_none_or(|(w, _, _)| weight > w) {
            best = Some((weight, ctx.region, top.map(|t| t.technique)));
        }
    }
    if scene.environment.is_some() {
        let ctx = sky.context(scene, x);
        if ctx.has_windows {
            let top = ctx
                .terms
                .iter()
                .max_by(|a, b| a.weight.total_cmp(&b.weight));
            let weight = sampler.environment_probability(x, n) * top.map_or(0.0, |t| t.weight);
            if best.is_none_or(|(w, _, _)| weight > w) {
                best = Some((weight, ctx.region, top.map(|t| t.technique.technique())));
            }
        }
    }
    let (combined, technique) = best.map_or((None, None), |(_, r, t)| (Some(r), t));
    let spread = lights_for_share(sampler, x, n, SPREAD_SHARE);
    (Some(p), regions, combined, technique, spread)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A set cancel flag gives the classification up; a clear one gives what `compute` gives.
    #[test]
    fn classification_gives_up_when_cancelled() {
        let scene = Scene::open("lampshade").unwrap();
        let cancelled = AtomicBool::new(true);
        assert!(PrimaryBuffer::compute_cancellable(&scene, 16, 12, false, &cancelled).is_none());
        let clear = AtomicBool::new(false);
        let buffer = PrimaryBuffer::compute_cancellable(&scene, 16, 12, false, &clear).unwrap();
        assert_eq!(buffer, PrimaryBuffer::compute(&scene, 16, 12, false));
        assert_eq!(buffer.spread.len(), 16 * 12);
    }
}
