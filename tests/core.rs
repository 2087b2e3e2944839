//! The core renderer: BVH against brute force, closed-form irradiance, determinism across
//! thread counts, the furnace, and BSDF energy. Run in release (`cargo test --release`).

mod common;

use common::*;
use glam::Vec3;
use portalview::asset::desc::{MaterialDesc, SceneDesc};
use portalview::light::{Mixture, Selection, Strategy};
use portalview::material::Material;
use portalview::render::integrator::{Integrator, RenderSettings};
use portalview::render::record::Recorder;
use portalview::render::stats::Stats;
use portalview::render::{
    Isa, Schedule, Tiles, render, render_pass, render_tile, render_tile_scheduled,
};
use portalview::sampling::{Rng, SamplerKind};
use portalview::scene::Scene;
use portalview::scene::bvh::{Bvh, BvhError, Hit, Tracer};

/// Brute-force closest hit over all triangles (Möller–Trumbore in f64).
fn brute_force(tris: &[[Vec3; 3]], o: Vec3, d: Vec3) -> Option<(f32, usize)> {
    let mut best: Option<(f64, usize)> = None;
    for (i, t) in tris.iter().enumerate() {
        let [a, b, c] = t.map(|v| v.as_dvec3());
        let (o, d) = (o.as_dvec3(), d.as_dvec3());
        let (e1, e2) = (b - a, c - a);
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-12 {
            continue;
        }
        let s = o - a;
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let v = d.dot(q) / det;
        let t = e2.dot(q) / det;
        if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0 && best.is_none_or(|(bt, _)| t < bt) {
            best = Some((t, i));
        }
    }
    best.map(|(t, i)| (t as f32, i))
}

fn random_point(rng: &mut Rng, scale: f32) -> Vec3 {
    (Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 2.0 - 1.0) * scale
}

#[test]
fn bvh_matches_brute_force_on_random_rays() {
    let mut rng = Rng::new(7, 1);
    let mut tris: Vec<[Vec3; 3]> = (0..600)
        .map(|_| {
            let c = random_point(&mut rng, 5.0);
            [
                c,
                c + random_point(&mut rng, 0.8),
                c + random_point(&mut rng, 0.8),
            ]
        })
        .collect();
    // Degenerate triangles: a point, a line, and a sliver must never be hit or crash.
    tris.push([Vec3::ONE; 3]);
    tris.push([Vec3::ZERO, Vec3::X, 2.0 * Vec3::X]);
    tris.push([Vec3::ZERO, Vec3::new(1e-9, 0.0, 0.0), Vec3::Y]);
    let bvh = Bvh::build(&tris).unwrap();
    let mut agree = 0;
    for _ in 0..4000 {
        let o = random_point(&mut rng, 8.0);
        let d = (random_point(&mut rng, 1.0)).normalize_or(Vec3::X);
        let got = bvh.closest_hit(o, d, 0.0, f32::INFINITY);
        let want = brute_force(&tris, o, d);
        match (got, want) {
            (Some(h), Some((t, i))) => {
                // Ties on shared hits may pick either triangle; the distance must agree.
                assert!((h.t - t).abs() <= 1e-3 * t.max(1.0), "t {} vs {t}", h.t);
                if h.triangle as usize == i {
                    let tri = tris[i];
                    let b = h.bary;
                    let p = (1.0 - b.x - b.y) * tri[0] + b.x * tri[1] + b.y * tri[2];
                    assert!(p.distance(o + h.t * d) < 1e-3, "barycentrics off");
                }
                agree += 1;
            }
            (None, None) => agree += 1,
            (got, want) => {
                // Only grazing hits on an edge may differ between the two tests.
                let t = got.map(|h| h.t).or(want.map(|w| w.0)).unwrap_or(0.0);
                let p = o + t * d;
                let near_edge = tris.iter().any(|tri| {
                    (0..3).any(|k| {
                        let (a, b) = (tri[k], tri[(k + 1) % 3]);
                        let ab = b - a;
                        let s = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
                        (a + s * ab).distance(p) < 1e-3
                    })
                });
                assert!(near_edge, "BVH {got:?} vs brute force {want:?}");
            }
        }
        let occluded = bvh.occluded(o, d, 0.0, 1e6);
        assert_eq!(occluded, bvh.closest_hit(o, d, 0.0, 1e6).is_some());
    }
    assert!(agree > 3900);
}

#[test]
fn bvh_handles_empty_scenes_and_rays_along_edges() {
    let empty = Bvh::build(&[]).unwrap();
    assert!(
        empty
            .closest_hit(Vec3::ZERO, Vec3::X, 0.0, f32::INFINITY)
            .is_none()
    );
    assert!(!empty.occluded(Vec3::ZERO, Vec3::X, 0.0, 1.0));
    // A quad split along its diagonal: a ray straight down the diagonal must hit exactly once,
    // and a ray lying in the quad's plane along an edge must not report a bogus hit distance.
    let (a, b, c, d) = (Vec3::ZERO, Vec3::X, Vec3::new(1.0, 0.0, 1.0), Vec3::Z);
    let bvh = Bvh::build(&[[a, b, c], [a, c, d]]).unwrap();
    let hit = bvh.closest_hit(Vec3::new(0.5, 1.0, 0.5), -Vec3::Y, 0.0, f32::INFINITY);
    assert!(hit.is_some_and(|h| (h.t - 1.0).abs() < 1e-5), "{hit:?}");
    let along = bvh.closest_hit(Vec3::new(-1.0, 0.0, 0.0), Vec3::X, 0.0, f32::INFINITY);
    assert!(along.is_none_or(|h| h.t.is_finite() && h.t >= 0.0));
}

#[test]
fn bvh_leaves_out_zero_area_triangles_and_refuses_piles_of_coincident_ones() {
    // A thousand copies of one triangle made obvhs build a chain 999 levels deep (its traversal
    // stack holds 32), in time quadratic in their number.
    let triangle = [Vec3::ZERO, Vec3::X, Vec3::Y];
    assert!(matches!(
        Bvh::build(&vec![triangle; 1000]),
        Err(BvhError::SharedBounds { count: 65 })
    ));
    // The most a build accepts makes the deepest tree the traversal meets: a ray through the
    // pile still finds one of its triangles, alone and in a packet.
    let pile = Bvh::build(&vec![triangle; 64]).unwrap();
    let (origin, down) = (Vec3::new(0.25, 0.25, 1.0), -Vec3::Z);
    let hit = pile.closest_hit(origin, down, 0.0, f32::INFINITY);
    assert!(
        hit.is_some_and(|h| h.triangle < 64 && (h.t - 1.0).abs() < 1e-6),
        "{hit:?}"
    );
    assert!(pile.occluded(origin, down, 0.0, 2.0));
    let mut hits = [None; 8];
    pile.closest_hits(&[origin; 8], &[down; 8], 0.0, f32::INFINITY, &mut hits);
    assert!(hits.iter().all(|&h| h == hit), "{hits:?}");
    // Collapsed triangles (a thousand at one point gave a tree 998 levels deep) are left out;
    // hits still name triangles by their index in the input.
    let mut triangles = vec![[Vec3::ZERO; 3]; 1000];
    triangles.push([
        Vec3::new(-1.0, -1.0, 1.0),
        Vec3::new(1.0, -1.0, 1.0),
        Vec3::new(0.0, 1.0, 1.0),
    ]);
    let bvh = Bvh::build(&triangles).unwrap();
    assert_eq!(bvh.triangle_count(), 1);
    let hit = bvh.closest_hit(Vec3::ZERO, Vec3::Z, 0.0, f32::INFINITY);
    assert!(
        hit.is_some_and(|h| h.triangle == 1000 && (h.t - 1.0).abs() < 1e-5),
        "{hit:?}"
    );
}

/// Lambert's formula against the renderer, for tilted lights wholly above the tangent plane.
/// Tolerance: 4 standard errors of the estimator, the standard error from the sample variance.
#[test]
fn diffuse_plane_matches_lambert_irradiance() {
    let (albedo, le) = (0.8, 5.0);
    let configs = [
        (Vec3::new(0.0, 2.0, 0.0), Vec3::new(0.0, -1.0, 0.0), 0.5),
        (Vec3::new(1.0, 1.5, -0.5), Vec3::new(-0.6, -1.0, 0.3), 0.4),
        (Vec3::new(-1.5, 0.8, 0.7), Vec3::new(1.0, -0.4, -0.2), 0.3),
        (Vec3::new(0.5, 3.0, 2.0), Vec3::new(0.1, -0.2, -1.0), 0.8),
    ];
    for (i, (c, n, h)) in configs.into_iter().enumerate() {
        let light = square(c, n, h);
        let scene = Scene::from_desc(floor_and_light(albedo, light.clone(), le), "test").unwrap();
        let scene = lambertian(scene, 0, albedo);
        let x = Vec3::new(0.1, 0.0, -0.2);
        let expected = albedo as f64 / std::f64::consts::PI
            * lambert_irradiance(x, Vec3::Y, &light, le) as f64;
        let (mean, se) = floor_radiance(&scene, (Strategy::Light, None), x, 40_000, i as u64);
        assert!(
            (mean - expected).abs() <= 4.0 * se,
            "config {i}: {mean} ± {se} vs Lambert {expected}"
        );
        // Negative case: a 3% error in the expected value is caught by the same test.
        if i == 0 {
            assert!(
                (mean - 1.03 * expected).abs() > 4.0 * se,
                "test cannot detect a 3% bias"
            );
        }
    }
}

fn small_scene() -> Scene {
    Scene::open("fig8c").unwrap()
}

#[test]
fn same_image_with_one_and_two_threads() {
    let scene = small_scene();
    for sampler in SamplerKind::ALL {
        let settings = RenderSettings {
            seed: 42,
            max_depth: 3,
            sampler,
            ..RenderSettings::default()
        };
        let render_with = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| render(&Integrator::new(&scene, settings), 48, 36, 3))
        };
        let (one, stats_one) = render_with(1);
        let (two, stats_two) = render_with(2);
        let (three, _) = render_with(3);
        let name = sampler.name();
        assert_eq!(one.mean(), two.mean(), "{name}");
        assert_eq!(one.mean(), three.mean(), "{name}");
        assert_eq!(stats_one.shadow_rays, stats_two.shadow_rays, "{name}");
        assert!(
            one.mean().iter().any(|c| c.max_element() > 0.0),
            "{name}: image is black"
        );
    }
}

/// The rays/s that the CLI and the benchmark report are only as true as the ray counts: every
/// traced ray is counted once, in its kind, and the pass renders what `render_tile` renders.
#[test]
fn statistics_count_every_traced_ray() {
    for name in ["lampshade", "fig8c"] {
        let scene = Scene::open(name).unwrap();
        for (strategy, max_depth) in [(Strategy::Light, 1), (Strategy::Antishadow, 3)] {
            let integrator = Integrator::new(
                &scene,
                RenderSettings {
                    strategy,
                    max_depth,
                    seed: 5,
                    ..RenderSettings::default()
                },
            );
            let tiles = Tiles::new(40, 30);
            let rays = scene.camera.rays(40.0 / 30.0);
            // The benchmark's recorder, whose rays are the raw side of its comparison.
            let recorder = Recorder::new(&scene.geometry.bvh);
            let mut stats = Stats::default();
            let mut pixels = Vec::new();
            for tile in 0..tiles.count() {
                pixels.push(render_tile(
                    &integrator,
                    &recorder,
                    &rays,
                    tiles,
                    tile,
                    0,
                    &mut stats,
                ));
            }
            let traced = recorder.into_rays();
            let closest = traced.iter().filter(|r| r.closest).count() as u64;
            let occlusion = traced.len() as u64 - closest;
            let label = format!("{name}, {strategy:?}, depth {max_depth}");
            assert_eq!(closest, stats.camera_rays + stats.bounce_rays, "{label}");
            assert_eq!(occlusion, stats.shadow_rays, "{label}");
            assert!(stats.shadow_rays > 0, "{label}: no shadow rays");
            let never = std::sync::atomic::AtomicBool::new(false);
            let (image, pass_stats) = render_pass(&integrator, 40, 30, 0, &never).unwrap();
            assert_eq!(pass_stats.rays(), stats.rays(), "{label}");
            for tile in 0..tiles.count() {
                let (x0, y0, w, _) = tiles.rect(tile);
                for (i, p) in pixels[tile as usize].iter().enumerate() {
                    let (x, y) = (x0 + i as u32 % w, y0 + i as u32 / w);
                    assert_eq!(*p, image[(y * 40 + x) as usize], "{label}: pixel {x},{y}");
                }
            }
        }
    }
}

/// Every built-in scene, as it is and with test textures on every material, named.
fn builtins_plain_and_textured() -> impl Iterator<Item = (String, Scene)> {
    builtins_with(false)
}

/// [`builtins_plain_and_textured`], and with `lambertian` each scene once more with every
/// material exactly Lambertian (no specular layer), as the peer benchmark converts them.
fn builtins_with(lambertian: bool) -> impl Iterator<Item = (String, Scene)> {
    portalview::asset::builtin::NAMES
        .iter()
        .flat_map(move |&name| {
            let desc = portalview::asset::builtin::desc(name).unwrap();
            let textured = portalview::asset::builtin::with_test_textures(desc.clone());
            let mut plain = desc.clone();
            for m in &mut plain.materials {
                (m.specular_factor, m.metallic, m.clearcoat) = (0.0, 0.0, 0.0);
            }
            [
                Some((name.to_string(), desc)),
                Some((format!("{name}, textured"), textured)),
                lambertian.then(|| (format!("{name}, Lambertian"), plain)),
            ]
            .into_iter()
            .flatten()
            .map(|(name, desc)| {
                let scene = Scene::from_desc(desc, &name).unwrap();
                (name, scene)
            })
        })
}

/// The renderer is compiled for baseline x86-64 and for x86-64-v3 (AVX2, FMA), the variant
/// chosen at run time: every variant this CPU runs must give the baseline's
/// pixels, bit for bit, on every built-in scene (textured too), with every strategy, for direct
/// light and longer paths. The test names the variants it compared (a CPU without AVX2 compares
/// the baseline with itself).
#[test]
fn instruction_set_variants_render_identical_pixels() {
    let variants: Vec<Isa> = Isa::ALL.into_iter().filter(|isa| isa.available()).collect();
    eprintln!("instruction-set variants compared: {variants:?}");
    for (name, scene) in builtins_plain_and_textured() {
        for strategy in Strategy::ALL {
            for max_depth in [1, 3] {
                let integrator = Integrator::new(
                    &scene,
                    RenderSettings {
                        strategy,
                        max_depth,
                        seed: 11,
                        ..RenderSettings::default()
                    },
                );
                let tiles = Tiles::new(24, 16);
                let rays = scene.camera.rays(24.0 / 16.0);
                let bvh = &scene.geometry.bvh;
                for tile in 0..tiles.count() {
                    let render = |isa| {
                        let mut stats = Stats::default();
                        let pixels = render_tile_scheduled(
                            isa,
                            Schedule::detect(&integrator),
                            &integrator,
                            bvh,
                            &rays,
                            tiles,
                            tile,
                            0,
                            &mut stats,
                        );
                        (
                            pixels
                                .iter()
                                .map(|p| p.to_array().map(f32::to_bits))
                                .collect::<Vec<_>>(),
                            stats,
                        )
                    };
                    let (baseline, baseline_stats) = render(Isa::Baseline);
                    for &isa in &variants {
                        let (pixels, stats) = render(isa);
                        let label = format!(
                            "{name}, {strategy:?}, depth {max_depth}, tile {tile}, {isa:?}"
                        );
                        assert_eq!(baseline, pixels, "{label}");
                        assert_eq!(baseline_stats.rays(), stats.rays(), "{label}");
                    }
                }
            }
        }
    }
}

/// The BVH, counting the shadow rays it was given in packets ([`Tracer::occluders_each`]): how
/// a test knows the staged schedule ran.
struct CountingPackets<'b> {
    bvh: &'b Bvh,
    packed: std::cell::Cell<usize>,
}

impl Tracer for CountingPackets<'_> {
    fn closest_hit(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        self.bvh.closest_hit(origin, dir, tmin, tmax)
    }
    fn occluder(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32, guess: u32) -> Option<u32> {
        Tracer::occluder(self.bvh, origin, dir, tmin, tmax, guess)
    }
    fn blocker_past(
        &self,
        origin: Vec3,
        dir: Vec3,
        segment: (f32, f32),
        guess: u32,
        pass: &mut dyn FnMut(&Hit) -> bool,
    ) -> Option<u32> {
        self.bvh.blocker_past(origin, dir, segment, guess, pass)
    }
    fn closest_hits(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        tmin: f32,
        tmax: f32,
        hits: &mut [Option<Hit>],
    ) {
        self.bvh.closest_hits(origins, dirs, tmin, tmax, hits);
    }
    fn occluders_each(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        tmin: f32,
        tmaxes: &[f32],
        guess: u32,
        blocked: &mut [bool],
    ) -> Option<u32> {
        self.packed.set(self.packed.get() + origins.len());
        self.bvh
            .occluders_each(origins, dirs, tmin, tmaxes, guess, blocked)
    }
}

/// The staged schedule (a packet's first vertices shaded in lanes, its shadow rays queued with
/// their contributions and traced together) renders the pixels of the one-path reference, bit
/// for bit, and counts the same rays: on every built-in scene (textured, and with every
/// material Lambertian, too), with every strategy, sampler, mixture and light selection, for
/// direct light and longer paths. The staged side must have traced its shadow rays in packets
/// and shaded first vertices in lanes on every scene without glass, or it compared the
/// reference with itself.
#[test]
fn staged_schedule_renders_the_reference_pixels() {
    let isa = Isa::detect();
    if isa == Isa::Baseline {
        eprintln!("no AVX2: both schedules run one path at a time here");
    }
    for (name, scene) in builtins_with(true) {
        let settings = Strategy::ALL.into_iter().flat_map(|strategy| {
            [(1, SamplerKind::Sobol), (3, SamplerKind::Independent)]
                .into_iter()
                .flat_map(move |(max_depth, sampler)| {
                    [
                        (Mixture::OneSample, Selection::Tree),
                        (Mixture::EachShare, Selection::Power),
                    ]
                    .map(|(mixture, selection)| RenderSettings {
                        strategy,
                        max_depth,
                        sampler,
                        mixture,
                        selection,
                        seed: 13,
                        ..RenderSettings::default()
                    })
                })
        });
        for settings in settings {
            let integrator = Integrator::new(&scene, settings);
            let tiles = Tiles::new(24, 16);
            let rays = scene.camera.rays(24.0 / 16.0);
            let tracer = CountingPackets {
                bvh: &scene.geometry.bvh,
                packed: std::cell::Cell::new(0),
            };
            let render = |schedule| {
                let mut stats = Stats::default();
                let pixels: Vec<_> = (0..tiles.count())
                    .flat_map(|tile| {
                        render_tile_scheduled(
                            isa,
                            schedule,
                            &integrator,
                            &tracer,
                            &rays,
                            tiles,
                            tile,
                            0,
                            &mut stats,
                        )
                    })
                    .map(|p| p.to_array().map(f32::to_bits))
                    .collect();
                // Every count but the sampling time, which is measured, and the first
                // vertices shaded in lanes, which only the staged schedule does.
                let lane_vertices = stats.lane_vertices;
                let stats = Stats {
                    sampling_ns: 0,
                    lane_vertices: 0,
                    ..stats
                };
                (pixels, stats, lane_vertices)
            };
            let label = format!("{name}, {settings:?}");
            // A render stages its packets only where some material is Lambertian: the
            // built-ins' all have a specular layer, which the stage costs up to 5%, but for the
            // desk lamp's matte ones (Blender's Principled BSDF with Specular 0).
            let glass = scene.geometry.has_panes
                || scene.geometry.materials.iter().any(|m| m.volume.is_some());
            if std::env::var_os("PORTALVIEW_INTEGRATOR").is_none() {
                let matte = name.ends_with("Lambertian") || name.starts_with("desklamp");
                let staged = matte && !glass;
                let expected = if staged {
                    Schedule::Staged
                } else {
                    Schedule::Paths
                };
                assert_eq!(Schedule::detect(&integrator), expected, "{label}");
            }
            let (reference, reference_stats, none) = render(Schedule::Paths);
            assert_eq!(tracer.packed.get(), 0, "{label}: the reference queued rays");
            assert_eq!(none, 0, "{label}: the reference shaded vertices in lanes");
            let (staged, staged_stats, lane_vertices) = render(Schedule::Staged);
            assert_eq!(reference.len(), staged.len(), "{label}");
            if let Some(i) = (0..reference.len()).find(|&i| reference[i] != staged[i]) {
                let bits = |p: [u32; 3]| p.map(f32::from_bits);
                let (a, b) = (bits(reference[i]), bits(staged[i]));
                panic!(
                    "{label}: pixel {i} (in tile order): {a:?} one path at a time, {b:?} staged"
                );
            }
            assert_eq!(reference_stats, staged_stats, "{label}");
            if isa != Isa::Baseline && !glass {
                assert_eq!(
                    tracer.packed.get() as u64,
                    staged_stats.shadow_rays,
                    "{label}: not every shadow ray went through the queue"
                );
                // Or it compared the one-path first vertex with itself (on the Lambertian
                // scenes, with the BSDF's draws in lanes too). Textured surfaces take the
                // one-path first vertex.
                if settings.max_depth == 1 && !name.ends_with("textured") {
                    assert!(lane_vertices > 0, "{label}: no first vertex in lanes");
                }
            }
        }
    }
}

/// A UV sphere's triangles (outward winding unless `inward`).
fn sphere(center: Vec3, r: f32, inward: bool) -> Vec<Vec<Vec3>> {
    let (nu, nv) = (32, 16);
    let p = |i: usize, j: usize| {
        let (phi, theta) = (
            std::f32::consts::TAU * i as f32 / nu as f32,
            std::f32::consts::PI * j as f32 / nv as f32,
        );
        center
            + r * Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            )
    };
    let mut tris = vec![];
    for i in 0..nu {
        for j in 0..nv {
            let (a, b, c, d) = (p(i, j), p(i + 1, j), p(i + 1, j + 1), p(i, j + 1));
            for t in [vec![a, b, c], vec![a, c, d]] {
                if t[0].distance(t[1]) < 1e-6
                    || t[1].distance(t[2]) < 1e-6
                    || t[0].distance(t[2]) < 1e-6
                {
                    continue;
                }
                // [a, b, c] winds outward.
                tris.push(if inward {
                    t.into_iter().rev().collect()
                } else {
                    t
                });
            }
        }
    }
    tris
}

/// A sphere of base colour `albedo` inside a closed emitter of radiance 1, rendered: the image
/// mean and its standard error (from the per-pixel variances). The sphere is the glTF material
/// Blender 3.4 writes for Principled *Specular* 0 (`specularColorFactor` [0, 0, 0],
/// `specularFactor` absent so 1, its IOR 1.45), which must be exactly Lambertian.
fn furnace(albedo: f32) -> (f64, f64) {
    let ball = MaterialDesc {
        specular_color: Vec3::ZERO,
        ior: 1.45,
        roughness: 0.5,
        ..MaterialDesc::diffuse("ball", Vec3::splat(albedo))
    };
    // The sky only emits: a glTF emitter would also reflect through its specular layer.
    let sky = MaterialDesc {
        specular_factor: 0.0,
        ..MaterialDesc::emitter("sky", Vec3::ONE, false)
    };
    let desc = SceneDesc {
        name: "furnace".into(),
        materials: vec![ball, sky],
        meshes: vec![
            flat("ball", 0, &sphere(Vec3::ZERO, 1.0, false)),
            flat("sky", 1, &sphere(Vec3::ZERO, 10.0, true)),
        ],
        portals: vec![],
        lamps: vec![],
        warnings: Vec::new(),
        images: Vec::new(),
        camera: camera(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO),
        environment: None,
    };
    let scene = Scene::from_desc(desc, "furnace").unwrap();
    let ball = &scene.geometry.materials[0];
    assert_eq!(
        (ball.f0, ball.f90, ball.metallic),
        (Vec3::ZERO, 0.0, 0.0),
        "Specular 0 must leave no specular layer"
    );
    let integrator = Integrator::new(
        &scene,
        RenderSettings {
            seed: 3,
            // The tolerance rests on the per-pixel sample variance: independent samples.
            sampler: SamplerKind::Independent,
            ..Default::default()
        },
    );
    let (film, stats) = render(&integrator, 32, 32, 64);
    assert_eq!(stats.nonfinite, 0, "non-finite radiance samples");
    let mean = film.mean();
    let var = film.variance_of_mean();
    let n = mean.len() as f64;
    let image_mean = mean.iter().map(|c| c.x as f64).sum::<f64>() / n;
    let image_se = (var.iter().map(|v| v.x as f64).sum::<f64>()).sqrt() / n;
    (image_mean, image_se)
}

/// The white furnace returns 1 within 4 standard errors of the image mean; the negative case,
/// a sphere reflecting 3 % less, is told apart by the same criterion.
#[test]
fn white_lambertian_furnace_returns_one() {
    let returns_one = |(mean, se): (f64, f64)| (mean - 1.0).abs() <= 4.0 * se + 1e-4;
    let white = furnace(1.0);
    assert!(returns_one(white), "{white:?}");
    let grey = furnace(0.97);
    assert!(!returns_one(grey), "a 3 % loss went unseen: {grey:?}");
}

/// The albedo `∫ f cos dωi` of every channel, estimated by sampling the BSDF `n` times from
/// `wo`, with its standard error.
fn albedo(m: &Material, wo: Vec3, rng: &mut Rng, n: usize) -> [(f64, f64); 3] {
    let mut channels: [Vec<f64>; 3] = Default::default();
    for _ in 0..n {
        let weight = match m.sample(wo, rng.uniform(), rng.uniform2()) {
            Some(s) => s.f * s.wi.z / s.pdf,
            None => Vec3::ZERO,
        };
        for (c, values) in channels.iter_mut().enumerate() {
            values.push(weight[c] as f64);
        }
    }
    channels.map(|values| mean_and_se(&values))
}

/// The energy criterion: an albedo above 1 by more than 5 standard errors of its estimate is a
/// gain, not noise (one-sided; 5 rather than 4 because the sweep makes thousands of checks).
/// 1e-5 more allows for f32 round-off where a lobe reflects exactly 1 with no variance.
fn gains_energy((albedo, se): (f64, f64)) -> bool {
    albedo > 1.0 + 5.0 * se + 1e-5
}

/// No configuration reflects more than it receives: a seeded sweep over base colour,
/// metallic, roughness, IOR (0 included), specular factor and specular colour (above 1
/// included), from normal to grazing incidence, in every channel.
#[test]
fn no_bsdf_creates_energy() {
    let mut rng = Rng::new(11, 5);
    let bases = [
        Vec3::ONE,
        Vec3::new(1.0, 0.5, 0.0),
        Vec3::splat(0.2),
        Vec3::ZERO,
    ];
    let colors = [
        Vec3::ONE,
        Vec3::ZERO,
        Vec3::new(1.0, 0.2, 0.0),
        Vec3::splat(3.0),
    ];
    let pick = |rng: &mut Rng, n: usize| ((rng.uniform() * n as f32) as usize).min(n - 1);
    for case in 0..160 {
        let d = MaterialDesc {
            metallic: [0.0, 0.0, 0.5, 1.0][pick(&mut rng, 4)],
            roughness: [0.05, 0.3, 0.7, 1.0][pick(&mut rng, 4)],
            ior: [1.5, 1.0, 1.45, 2.5, 0.0][pick(&mut rng, 5)],
            specular_factor: [1.0, 0.5, 0.0][pick(&mut rng, 3)],
            specular_color: colors[pick(&mut rng, 4)],
            ..MaterialDesc::diffuse("m", bases[pick(&mut rng, 4)])
        };
        let m = Material::from_desc(&d);
        for cos_o in [1.0f32, 0.5, 0.15, 0.03] {
            let wo = Vec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
            for (c, estimate) in albedo(&m, wo, &mut rng, 10_000).into_iter().enumerate() {
                assert!(
                    !gains_energy(estimate),
                    "case {case}, channel {c}, cos θo {cos_o}: {estimate:?} for {d:?}"
                );
            }
        }
    }
}

/// The negative case of `no_bsdf_creates_energy`: a BSDF whose diffuse did not give up the
/// energy its specular layer takes (white Lambert plus the layer alone) is caught.
#[test]
fn the_energy_criterion_catches_a_layer_added_without_loss() {
    let mut rng = Rng::new(12, 5);
    let layer_alone = Material::from_desc(&MaterialDesc::diffuse("layer", Vec3::ZERO));
    for cos_o in [1.0f32, 0.15] {
        let wo = Vec3::new((1.0 - cos_o * cos_o).sqrt(), 0.0, cos_o);
        let [(layer, se), ..] = albedo(&layer_alone, wo, &mut rng, 10_000);
        // White Lambert reflects exactly 1 (zero variance), so the sum is 1 + the layer.
        assert!(gains_energy((1.0 + layer, se)), "{layer} ± {se}");
    }
}
