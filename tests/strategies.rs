//! The portal method's strategies (METHOD.md, "Correctness checks every strategy must pass"):
//! the mixture pdf integrates to the covered fraction, each technique's sampled density equals
//! its evaluated density, samples pass a chi-square test against the pdf, every strategy's image
//! agrees with light sampling (also with a misplaced portal, which alpha = 0 must break), and
//! the plane classifier agrees with brute force on the built-in scenes. Run in release.

mod common;

use glam::{Vec2, Vec3};
use portalview::asset::builtin;
use portalview::light::antishadow::{Region, classify_brute_force};
use portalview::light::estimator::{LightContext, LightSampler, portal_pdf, term_pdf};
use portalview::light::{Strategy, Technique};
use portalview::render::film::Film;
use portalview::render::integrator::{Integrator, RenderSettings};
use portalview::render::render;
use portalview::sampling::{Frame, Rng};
use portalview::scene::Scene;

/// A cone of directions from `x` containing every direction to `points` (plus a margin), sampled
/// uniformly: it covers the support of every technique for a light and its portals.
struct Cone {
    frame: Frame,
    cos_max: f32,
}

impl Cone {
    fn around(x: Vec3, points: &[Vec3]) -> Cone {
        let dirs: Vec<Vec3> = points.iter().map(|p| (*p - x).normalize()).collect();
        let axis = dirs.iter().copied().sum::<Vec3>().normalize();
        let half = dirs
            .iter()
            .map(|d| d.dot(axis).clamp(-1.0, 1.0).acos())
            .fold(0.0, f32::max);
        let half = (half * 1.05 + 1e-3).min(std::f32::consts::FRAC_PI_2 * 0.99);
        Cone {
            frame: Frame::from_normal(axis),
            cos_max: half.cos(),
        }
    }
    fn solid_angle(&self) -> f64 {
        std::f64::consts::TAU * (1.0 - self.cos_max as f64)
    }
    /// `u` in [0,1)²: uniform in solid angle (cos θ uniform, φ uniform).
    fn direction(&self, u: Vec2) -> Vec3 {
        let cos = 1.0 - u.x * (1.0 - self.cos_max);
        let sin = (1.0 - cos * cos).max(0.0).sqrt();
        let phi = std::f32::consts::TAU * u.y;
        self.frame
            .to_world(Vec3::new(sin * phi.cos(), sin * phi.sin(), cos))
    }
    /// The equal-solid-angle cell (of `n × n`) a direction falls in, if inside the cone.
    fn cell(&self, w: Vec3, n: usize) -> Option<usize> {
        let l = self.frame.to_local(w);
        if l.z < self.cos_max {
            return None;
        }
        let a = ((1.0 - l.z) / (1.0 - self.cos_max) * n as f32) as usize;
        let phi = l.y.atan2(l.x).rem_euclid(std::f32::consts::TAU);
        let b = (phi / std::f32::consts::TAU * n as f32) as usize;
        Some(a.min(n - 1) * n + b.min(n - 1))
    }
}

/// The vertices of the context's light and of the portals its terms use: the cone through
/// them holds the pdf's support and no more, so that its cells resolve the pdf.
fn support_points(scene: &Scene, ctx: &LightContext) -> Vec<Vec3> {
    let mut points: Vec<Vec3> = scene.geometry.lights[ctx.light]
        .polygon
        .as_ref()
        .unwrap()
        .vertices()
        .to_vec();
    for t in &ctx.terms {
        points.extend(scene.portals[t.portal].polygon.vertices());
    }
    points
}

/// The mixture pdf of the direction `w`.
fn q(sampler: &LightSampler, scene: &Scene, ctx: &LightContext, w: Vec3) -> f32 {
    let hit = sampler.light_hit(scene, ctx.light, ctx.x, w);
    sampler.pdf(scene, ctx, w, hit)
}

/// Points of `scene` in each region of portal 0, found by random search below the portal.
fn points_by_region(scene: &Scene, seed: u64) -> Vec<(Region, Vec3)> {
    let mut rng = Rng::new(seed, 9);
    let (lo, hi) = scene.geometry.bounds;
    let mut found: Vec<(Region, Vec3)> = Vec::new();
    for _ in 0..200_000 {
        let x = lo + (hi - lo) * Vec3::new(rng.uniform(), rng.uniform(), rng.uniform());
        let planes = &scene.portals[0].planes;
        let region = planes.classify(x);
        // Keep clear of region borders, where f32 round-off may flip the answer.
        if planes.planes_distance(x) < 1e-2 || found.iter().any(|(r, _)| *r == region) {
            continue;
        }
        found.push((region, x));
    }
    found
}

/// The scenes and points every check below runs on.
fn cases() -> Vec<(String, Scene, Region, Vec3)> {
    let mut cases = vec![];
    for (i, name) in builtin::NAMES.iter().enumerate() {
        let scene = Scene::open(name).unwrap();
        for (region, x) in points_by_region(&scene, i as u64) {
            if region != Region::Behind {
                cases.push((name.to_string(), scene.clone(), region, x));
            }
        }
    }
    let regions: Vec<Region> = cases.iter().map(|c| c.2).collect();
    for r in [
        Region::Outside,
        Region::Antiumbra,
        Region::Antipenumbra,
        Region::Antiantumbra,
    ] {
        assert!(regions.contains(&r), "no test point in {}", r.name());
    }
    cases
}

/// `∫ q dω` is 1 where some portal term exists or portals are unused, and alpha at a point in
/// front of portals but outside every antishadow (the covered fraction). Estimated by stratified
/// uniform directions over a cone holding the support; tolerance 4 standard errors.
#[test]
fn mixture_pdf_integrates_to_covered_fraction() {
    for (name, scene, region, x) in cases() {
        for strategy in Strategy::ALL {
            let sampler = LightSampler::new(&scene, strategy, None);
            let ctx = sampler.context(&scene, 0, x);
            let cone = Cone::around(x, &support_points(&scene, &ctx));
            let n = 400;
            let values: Vec<f64> = (0..n * n)
                .map(|i| {
                    let mut rng = Rng::keyed(1, &[i as u64]);
                    let u = (Vec2::new((i % n) as f32, (i / n) as f32) + rng.uniform2()) / n as f32;
                    q(&sampler, &scene, &ctx, cone.direction(u)) as f64 * cone.solid_angle()
                })
                .collect();
            let (integral, se) = common::mean_and_se(&values);
            let expected = if ctx.uses_portals && ctx.terms.is_empty() {
                ctx.alpha as f64
            } else {
                1.0
            };
            // Stratification makes the plain standard error conservative.
            assert!(
                (integral - expected).abs() <= 4.0 * se + 2e-3,
                "{name} {} {}: ∫q = {integral} ± {se}, expected {expected}",
                region.name(),
                strategy.name()
            );
        }
    }
}

/// The density each technique reports while sampling equals its density evaluated for the
/// sampled direction (by ray intersection, or the spherical polygon's test).
#[test]
fn sampled_pdf_equals_evaluated_pdf() {
    for (name, scene, region, x) in cases() {
        for strategy in Strategy::ALL {
            let sampler = LightSampler::new(&scene, strategy, None);
            let ctx = sampler.context(&scene, 0, x);
            let mut rng = Rng::new(3, 4);
            for _ in 0..2000 {
                let Some(s) = sampler.sample(&scene, &ctx, rng.uniform(), rng.uniform2()) else {
                    continue;
                };
                let hit = sampler.light_hit(&scene, ctx.light, x, s.wi);
                let p_light = sampler.light_pdf(&scene, ctx.light, s.wi, hit);
                let evaluated: Vec<f32> = match s.technique {
                    Technique::Light => vec![p_light],
                    _ => ctx
                        .terms
                        .iter()
                        .filter(|t| t.technique == s.technique)
                        .map(|t| term_pdf(&scene, x, t, p_light, s.wi))
                        .collect(),
                };
                let ok = evaluated
                    .iter()
                    .any(|&e| (e - s.technique_pdf).abs() <= 2e-3 * e.max(s.technique_pdf));
                assert!(
                    ok,
                    "{name} {} {} {}: sampled {} vs evaluated {evaluated:?}",
                    region.name(),
                    strategy.name(),
                    s.technique.name(),
                    s.technique_pdf
                );
                assert!(s.pdf.is_finite() && s.pdf > 0.0);
                assert_eq!(s.pdf, sampler.pdf(&scene, &ctx, s.wi, s.hit));
            }
        }
    }
}

/// Wilson–Hilferty's approximation of the chi-square quantile at significance 1e-3.
fn chi_square_critical(dof: usize) -> f64 {
    let k = dof as f64;
    let z = 3.090; // the standard normal's 0.999 quantile
    k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3)
}

/// Pearson's statistic of `samples` against the density `pdf` over `n × n` equal-solid-angle
/// cells of the cone; expected counts from stratified quadrature of the pdf in each cell (fine:
/// a mixture can hold most of its mass in a small portal), cells expecting fewer than 5
/// pooled. Returns (statistic, critical value at 1e-3).
fn chi_square(cone: &Cone, samples: &[Vec3], pdf: impl Fn(Vec3) -> f32) -> (f64, f64) {
    let outside = samples
        .iter()
        .filter(|&&w| cone.cell(w, 8).is_none())
        .count();
    assert!(outside == 0, "{outside} samples outside the cone");
    let n = 8;
    let m = 96; // quadrature points per cell side
    let cell_omega = cone.solid_angle() / (n * n) as f64;
    let mut mass = vec![0.0f64; n * n];
    let mut rng = Rng::new(5, 6);
    for (c, cell_mass) in mass.iter_mut().enumerate() {
        let (a, b) = (c / n, c % n);
        let mut sum = 0.0;
        for k in 0..m * m {
            let u = Vec2::new(
                (a as f32 + ((k / m) as f32 + rng.uniform()) / m as f32) / n as f32,
                (b as f32 + ((k % m) as f32 + rng.uniform()) / m as f32) / n as f32,
            );
            sum += pdf(cone.direction(u)) as f64;
        }
        *cell_mass = sum / (m * m) as f64 * cell_omega;
    }
    let total: f64 = mass.iter().sum();
    let mut observed = vec![0usize; n * n];
    for &w in samples {
        if let Some(c) = cone.cell(w, n) {
            observed[c] += 1;
        }
    }
    let count = samples.len() as f64;

    let (mut stat, mut cells, mut pooled_o, mut pooled_e) = (0.0, 0usize, 0.0, 0.0);
    for (o, e) in observed.iter().zip(&mass) {
        let e = e / total * count;
        if e < 5.0 {
            pooled_o += *o as f64;
            pooled_e += e;
        } else {
            stat += (*o as f64 - e).powi(2) / e;
            cells += 1;
        }
    }
    if pooled_e >= 5.0 {
        stat += (pooled_o - pooled_e).powi(2) / pooled_e;
        cells += 1;
    } else if pooled_o > 5.0 + 5.0 * pooled_e {
        // Many samples where the pdf says almost none may fall: reject outright.
        stat = f64::INFINITY;
    }
    (stat, chi_square_critical(cells.saturating_sub(1).max(1)))
}

/// Samples of every strategy at points in every region follow the mixture pdf.
#[test]
fn samples_pass_chi_square_against_the_pdf() {
    for (name, scene, region, x) in cases() {
        for strategy in Strategy::ALL {
            let sampler = LightSampler::new(&scene, strategy, None);
            let ctx = sampler.context(&scene, 0, x);
            let cone = Cone::around(x, &support_points(&scene, &ctx));
            let mut rng = Rng::new(7, 8);
            let samples: Vec<Vec3> = (0..30_000)
                .filter_map(|_| sampler.sample(&scene, &ctx, rng.uniform(), rng.uniform2()))
                .map(|s| s.wi)
                .collect();
            let (stat, critical) = chi_square(&cone, &samples, |w| q(&sampler, &scene, &ctx, w));
            assert!(
                stat <= critical,
                "{name} {} {}: chi-square {stat:.1} > {critical:.1}",
                region.name(),
                strategy.name()
            );
        }
    }
}

/// Negative case: light-sampling directions tested against the portal strategy's pdf at a point
/// in the antiantumbra (where the two differ) are rejected, so the test above can fail.
#[test]
fn chi_square_rejects_samples_from_another_pdf() {
    let scene = Scene::open("fig8a").unwrap();
    let x = Vec3::new(0.0, 1.05, 0.0);
    assert_eq!(scene.portals[0].planes.classify(x), Region::Antiantumbra);
    let light_only = LightSampler::new(&scene, Strategy::Light, None);
    let portal = LightSampler::new(&scene, Strategy::Portal, None);
    let ctx_light = light_only.context(&scene, 0, x);
    let ctx_portal = portal.context(&scene, 0, x);
    let cone = Cone::around(x, &support_points(&scene, &ctx_portal));
    let mut rng = Rng::new(7, 8);
    let samples: Vec<Vec3> = (0..30_000)
        .filter_map(|_| light_only.sample(&scene, &ctx_light, rng.uniform(), rng.uniform2()))
        .map(|s| s.wi)
        .collect();
    let (stat, critical) = chi_square(&cone, &samples, |w| q(&portal, &scene, &ctx_portal, w));
    assert!(
        stat > critical,
        "chi-square {stat:.1} did not reject (critical {critical:.1})"
    );
}

/// Portal sampling's pdf is zero off the portal and positive through it.
#[test]
fn portal_pdf_support() {
    let scene = Scene::open("fig8b").unwrap();
    let portal = &scene.portals[0];
    let x = Vec3::new(0.2, 0.9, 0.1);
    let through = (portal.polygon.centroid() - x).normalize();
    assert!(portal_pdf(portal, x, through) > 0.0);
    assert_eq!(portal_pdf(portal, x, -through), 0.0);
}

/// Per-block z-scores between two images (blocks of `b × b` pixels, luminance): independent
/// estimates of the same image have z ~ N(0, 1); the standard error of each block mean comes
/// from the per-pixel sample variances. Blocks darker than 1e-3 of the brightest carry no
/// information at these sample counts (their variance estimates rest on a handful of rare
/// hits), so they are left out.
fn block_z_scores(a: &Film, b: &Film, block: u32) -> Vec<f64> {
    let lum = |c: Vec3| (c.x + c.y + c.z) as f64 / 3.0;
    let (ma, va, mb, vb) = (
        a.mean(),
        a.variance_of_mean(),
        b.mean(),
        b.variance_of_mean(),
    );
    let mut blocks = vec![];
    for by in 0..a.height / block {
        for bx in 0..a.width / block {
            let (mut sa, mut sb, mut vsum, mut n) = (0.0, 0.0, 0.0, 0.0);
            for y in by * block..(by + 1) * block {
                for x in bx * block..(bx + 1) * block {
                    let i = (y * a.width + x) as usize;
                    sa += lum(ma[i]);
                    sb += lum(mb[i]);
                    vsum += lum(va[i]) + lum(vb[i]);
                    n += 1.0;
                }
            }
            blocks.push((sa / n, sb / n, vsum.sqrt() / n));
        }
    }
    let brightest = blocks.iter().map(|b| b.0.max(b.1)).fold(0.0, f64::max);
    blocks
        .into_iter()
        .filter(|&(ma, mb, se)| se > 0.0 && ma.max(mb) > 1e-3 * brightest)
        .map(|(ma, mb, se)| (ma - mb) / se)
        .collect()
}

/// Whether block z-scores look like N(0, 1): sum of squares within chi-square at 1e-3, and no
/// block beyond 5 sigma.
fn consistent(z: &[f64]) -> bool {
    let ss: f64 = z.iter().map(|v| v * v).sum();
    ss <= chi_square_critical(z.len()) && z.iter().all(|v| v.abs() < 5.0)
}

fn render_image(scene: &Scene, strategy: Strategy, alpha: Option<f32>, seed: u64) -> Film {
    let integrator = Integrator::new(
        scene,
        RenderSettings {
            strategy,
            alpha,
            max_depth: 1,
            seed,
        },
    );
    render(&integrator, 48, 36, 96).0
}

/// Every strategy's image equals light sampling's within statistical error on the built-in
/// scenes (the lampshade with its two portals).
#[test]
fn every_strategy_agrees_with_light_sampling() {
    for name in builtin::NAMES {
        let scene = Scene::open(name).unwrap();
        let reference = render_image(&scene, Strategy::Light, None, 100);
        for (k, strategy) in [Strategy::Portal, Strategy::Projection, Strategy::Antishadow]
            .into_iter()
            .enumerate()
        {
            let image = render_image(&scene, strategy, None, 200 + k as u64);
            let z = block_z_scores(&image, &reference, 6);
            assert!(z.len() > 10, "{name}: too few lit blocks");
            assert!(consistent(&z), "{name} {}: z = {z:?}", strategy.name());
        }
    }
}

/// fig8a with its portal moved sideways so it covers only part of the opening: with alpha > 0
/// every strategy stays unbiased; with alpha = 0 the light seen through the uncovered part of
/// the opening is lost, and the same test detects it.
#[test]
fn misplaced_portal_is_unbiased_only_with_alpha() {
    let scene = Scene::open("fig8a").unwrap();
    let mut portals = scene.desc.portals.clone();
    portals[0].world_from_local = glam::Mat4::from_translation(Vec3::new(0.2, 0.0, 0.0));
    let moved = scene.with_portals(portals).unwrap();
    let reference = render_image(&moved, Strategy::Light, None, 100);
    for (k, strategy) in [Strategy::Portal, Strategy::Projection, Strategy::Antishadow]
        .into_iter()
        .enumerate()
    {
        let image = render_image(&moved, strategy, Some(0.3), 300 + k as u64);
        let z = block_z_scores(&image, &reference, 6);
        assert!(consistent(&z), "misplaced, {}: z = {z:?}", strategy.name());
    }
    let biased = render_image(&moved, Strategy::Portal, Some(0.0), 400);
    let z = block_z_scores(&biased, &reference, 6);
    assert!(
        !consistent(&z),
        "alpha = 0 on a misplaced portal went undetected"
    );
}

/// The plane classifier agrees with brute force for every portal of the built-in scenes, at
/// random points over the scene, except within a thin band around the planes.
#[test]
fn classifier_matches_brute_force_on_builtin_scenes() {
    for name in builtin::NAMES {
        let scene = Scene::open(name).unwrap();
        let (lo, hi) = scene.geometry.bounds;
        let band = 1e-4 * (hi - lo).length();
        let mut rng = Rng::new(21, 22);
        for portal in &scene.portals {
            let mut counts = [0usize; 5];
            for _ in 0..20_000 {
                let x = lo + (hi - lo) * Vec3::new(rng.uniform(), rng.uniform(), rng.uniform());
                if portal.planes.planes_distance(x) < band {
                    continue;
                }
                let fast = portal.planes.classify(x);
                let slow = classify_brute_force(&portal.polygon, &portal.light_polygon, x);
                assert_eq!(fast, slow, "{name} {} at {x}", portal.name);
                counts[Region::ALL.iter().position(|&r| r == fast).unwrap()] += 1;
            }
            assert!(
                counts.iter().filter(|&&c| c > 0).count() >= 3,
                "{name}: {counts:?}"
            );
        }
    }
}

/// The overlay's debug mode classifies by brute force; on every built-in scene it agrees with
/// the planes on all but a sliver of pixels (those within a hair of a plane).
#[test]
fn overlay_debug_mode_agrees_with_the_planes() {
    use portalview::render::primary::PrimaryBuffer;
    for name in builtin::NAMES {
        let scene = Scene::open(name).unwrap();
        let planes = PrimaryBuffer::compute(&scene, 64, 48, false);
        let brute = PrimaryBuffer::compute(&scene, 64, 48, true);
        let differing = planes
            .regions
            .iter()
            .zip(&brute.regions)
            .filter(|(a, b)| a != b)
            .count();
        assert!(
            differing * 200 <= planes.regions.len(),
            "{name}: {differing} of {} pixel regions differ",
            planes.regions.len()
        );
        assert!(planes.regions.iter().any(|r| r.is_some()));
    }
}
