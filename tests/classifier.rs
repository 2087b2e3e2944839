//! The antishadow classifier against brute force (`docs/method.md` §3.5): random convex portals and lights of 3 to 8 vertices, tilted lights and lights
//! straddling the portal plane included, must agree everywhere except in a thin band around
//! the planes. Negative cases show that the comparison would notice a wrong classifier.

use glam::{DVec3, Quat, Vec3};
use portalview::light::antishadow::{
    AntishadowError, AntishadowPlanes, Region, classify_brute_force,
};
use portalview::sampling::Rng;
use portalview::sampling::polygon::{ConvexPolygon, sample_polygon_area};

/// Points closer than this (relative to the scene's size) to any plane are not compared. The
/// comparison was seen to hold down to 1e-6 (and fail once in 2·10^6 points with no band).
const BAND: f32 = 1e-4;
const SCENES: usize = 1000;
const POINTS_PER_SCENE: usize = 200;

struct Scene {
    portal: ConvexPolygon,
    light: ConvexPolygon,
    planes: AntishadowPlanes,
    /// World from the canonical frame (portal at the origin facing +z), scale included.
    rotation: Quat,
    translation: Vec3,
    size: f32,
    /// Whether part of the light is in front of the portal plane (clipped away).
    straddles: bool,
}

impl Scene {
    fn world(&self, p: Vec3) -> Vec3 {
        self.rotation * (self.size * p) + self.translation
    }

    /// Half the points in a box around and in front of the portal (a little behind it too),
    /// half on lines from the light through the portal, where the three inner regions are.
    fn sample_point(&self, rng: &mut Rng) -> Vec3 {
        if rng.uniform() < 0.5 {
            let u = Vec3::new(rng.uniform(), rng.uniform(), rng.uniform());
            let local = Vec3::new(-4.0, -4.0, -0.5) + u * Vec3::new(8.0, 8.0, 6.5);
            self.world(local)
        } else {
            let p = self.portal.sample_uniform(rng.uniform2());
            let l = sample_polygon_area(self.planes.light_behind_portal(), rng.uniform2());
            let t = 10f32.powf(uniform_in(rng, -2.0, 1.3));
            p + t * (p - l)
        }
    }
}

fn uniform_in(rng: &mut Rng, lo: f32, hi: f32) -> f32 {
    lo + (hi - lo) * rng.uniform()
}

/// A random convex polygon of 3 to 8 vertices: sorted random angles on an ellipse, in the
/// plane through `center` with counter-clockwise winding around `normal`.
fn random_polygon(rng: &mut Rng, center: Vec3, normal: Vec3, scale: f32) -> Option<ConvexPolygon> {
    let n = 3 + (rng.next_u32() % 6) as usize;
    let (a, b) = (
        scale * uniform_in(rng, 0.3, 1.5),
        scale * uniform_in(rng, 0.3, 1.5),
    );
    let spin = uniform_in(rng, 0.0, std::f32::consts::TAU);
    let mut angles: Vec<f32> = (0..n)
        .map(|_| uniform_in(rng, 0.0, std::f32::consts::TAU))
        .collect();
    angles.sort_by(f32::total_cmp);
    let frame = portalview::sampling::Frame::from_normal(normal.normalize());
    let (sr, cr) = spin.sin_cos();
    let points: Vec<Vec3> = angles
        .iter()
        .map(|&t| {
            let (x, y) = (a * t.cos(), b * t.sin());
            center + frame.t * (cr * x - sr * y) + frame.b * (sr * x + cr * y)
        })
        .collect();
    // Nearly coincident angles give slivers that ConvexPolygon rejects or merges: resample.
    let polygon = ConvexPolygon::new(&points).ok()?;
    (polygon.vertices().len() >= 3 && polygon.normal().dot(normal) > 0.0).then_some(polygon)
}

/// A random (portal, light) pair in world space that `AntishadowPlanes::new` accepts.
fn random_scene(rng: &mut Rng) -> Scene {
    loop {
        // Canonical frame: portal at the origin, front +z; the light below, facing up-ish.
        let Some(portal) = random_polygon(rng, Vec3::ZERO, Vec3::Z, 1.0) else {
            continue;
        };
        let tilt = uniform_in(rng, 0.0, 1.3); // up to about 75 degrees
        let azimuth = uniform_in(rng, 0.0, std::f32::consts::TAU);
        let light_normal = Vec3::new(
            tilt.sin() * azimuth.cos(),
            tilt.sin() * azimuth.sin(),
            tilt.cos(),
        );
        // A third of the lights sit close below the portal plane so that tilted ones cross it.
        let depth = if rng.uniform() < 0.33 {
            uniform_in(rng, 0.0, 0.4)
        } else {
            uniform_in(rng, 0.2, 2.5)
        };
        let offset = Vec3::new(
            uniform_in(rng, -1.5, 1.5),
            uniform_in(rng, -1.5, 1.5),
            -depth,
        );
        // Lights from a third to three times the portal's size.
        let light_scale = 3f32.powf(uniform_in(rng, -1.0, 1.0));
        let Some(light) = random_polygon(rng, offset, light_normal, light_scale) else {
            continue;
        };
        let size = 10f32.powf(uniform_in(rng, -1.0, 1.0));
        let rotation = Quat::from_euler(
            glam::EulerRot::ZXY,
            uniform_in(rng, -3.1, 3.1),
            uniform_in(rng, -3.1, 3.1),
            uniform_in(rng, -3.1, 3.1),
        );
        let translation = size
            * Vec3::new(
                uniform_in(rng, -3.0, 3.0),
                uniform_in(rng, -3.0, 3.0),
                uniform_in(rng, -3.0, 3.0),
            );
        let to_world = |polygon: &ConvexPolygon| {
            let points: Vec<Vec3> = polygon
                .vertices()
                .iter()
                .map(|&p| rotation * (size * p) + translation)
                .collect();
            ConvexPolygon::new(&points).ok()
        };
        let (Some(portal), Some(light)) = (to_world(&portal), to_world(&light)) else {
            continue;
        };
        let straddles = light
            .vertices()
            .iter()
            .any(|&v| portal.plane().signed_distance(v) > 0.0);
        // The preconditions (light partly behind the portal, portal on the light's emitting
        // side) are not always met by a random pair: redraw. Anything else is a failure.
        let planes = match AntishadowPlanes::new(&portal, &light) {
            Ok(planes) => planes,
            Err(AntishadowError::PortalBehindLight | AntishadowError::LightInFrontOfPortal) => {
                continue;
            }
            Err(e) => panic!("{e}\nportal {portal:?}\nlight {light:?}"),
        };
        return Scene {
            portal,
            light,
            planes,
            rotation,
            translation,
            size,
            straddles,
        };
    }
}

#[derive(Default, Debug)]
struct Tally {
    agreements: [usize; 5],
    disagreements: usize,
    in_band: usize,
    first_disagreement: Option<String>,
}

impl Tally {
    fn record(&mut self, expected: Region, got: Region, what: impl FnOnce() -> String) {
        if expected == got {
            self.agreements[expected as usize] += 1;
        } else {
            self.disagreements += 1;
            if self.first_disagreement.is_none() {
                self.first_disagreement = Some(what());
            }
        }
    }
    fn report(&self, title: &str) {
        println!("{title}:");
        for region in Region::ALL {
            println!(
                "  {:>13}: {}",
                region.name(),
                self.agreements[region as usize]
            );
        }
        println!(
            "  in band (skipped): {}, disagreements: {}",
            self.in_band, self.disagreements
        );
    }
}

#[test]
fn planes_agree_with_brute_force_on_random_polygons() {
    let mut rng = Rng::new(2022, 7);
    let mut tally = Tally::default();
    let mut straddling_scenes = 0;
    let mut straddling_agreements = 0;
    for _ in 0..SCENES {
        let scene = random_scene(&mut rng);
        straddling_scenes += scene.straddles as usize;
        let band = BAND * scene.size;
        for _ in 0..POINTS_PER_SCENE {
            let x = scene.sample_point(&mut rng);
            if scene.planes.planes_distance(x) < band {
                tally.in_band += 1;
                continue;
            }
            let got = scene.planes.classify(x);
            let expected = classify_brute_force(&scene.portal, &scene.light, x);
            straddling_agreements += (scene.straddles && got == expected) as usize;
            tally.record(expected, got, || {
                format!(
                    "x = {x}: brute force {expected:?}, planes {got:?}\nportal {:?}\nlight {:?}",
                    scene.portal.vertices(),
                    scene.light.vertices()
                )
            });
        }
    }
    tally.report("planes vs brute force");
    println!("  scenes with a light straddling the portal plane: {straddling_scenes}");
    assert_eq!(
        tally.disagreements,
        0,
        "first: {}",
        tally.first_disagreement.unwrap_or_default()
    );
    let compared: usize = tally.agreements.iter().sum();
    assert!(compared >= 100_000, "only {compared} points compared");
    for region in Region::ALL {
        let count = tally.agreements[region as usize];
        assert!(
            count >= 1000,
            "{} occurred only {count} times",
            region.name()
        );
    }
    assert!(straddling_scenes >= 50 && straddling_agreements >= 5000);
    // The band must stay thin, or the comparison would skip the interesting points.
    assert!(
        tally.in_band * 50 < compared,
        "{} points in the band",
        tally.in_band
    );
}

/// The brute force written again, in f64 as the library's: project the light from `x` onto the
/// portal plane, clip by the portal, compare areas. With `clip_light = false` it makes the
/// mistake `docs/method.md` warns about and projects the whole light, also the part in front of the
/// portal plane.
fn brute_force_again(
    portal: &ConvexPolygon,
    light: &ConvexPolygon,
    x: Vec3,
    clip_light: bool,
) -> Region {
    fn vertices(polygon: &ConvexPolygon) -> Vec<DVec3> {
        polygon.vertices().iter().map(|v| v.as_dvec3()).collect()
    }
    fn plane_of(v: &[DVec3]) -> (DVec3, f64) {
        let n = twice_area(v).normalize();
        (n, n.dot(v.iter().sum::<DVec3>() / v.len() as f64))
    }
    fn twice_area(v: &[DVec3]) -> DVec3 {
        (1..v.len().saturating_sub(1))
            .map(|i| (v[i] - v[0]).cross(v[i + 1] - v[0]))
            .sum()
    }
    fn keep_positive(v: &[DVec3], n: DVec3, d: f64) -> Vec<DVec3> {
        let mut out = Vec::new();
        for i in 0..v.len() {
            let (a, b) = (v[i], v[(i + 1) % v.len()]);
            let (da, db) = (n.dot(a) - d, n.dot(b) - d);
            if da >= 0.0 {
                out.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                out.push(a + da / (da - db) * (b - a));
            }
        }
        out
    }
    let (portal_vertices, light_vertices, x) = (vertices(portal), vertices(light), x.as_dvec3());
    let ((n_p, d_p), (n_l, d_l)) = (plane_of(&portal_vertices), plane_of(&light_vertices));
    let height = n_p.dot(x) - d_p;
    if height.is_nan() || height <= 0.0 {
        return Region::Behind;
    }
    if n_l.dot(x) - d_l <= 0.0 {
        return Region::Outside;
    }
    let seen = if clip_light {
        keep_positive(&light_vertices, -n_p, -d_p)
    } else {
        light_vertices
    };
    if seen.len() < 3 {
        return Region::Outside;
    }
    let projected: Vec<DVec3> = seen
        .iter()
        .map(|&v| x + height / (height - (n_p.dot(v) - d_p)) * (v - x))
        .collect();
    let mut overlap = projected.clone();
    for i in 0..portal_vertices.len() {
        let (a, b) = (
            portal_vertices[i],
            portal_vertices[(i + 1) % portal_vertices.len()],
        );
        let inward = n_p.cross(b - a);
        overlap = keep_positive(&overlap, inward, inward.dot(a));
    }
    let area = |v: &[DVec3]| 0.5 * twice_area(v).length();
    let (area_c, area_d, area_cd) = (area(&projected), area(&portal_vertices), area(&overlap));
    let tol = 1e-12;
    if !area_c.is_finite() || area_cd <= tol * area_c.min(area_d) {
        Region::Outside
    } else if area_c - area_cd <= tol * area_c {
        Region::Antiumbra
    } else if area_d - area_cd <= tol * area_d {
        Region::Antiantumbra
    } else {
        Region::Antipenumbra
    }
}

/// The comparison has teeth: the brute force written again agrees with the library's, but
/// without clipping the light first it disagrees with the planes on straddling lights; and the
/// planes of a light only 2% larger than the real one disagree with the brute force.
#[test]
fn comparison_detects_wrong_classifiers() {
    let mut rng = Rng::new(1995, 3);
    let mut again = Tally::default();
    let mut unclipped = Tally::default();
    let mut enlarged = Tally::default();
    let mut scenes = 0;
    while scenes < 200 {
        let scene = random_scene(&mut rng);
        if !scene.straddles {
            continue;
        }
        scenes += 1;
        let c = scene.light.centroid();
        let grown: Vec<Vec3> = scene
            .light
            .vertices()
            .iter()
            .map(|&v| c + 1.02 * (v - c))
            .collect();
        let Ok(grown) = ConvexPolygon::new(&grown) else {
            continue;
        };
        let Ok(wrong_planes) = AntishadowPlanes::new(&scene.portal, &grown) else {
            continue;
        };
        let band = BAND * scene.size;
        for _ in 0..POINTS_PER_SCENE {
            let x = scene.sample_point(&mut rng);
            if scene.planes.planes_distance(x) < band || wrong_planes.planes_distance(x) < band {
                continue;
            }
            let (portal, light) = (&scene.portal, &scene.light);
            let expected = classify_brute_force(portal, light, x);
            again.record(
                expected,
                brute_force_again(portal, light, x, true),
                String::new,
            );
            let planes = scene.planes.classify(x);
            unclipped.record(
                planes,
                brute_force_again(portal, light, x, false),
                String::new,
            );
            enlarged.record(expected, wrong_planes.classify(x), String::new);
        }
    }
    again.report("brute force vs brute force written again");
    unclipped.report("planes vs brute force without clipping the light");
    enlarged.report("brute force vs planes of a 2% larger light");
    assert_eq!(again.disagreements, 0);
    assert!(
        unclipped.disagreements >= 100,
        "{}",
        unclipped.disagreements
    );
    assert!(enlarged.disagreements >= 100, "{}", enlarged.disagreements);
}

#[test]
fn classification_is_invariant_under_rigid_motion() {
    // The same canonical scene placed twice: far from the origin and at it.
    let mut rng = Rng::new(42, 1);
    for _ in 0..50 {
        let scene = random_scene(&mut rng);
        let back = |p: Vec3| (scene.rotation.inverse() * (p - scene.translation)) / scene.size;
        let local = |polygon: &ConvexPolygon| {
            let points: Vec<Vec3> = polygon.vertices().iter().map(|&p| back(p)).collect();
            ConvexPolygon::new(&points).expect("a rigid motion keeps a polygon valid")
        };
        let (portal, light) = (local(&scene.portal), local(&scene.light));
        let planes = AntishadowPlanes::new(&portal, &light).expect("accepted once, accepted again");
        for _ in 0..100 {
            let x = scene.sample_point(&mut rng);
            if scene.planes.planes_distance(x) < BAND * scene.size {
                continue;
            }
            let y = back(x);
            if planes.planes_distance(y) < BAND {
                continue;
            }
            assert_eq!(scene.planes.classify(x), planes.classify(y));
        }
    }
}

/// An axis-aligned rectangle `[x0, x1] × [y0, y1]` at height `z`, counter-clockwise around +z.
fn rectangle(x: (f32, f32), y: (f32, f32), z: f32) -> ConvexPolygon {
    let points = [
        Vec3::new(x.0, y.0, z),
        Vec3::new(x.1, y.0, z),
        Vec3::new(x.1, y.1, z),
        Vec3::new(x.0, y.1, z),
    ];
    ConvexPolygon::new(&points).expect("a rectangle of positive size")
}

/// Exactly aligned and touching configurations, where candidate planes tie (parallel edges),
/// coincide with a polygon's plane, or pass through shared vertices: the thesis's aligned
/// rectangles on a grid, and lights perpendicular to the portal plane that end on it or cross
/// it. Both unrotated (exact ties) and randomly rotated (ties up to rounding).
#[test]
fn agrees_on_aligned_and_touching_polygons() {
    let mut rng = Rng::new(7, 7);
    let grid = |rng: &mut Rng| -2.0 + 0.5 * (rng.next_u32() % 9) as f32;
    let interval = |rng: &mut Rng| loop {
        let (a, b) = (grid(rng), grid(rng));
        if a < b {
            return (a, b);
        }
    };
    let mut tally = Tally::default();
    let mut built = 0;
    for case in 0..600 {
        let portal = rectangle(interval(&mut rng), interval(&mut rng), 0.0);
        let rotated = case % 3 != 0;
        let light = if case % 2 == 0 {
            let depth = [0.5, 1.0, 2.0][(rng.next_u32() % 3) as usize];
            rectangle(interval(&mut rng), interval(&mut rng), -depth)
        } else {
            // In the plane x = c facing +x, the portal's side; its top at, below or above z = 0.
            let x0 = portal.vertices()[0].x;
            let top = [0.0, -0.5, 0.5, 1.0][(rng.next_u32() % 4) as usize];
            let mut c = grid(&mut rng).min(x0);
            // With c = x0 and top >= 0 the cut edge of the light lies on the portal edge's
            // line, so "C ⊆ D" or "D ⊆ C" holds with equality over whole regions: exact
            // coordinates still decide it, but after a rotation rounding does. Skip that one.
            if rotated && c == x0 && top >= 0.0 {
                c -= 0.5;
            }
            let (y0, y1) = interval(&mut rng);
            let points = [
                Vec3::new(c, y0, -2.0),
                Vec3::new(c, y1, -2.0),
                Vec3::new(c, y1, top),
                Vec3::new(c, y0, top),
            ];
            ConvexPolygon::new(&points).expect("a rectangle of positive size")
        };
        let rotation = if rotated {
            Quat::from_euler(
                glam::EulerRot::ZXY,
                uniform_in(&mut rng, -3.1, 3.1),
                uniform_in(&mut rng, -3.1, 3.1),
                uniform_in(&mut rng, -3.1, 3.1),
            )
        } else {
            Quat::IDENTITY
        };
        let rotate = |polygon: &ConvexPolygon| {
            let points: Vec<Vec3> = polygon.vertices().iter().map(|&p| rotation * p).collect();
            ConvexPolygon::new(&points).expect("a rotation keeps a polygon valid")
        };
        let (portal, light) = (rotate(&portal), rotate(&light));
        let planes = AntishadowPlanes::new(&portal, &light)
            .unwrap_or_else(|e| panic!("case {case}: {e}\nportal {portal:?}\nlight {light:?}"));
        built += 1;
        for _ in 0..POINTS_PER_SCENE {
            let u = Vec3::new(rng.uniform(), rng.uniform(), rng.uniform());
            let x = rotation * (Vec3::new(-5.0, -5.0, -0.5) + u * Vec3::new(10.0, 10.0, 8.0));
            if planes.planes_distance(x) < BAND {
                tally.in_band += 1;
                continue;
            }
            let expected = classify_brute_force(&portal, &light, x);
            tally.record(expected, planes.classify(x), || {
                format!(
                    "case {case}, x = {x}: brute force {expected:?}, planes {:?}",
                    planes.classify(x)
                )
            });
        }
    }
    tally.report("aligned and touching polygons");
    assert_eq!(built, 600);
    assert_eq!(
        tally.disagreements,
        0,
        "first: {}",
        tally.first_disagreement.unwrap_or_default()
    );
    for region in Region::ALL {
        let count = tally.agreements[region as usize];
        assert!(
            count >= 500,
            "{} occurred only {count} times",
            region.name()
        );
    }
}
