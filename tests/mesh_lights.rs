//! Portals onto emissive meshes of any shape (`docs/method.md` §3.6): a classification error
//! costs variance, never bias. At floor points under a bulb in a shade and a tube over a slot,
//! the direct irradiance estimated by the light technique mixture of every strategy, with the
//! true classifier and with deliberately wrong ones, agrees with light sampling within its
//! standard error. The negative case shows the comparison detects the bias that appears when
//! the alpha share, which is what makes any classifier safe, is taken away. Run in release.

mod common;

use glam::Vec3;
use portalview::light::antishadow::Region;
use portalview::light::estimator::{LightContext, LightSampler};
use portalview::light::portal::Portal;
use portalview::light::{Strategy, Technique};
use portalview::sampling::Rng;
use portalview::scene::Scene;

/// A classifier: the true one or a wrong one.
type Classify = fn(&Portal, Vec3) -> Region;

fn truth(p: &Portal, x: Vec3) -> Region {
    p.planes.classify(x)
}

/// Every region moved to another: the antiumbra gets the portal technique, the antiantumbra
/// the projection, the antipenumbra the light, and points outside get a projection term.
fn shifted(p: &Portal, x: Vec3) -> Region {
    match p.planes.classify(x) {
        Region::Behind => Region::Behind,
        Region::Antiumbra => Region::Antiantumbra,
        Region::Antiantumbra => Region::Antipenumbra,
        Region::Antipenumbra => Region::Antiumbra,
        Region::Outside => Region::Antipenumbra,
    }
}

/// A region drawn from a hash of `x` (a function of the point alone, as a classifier must be).
fn hashed(_: &Portal, x: Vec3) -> Region {
    let h = (x.x.to_bits() ^ x.y.to_bits().rotate_left(11) ^ x.z.to_bits().rotate_left(22))
        .wrapping_mul(0x9E37_79B9);
    [
        Region::Outside,
        Region::Antiumbra,
        Region::Antipenumbra,
        Region::Antiantumbra,
    ][(h >> 30) as usize]
}

fn all_outside(_: &Portal, _: Vec3) -> Region {
    Region::Outside
}

fn all_behind(_: &Portal, _: Vec3) -> Region {
    Region::Behind
}

const WRONG: [(&str, Classify); 4] = [
    ("shifted", shifted),
    ("hashed", hashed),
    ("all outside", all_outside),
    ("all behind", all_behind),
];

/// Irradiance at floor point `x` (normal +y) from one light: `n` samples of the mixture under
/// `strategy`, regions from `classify`, each weighted `Le · cos / q` if its shadow ray is clear.
/// Mean and standard error.
fn irradiance(
    scene: &Scene,
    (strategy, alpha): (Strategy, Option<f32>),
    classify: Classify,
    x: Vec3,
    (n, seed): (usize, u64),
) -> (f64, f64) {
    let sampler = LightSampler::new(scene, strategy, alpha);
    let mut ctx = LightContext::new();
    sampler.fill_context_classified(scene, 0, x, &mut ctx, &classify);
    let bvh = &scene.geometry.bvh;
    let values: Vec<f64> = (0..n)
        .map(|i| {
            let mut rng = Rng::keyed(seed, &[i as u64]);
            let Some(s) = sampler.sample(scene, &ctx, rng.uniform(), rng.uniform2()) else {
                return 0.0;
            };
            let Some((_, dist)) = s.hit else {
                return 0.0;
            };
            let cos = s.wi.y;
            if cos <= 0.0 || s.pdf <= 0.0 || bvh.occluded(x, s.wi, 0.0, dist * (1.0 - 1e-4) - 1e-5)
            {
                return 0.0;
            }
            (s.le.x * cos / s.pdf) as f64
        })
        .collect();
    common::mean_and_se(&values)
}

/// The two scenes and floor points under each, across their regions.
fn cases() -> Vec<(&'static str, Scene, Vec<Vec3>)> {
    let floor =
        |xs: &[f32]| -> Vec<Vec3> { xs.iter().map(|&v| Vec3::new(v, 1e-3, 0.13 * v)).collect() };
    vec![
        (
            "bulb in shade",
            Scene::from_desc(common::bulb_in_shade(), "bulb").unwrap(),
            floor(&[0.0, 0.35, 0.7, 1.1, 1.6]),
        ),
        (
            "tube over a slot",
            Scene::from_desc(common::tube_over_a_slot(), "tube").unwrap(),
            floor(&[0.0, 0.3, 0.6, 0.9, 1.4]),
        ),
    ]
}

/// z-score of the difference of two independent estimates.
fn z((a, sa): (f64, f64), (b, sb): (f64, f64)) -> f64 {
    (a - b) / (sa * sa + sb * sb).sqrt().max(1e-300)
}

/// With the true classifier and with each wrong one, every strategy's estimate agrees with
/// light sampling's within 4.5 standard errors of the difference (from the sample variances;
/// 150 comparisons, so a false alarm has probability about 1e-3). The points cover the
/// antiumbra, antipenumbra and antiantumbra of the two portals, and the wrong classifiers give each point techniques of other
/// regions, or none, or plain light sampling.
#[test]
fn wrong_classifiers_cost_no_bias() {
    let mut regions_seen = vec![];
    for (name, scene, points) in cases() {
        for &x in &points {
            regions_seen.push(scene.portals[0].planes.classify(x));
            let reference = irradiance(&scene, (Strategy::Light, None), truth, x, (400_000, 1));
            assert!(reference.0 > 0.0, "{name}: no light reaches {x}");
            for (k, strategy) in [Strategy::Portal, Strategy::Projection, Strategy::Antishadow]
                .into_iter()
                .enumerate()
            {
                for (c, (label, classify)) in [("true", truth as Classify)]
                    .into_iter()
                    .chain(WRONG)
                    .enumerate()
                {
                    let seed = 10 + 10 * k as u64 + c as u64;
                    let estimate =
                        irradiance(&scene, (strategy, None), classify, x, (100_000, seed));
                    let score = z(estimate, reference);
                    assert!(
                        score.abs() <= 4.5,
                        "{name} at {x}, {} with the {label} classifier: {estimate:?} vs \
                         light sampling {reference:?} (z = {score:.2})",
                        strategy.name()
                    );
                }
            }
        }
    }
    // (Outside the antishadow, these closed shades let no light through: nothing to compare.)
    for r in [
        Region::Antiumbra,
        Region::Antipenumbra,
        Region::Antiantumbra,
    ] {
        assert!(
            regions_seen.contains(&r),
            "no point in {}: {regions_seen:?}",
            r.name()
        );
    }
}

/// The negative case: without the alpha share (alpha = 0), a classifier that wrongly puts a
/// point outside every antishadow leaves its light uncovered, and the comparison detects the
/// bias (the estimate is zero where light sampling sees the light). With the true classifier,
/// alpha = 0 is still unbiased at a point whose light is seen through the portal only by the
/// portal technique, which covers the whole opening.
#[test]
fn without_alpha_a_wrong_classifier_is_biased_and_detected() {
    let (_, scene, points) = cases().remove(1);
    let x = points[0];
    assert_eq!(scene.portals[0].planes.classify(x), Region::Antiantumbra);
    let reference = irradiance(&scene, (Strategy::Light, None), truth, x, (400_000, 1));
    let biased = irradiance(
        &scene,
        (Strategy::Antishadow, Some(0.0)),
        all_outside,
        x,
        (100_000, 2),
    );
    assert!(
        z(biased, reference).abs() > 10.0,
        "{biased:?} vs {reference:?}"
    );
    let covered = irradiance(
        &scene,
        (Strategy::Portal, Some(0.0)),
        truth,
        x,
        (100_000, 3),
    );
    assert!(
        z(covered, reference).abs() <= 4.5,
        "{covered:?} vs {reference:?}"
    );
}

/// A portal onto a bulb: the projection technique draws only through the solid's projection
/// clipped to the portal, and every direction it draws evaluates to the density it was drawn
/// with; the bulb's solid, seen from points below, lies behind the portal plane.
#[test]
fn projection_of_a_bulb_samples_its_own_density() {
    let (_, scene, points) = cases().remove(0);
    let portal = &scene.portals[0];
    assert!(portal.light_polygon.is_none() && portal.planes.is_hull());
    let plane = portal.polygon.plane();
    assert!(
        portal
            .planes
            .light_behind_portal()
            .iter()
            .all(|&v| plane.signed_distance(v) <= 1e-5)
    );
    let sampler = LightSampler::new(&scene, Strategy::Projection, None);
    let mut tested = 0;
    for &x in &points {
        let ctx = sampler.context(&scene, 0, x);
        let Some(term) = ctx.terms().first() else {
            continue;
        };
        assert_eq!(term.technique, Technique::Projection);
        let q = term.projection().unwrap();
        let mut rng = Rng::new(5, 6);
        for _ in 0..5000 {
            let Some((w, pdf)) = q.sample(rng.uniform2()) else {
                continue;
            };
            assert!(
                (q.pdf(w) - pdf).abs() <= 1e-4 * pdf,
                "{x}: {} vs {pdf}",
                q.pdf(w)
            );
            // Through the portal, towards the solid.
            assert!(portalview::light::estimator::portal_pdf(portal, x, w) > 0.0);
            tested += 1;
        }
    }
    assert!(tested > 10_000);
}
