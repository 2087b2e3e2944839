//! Spherical triangle and polygon sampling checked against independent answers: closed-form solid
//! angles, an f64 transcription of Arvo's angle-based formulas, Monte Carlo integrals of the pdf,
//! f64 ray–polygon tests, and chi-square tests of the samples against the pdf.

use glam::{DVec2, DVec3, Vec2, Vec3};
use portalview::sampling::polygon::sample_polygon_area;
use portalview::sampling::spherical::{
    SMALL_SOLID_ANGLE, SphericalPolygon, sample_spherical_triangle, spherical_triangle_solid_angle,
};
use portalview::sampling::{Frame, Rng};
use std::f64::consts::PI;

// ---------------------------------------------------------------------------------------------
// Independent references (f64)

/// The solid angle of an `a × b` rectangle centred on the axis at distance `d`.
fn rectangle_solid_angle(a: f64, b: f64, d: f64) -> f64 {
    4.0 * (a * b / ((a * a + 4.0 * d * d) * (b * b + 4.0 * d * d)).sqrt()).asin()
}

fn triangle_solid_angle_f64(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let volume = a.dot((b - a).cross(c - a)).abs();
    2.0 * volume.atan2(1.0 + a.dot(b) + b.dot(c) + c.dot(a))
}

/// The solid angle of a convex polygon seen from `x`, in f64.
fn polygon_solid_angle_f64(x: DVec3, vertices: &[DVec3]) -> f64 {
    let d: Vec<DVec3> = vertices.iter().map(|&v| (v - x).normalize()).collect();
    (1..d.len() - 1)
        .map(|i| triangle_solid_angle_f64(d[0], d[i], d[i + 1]))
        .sum()
}

/// pbrt-v4's `SampleSphericalTriangle` (Arvo 1995 through the vertex angles), transcribed for
/// any glam vector type: the reference for our reformulation, and the measure of how badly the
/// angle-based formulas do in f32 for small triangles.
macro_rules! arvo_angle_based {
    ($name:ident, $vec:ty, $float:ident) => {
        fn $name(a: $vec, b: $vec, c: $vec, u: [$float; 2]) -> Option<$vec> {
            use std::$float::consts::PI;
            let angle = |p: $vec, q: $vec| {
                if p.dot(q) < 0.0 {
                    PI - 2.0 * (0.5 * (p + q).length()).min(1.0).asin()
                } else {
                    2.0 * (0.5 * (q - p).length()).min(1.0).asin()
                }
            };
            let n_ab = a.cross(b).try_normalize()?;
            let n_bc = b.cross(c).try_normalize()?;
            let n_ca = c.cross(a).try_normalize()?;
            let alpha = angle(n_ab, -n_ca);
            let beta = angle(n_bc, -n_ab);
            let gamma = angle(n_ca, -n_bc);
            let a_pi = alpha + beta + gamma;
            if a_pi <= PI {
                return None;
            }
            let ap_pi = (1.0 - u[0]) * PI + u[0] * a_pi;
            let (cos_alpha, sin_alpha) = (alpha.cos(), alpha.sin());
            let sin_phi = ap_pi.sin() * cos_alpha - ap_pi.cos() * sin_alpha;
            let cos_phi = ap_pi.cos() * cos_alpha + ap_pi.sin() * sin_alpha;
            let k1 = cos_phi + cos_alpha;
            let k2 = sin_phi - sin_alpha * a.dot(b);
            let cos_bp = ((k2 + (k2 * cos_phi - k1 * sin_phi) * cos_alpha)
                / ((k2 * sin_phi + k1 * cos_phi) * sin_alpha))
                .clamp(-1.0, 1.0);
            let sin_bp = (1.0 - cos_bp * cos_bp).max(0.0).sqrt();
            let cp = cos_bp * a + sin_bp * (c - c.dot(a) * a).try_normalize()?;
            let cos_theta = 1.0 - u[1] * (1.0 - cp.dot(b));
            let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
            Some(cos_theta * b + sin_theta * (cp - cp.dot(b) * b).try_normalize()?)
        }
    };
}
arvo_angle_based!(arvo_f64, DVec3, f64);
arvo_angle_based!(arvo_f32, Vec3, f32);

/// Whether the ray `x + t·w`, `t > 0`, passes through the convex polygon, in f64, allowing
/// `tolerance` radians of slack at the edges (f32 directions are only good to ~1e-7 rad).
fn ray_hits_polygon(x: Vec3, vertices: &[Vec3], w: Vec3, tolerance: f64) -> bool {
    let x = x.as_dvec3();
    let w = w.as_dvec3().normalize();
    let r: Vec<DVec3> = vertices.iter().map(|v| v.as_dvec3() - x).collect();
    let n = r.len();
    let winding: DVec3 = (1..n - 1)
        .map(|i| (r[i] - r[0]).cross(r[i + 1] - r[0]))
        .sum();
    // With the winding normal pointing away from x, `r_i × r_{i+1}` points inside.
    let away = if winding.dot(r[0]) > 0.0 { 1.0 } else { -1.0 };
    w.dot(away * winding) > 0.0
        && (0..n).all(|i| w.dot(away * r[i].cross(r[(i + 1) % n]).normalize()) >= -tolerance)
}

/// The slack of `SphericalPolygon::pdf`'s inside test (radians), which only matters for tiny
/// polygons.
const EDGE_SLACK: f64 = 2.0 * f32::EPSILON as f64;

// ---------------------------------------------------------------------------------------------
// Test scenes

fn uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = 2.0 * std::f32::consts::PI * u.y;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// A random convex polygon: `n` vertices on an ellipse around `centre` in the plane with normal
/// `normal`, spaced by random gaps (no slivers), in a random winding.
fn random_polygon(rng: &mut Rng, n: usize, centre: Vec3, radius: f32, normal: Vec3) -> Vec<Vec3> {
    let frame = Frame::from_normal(normal);
    let aspect = 0.4 + 0.6 * rng.uniform();
    let gaps: Vec<f32> = (0..n).map(|_| 0.5 + rng.uniform()).collect();
    let scale = 2.0 * std::f32::consts::PI / gaps.iter().sum::<f32>();
    let start = 2.0 * std::f32::consts::PI * rng.uniform();
    let mut angle = start;
    let mut vertices: Vec<Vec3> = gaps
        .iter()
        .map(|g| {
            angle += g * scale;
            centre + radius * (angle.cos() * frame.t + aspect * angle.sin() * frame.b)
        })
        .collect();
    if rng.uniform() < 0.5 {
        vertices.reverse();
    }
    vertices
}

struct Case {
    name: String,
    x: Vec3,
    vertices: Vec<Vec3>,
}

/// Random polygons of 3 to 8 vertices seen from in front, edge-on, and from very close.
fn cases() -> Vec<Case> {
    let mut rng = Rng::new(2024, 1);
    let mut cases = Vec::new();
    for (i, n) in (3..=8).enumerate() {
        let normal = uniform_sphere(rng.uniform2());
        let centre = 4.0 * (rng.uniform2().extend(rng.uniform()) - 0.5);
        let radius = 0.3 + 1.2 * rng.uniform();
        let vertices = random_polygon(&mut rng, n, centre, radius, normal);
        let frame = Frame::from_normal(normal);
        let lateral = radius * (2.0 * rng.uniform2() - 1.0);
        let height = radius * (0.3 + 2.0 * rng.uniform());
        let side = if i % 2 == 0 { 1.0 } else { -1.0 };
        let x = centre + lateral.x * frame.t + lateral.y * frame.b + side * height * normal;
        cases.push(Case {
            name: format!("random {n}-gon"),
            x,
            vertices,
        });
    }
    // Edge-on: x barely above the plane, beside the polygon.
    for (n, height, lateral) in [(5, 0.05, 1.5), (7, 0.01, 3.0)] {
        let normal = uniform_sphere(rng.uniform2());
        let centre = Vec3::new(1.0, -2.0, 0.5);
        let vertices = random_polygon(&mut rng, n, centre, 1.0, normal);
        let frame = Frame::from_normal(normal);
        cases.push(Case {
            name: format!("edge-on {n}-gon (height {height}, {lateral} away)"),
            x: centre + lateral * frame.t + height * normal,
            vertices,
        });
    }
    // Near-hemisphere: x very close to a large polygon.
    for (n, radius, height) in [(6, 1.0, 0.01), (4, 5.0, 1e-3)] {
        let normal = uniform_sphere(rng.uniform2());
        let centre = Vec3::new(-3.0, 0.5, 2.0);
        let vertices = random_polygon(&mut rng, n, centre, radius, normal);
        let frame = Frame::from_normal(normal);
        cases.push(Case {
            name: format!("near-hemisphere {n}-gon (radius {radius}, height {height})"),
            x: centre + 0.1 * radius * frame.t + height * normal,
            vertices,
        });
    }
    cases
}

// ---------------------------------------------------------------------------------------------
// Chi-square machinery

/// The upper 1e-3 quantile of the chi-square distribution with `dof` degrees of freedom
/// (Wilson–Hilferty approximation).
fn chi_square_critical(dof: usize) -> f64 {
    let z = 3.090_232_306; // the standard normal's upper 1e-3 quantile
    let k = dof as f64;
    let h = 2.0 / (9.0 * k);
    k * (1.0 - h + z * h.sqrt()).powi(3)
}

/// Pearson's statistic and degrees of freedom, pooling bins whose expected count is below 5.
fn chi_square_statistic(observed: &[f64], expected: &[f64]) -> (f64, usize) {
    let mut order: Vec<usize> = (0..observed.len()).collect();
    order.sort_by(|&i, &j| expected[i].total_cmp(&expected[j]));
    let (mut statistic, mut bins) = (0.0, 0usize);
    let (mut pool_observed, mut pool_expected) = (0.0, 0.0);
    for i in order {
        if expected[i] < 5.0 || pool_expected > 0.0 && pool_expected < 5.0 {
            pool_observed += observed[i];
            pool_expected += expected[i];
        } else {
            statistic += (observed[i] - expected[i]).powi(2) / expected[i];
            bins += 1;
        }
    }
    if pool_observed > 0.0 || pool_expected > 0.0 {
        // A pool with nothing expected but something observed rejects outright.
        statistic += (pool_observed - pool_expected).powi(2) / pool_expected.max(1e-300);
        bins += 1;
    }
    (statistic, bins.saturating_sub(1).max(1))
}

/// Bins for directions from `x` through a polygon: a grid over the polygon's plane, uniform in
/// the angles `atan(p/h)` of the in-plane coordinates `p` around the foot of `x` (`h` its
/// height), so that cells stay comparable in solid angle even when `x` almost touches the plane.
struct PlaneGrid {
    x: DVec3,
    foot: DVec3,
    normal: DVec3, // towards x
    axes: [DVec3; 2],
    height: f64,
    lo: DVec2,
    step: DVec2,
    cells: usize,
}

impl PlaneGrid {
    fn new(x: Vec3, vertices: &[Vec3], cells: usize) -> Self {
        let v: Vec<DVec3> = vertices.iter().map(|v| v.as_dvec3()).collect();
        let x = x.as_dvec3();
        let mut normal = (1..v.len() - 1)
            .map(|i| (v[i] - v[0]).cross(v[i + 1] - v[0]))
            .sum::<DVec3>()
            .normalize();
        if normal.dot(x - v[0]) < 0.0 {
            normal = -normal;
        }
        let height = normal.dot(x - v[0]);
        let foot = x - height * normal;
        let t = normal.any_orthonormal_vector();
        let axes = [t, normal.cross(t)];
        let angles = |p: DVec3| {
            let q = p - foot;
            DVec2::new(
                (q.dot(axes[0]) / height).atan(),
                (q.dot(axes[1]) / height).atan(),
            )
        };
        let (lo, hi) = v
            .iter()
            .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(angles(p)), hi.max(angles(p)))
            });
        PlaneGrid {
            x,
            foot,
            normal,
            axes,
            height,
            lo,
            step: (hi - lo) / cells as f64,
            cells,
        }
    }

    /// The bin of direction `w`; the last bin (`cells²`) holds directions that miss the plane.
    fn bin(&self, w: Vec3) -> usize {
        let w = w.as_dvec3();
        let cos = -self.normal.dot(w);
        if cos.is_nan() || cos <= 0.0 {
            return self.cells * self.cells;
        }
        let q = self.x + (self.height / cos) * w - self.foot;
        let angles = DVec2::new(
            (q.dot(self.axes[0]) / self.height).atan(),
            (q.dot(self.axes[1]) / self.height).atan(),
        );
        let cell = ((angles - self.lo) / self.step).floor();
        let clamp = |c: f64| (c.max(0.0) as usize).min(self.cells - 1);
        clamp(cell.y) * self.cells + clamp(cell.x)
    }

    /// Expected counts of `n` samples per bin: the pdf integrated over each cell ∩ polygon. The
    /// cell is clipped exactly, fanned into triangles, and each triangle's exact solid angle is
    /// weighted by the pdf at its centroid (exact for a piecewise-constant pdf; the area
    /// fallback's pdf varies by < 1e-3 across the tiny polygons that use it).
    fn expected(&self, vertices: &[Vec3], pdf: impl Fn(Vec3) -> f32, n: f64) -> Vec<f64> {
        let flat: Vec<DVec2> = vertices
            .iter()
            .map(|v| {
                let q = v.as_dvec3() - self.foot;
                DVec2::new(q.dot(self.axes[0]), q.dot(self.axes[1]))
            })
            .collect();
        let mut expected = vec![0.0; self.cells * self.cells + 1];
        for j in 0..self.cells {
            for i in 0..self.cells {
                let corner = |k: f64, l: f64| {
                    let a = self.lo + self.step * DVec2::new(k, l);
                    self.height * DVec2::new(a.x.tan(), a.y.tan())
                };
                let (lo, hi) = (
                    corner(i as f64, j as f64),
                    corner(i as f64 + 1.0, j as f64 + 1.0),
                );
                let clipped = clip_to_rectangle(&flat, lo, hi);
                if clipped.len() < 3 {
                    continue;
                }
                let lift = |p: DVec2| self.foot + p.x * self.axes[0] + p.y * self.axes[1];
                let d: Vec<DVec3> = clipped
                    .iter()
                    .map(|&p| (lift(p) - self.x).normalize())
                    .collect();
                let mut mass = 0.0;
                for k in 1..d.len() - 1 {
                    let omega = triangle_solid_angle_f64(d[0], d[k], d[k + 1]);
                    let centroid = (d[0] + d[k] + d[k + 1]).normalize().as_vec3();
                    mass += omega * pdf(centroid) as f64;
                }
                expected[j * self.cells + i] = n * mass;
            }
        }
        expected
    }
}

/// Sutherland–Hodgman against an axis-aligned rectangle, in f64 (independent of the crate's).
fn clip_to_rectangle(polygon: &[DVec2], lo: DVec2, hi: DVec2) -> Vec<DVec2> {
    let mut out = polygon.to_vec();
    let planes = [
        (DVec2::X, lo.x),
        (-DVec2::X, -hi.x),
        (DVec2::Y, lo.y),
        (-DVec2::Y, -hi.y),
    ];
    for (n, d) in planes {
        let input = std::mem::take(&mut out);
        for (k, &a) in input.iter().enumerate() {
            let b = input[(k + 1) % input.len()];
            let (da, db) = (n.dot(a) - d, n.dot(b) - d);
            if da >= 0.0 {
                out.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                out.push(a + (da / (da - db)) * (b - a));
            }
        }
    }
    out
}

/// Chi-square test of `samples` (directions from `x`) against `pdf` over the polygon; returns
/// the statistic and its critical value at significance 1e-3.
fn chi_square_test(
    x: Vec3,
    vertices: &[Vec3],
    samples: &[Vec3],
    pdf: impl Fn(Vec3) -> f32,
) -> (f64, f64) {
    let grid = PlaneGrid::new(x, vertices, 12);
    let expected = grid.expected(vertices, pdf, samples.len() as f64);
    let mut observed = vec![0.0; expected.len()];
    for &w in samples {
        observed[grid.bin(w)] += 1.0;
    }
    let (statistic, dof) = chi_square_statistic(&observed, &expected);
    (statistic, chi_square_critical(dof))
}

/// 4π·mean(pdf) over uniform sphere directions, and that estimator's standard error computed
/// from the sample variance.
fn integrate_over_sphere(pdf: impl Fn(Vec3) -> f32, n: usize, rng: &mut Rng) -> (f64, f64) {
    let (mut sum, mut sum_sq) = (0.0, 0.0);
    for _ in 0..n {
        let f = 4.0 * PI * pdf(uniform_sphere(rng.uniform2())) as f64;
        sum += f;
        sum_sq += f * f;
    }
    let mean = sum / n as f64;
    let variance = (sum_sq / n as f64 - mean * mean).max(0.0) * n as f64 / (n - 1) as f64;
    (mean, (variance / n as f64).sqrt())
}

/// Checks that every sample's pdf matches `pdf(wi)` and that its ray hits the polygon; returns
/// the directions.
fn checked_samples(case: &Case, polygon: &SphericalPolygon, n: usize, rng: &mut Rng) -> Vec<Vec3> {
    (0..n)
        .map(|k| {
            let Some((wi, pdf)) = polygon.sample(rng.uniform2()) else {
                panic!("{}: sample {k} failed", case.name);
            };
            assert!(
                wi.is_finite() && (wi.length() - 1.0).abs() < 1e-5,
                "{}: {wi}",
                case.name
            );
            assert!(pdf.is_finite() && pdf > 0.0, "{}: pdf {pdf}", case.name);
            let evaluated = polygon.pdf(wi);
            assert!(
                (evaluated - pdf).abs() <= 1e-3 * pdf,
                "{}: sampled pdf {pdf}, pdf(wi) {evaluated}, wi {wi}",
                case.name
            );
            assert!(
                ray_hits_polygon(case.x, &case.vertices, wi, 1e-6),
                "{}: sample {wi} misses the polygon",
                case.name
            );
            wi
        })
        .collect()
}

// ---------------------------------------------------------------------------------------------
// Tests

#[test]
fn rectangle_solid_angle_matches_closed_form() {
    let mut rng = Rng::new(3, 0);
    for (a, b, d) in [
        (1.0f32, 1.0f32, 0.5f32),
        (2.0, 0.5, 1.0),
        (0.1, 3.0, 0.2),
        (1.0, 1.0, 10.0),
        (0.01, 0.02, 1.0),
        (10.0, 10.0, 1e-3),
    ] {
        // On the z axis, the f32 corners are the rectangle that the closed form describes.
        let corner = |s: f32, t: f32| Vec3::new(s * 0.5 * a, t * 0.5 * b, -d);
        let rectangle = [
            corner(-1.0, -1.0),
            corner(1.0, -1.0),
            corner(1.0, 1.0),
            corner(-1.0, 1.0),
        ];
        let polygon = SphericalPolygon::new(Vec3::ZERO, &rectangle).unwrap();
        let exact = rectangle_solid_angle(2.0 * (0.5 * a) as f64, 2.0 * (0.5 * b) as f64, d as f64);
        let omega = polygon.solid_angle() as f64;
        assert!(
            ((omega - exact) / exact).abs() < 1e-6,
            "{a}×{b} at {d}: {omega} vs {exact}"
        );

        // Anywhere else, in any orientation: rounding the corners to f32 changes the rectangle,
        // so compare with the f64 solid angle of the rounded corners.
        let frame = Frame::from_normal(uniform_sphere(rng.uniform2()));
        let centre = Vec3::new(3.0, -1.0, 2.0);
        let corner = |s: f32, t: f32| centre + s * 0.5 * a * frame.t + t * 0.5 * b * frame.b;
        let rectangle = [
            corner(-1.0, -1.0),
            corner(1.0, -1.0),
            corner(1.0, 1.0),
            corner(-1.0, 1.0),
        ];
        let x = centre + d * frame.n;
        let polygon = SphericalPolygon::new(x, &rectangle).unwrap();
        let reference = polygon_solid_angle_f64(
            x.as_dvec3(),
            &rectangle.iter().map(|v| v.as_dvec3()).collect::<Vec<_>>(),
        );
        let omega = polygon.solid_angle() as f64;
        assert!(
            ((omega - reference) / reference).abs() < 1e-6,
            "{a}×{b} at {d}, moved: {omega} vs {reference}"
        );
        assert!(
            ((omega - exact) / exact).abs() < 1e-3,
            "{a}×{b} at {d}, moved: {omega} vs {exact}"
        );
    }
}

#[test]
fn triangle_sampler_matches_arvo_reference() {
    // Same `u`, same map: our f32 sampler against Arvo's formulas in f64, for triangles from 1 sr
    // down to 1e-8 sr. The error is measured relative to the triangle's angular size √Ω.
    let mut rng = Rng::new(5, 0);
    for omega_target in [1.0f64, 1e-2, 1e-4, 1e-6, 1e-8] {
        let (mut ours, mut ours_absolute, mut angle_based_f32) = (0.0f64, 0.0f64, 0.0f64);
        for _ in 0..200 {
            let centre = uniform_sphere(rng.uniform2());
            let frame = Frame::from_normal(centre);
            let size = (2.0 * omega_target).sqrt() as f32;
            let vertex = |rng: &mut Rng| {
                let o = size * (2.0 * rng.uniform2() - 1.0);
                (centre + o.x * frame.t + o.y * frame.b).normalize()
            };
            let (a, b, c) = (vertex(&mut rng), vertex(&mut rng), vertex(&mut rng));
            let omega = spherical_triangle_solid_angle(a, b, c) as f64;
            if omega < 0.05 * omega_target {
                continue; // a sliver: its size is not the one measured here
            }
            for _ in 0..10 {
                let u = rng.uniform2();
                // The angle-based formulas are sensitive to vertices off the unit sphere, as f32
                // vertices are by ~1e-7: renormalise in f64.
                let (da, db, dc) = (
                    a.as_dvec3().normalize(),
                    b.as_dvec3().normalize(),
                    c.as_dvec3().normalize(),
                );
                let reference = arvo_f64(da, db, dc, [u.x as f64, u.y as f64]).unwrap();
                let w = sample_spherical_triangle(a, b, c, u).unwrap().as_dvec3();
                ours_absolute = ours_absolute.max((w - reference).length());
                ours = ours.max((w - reference).length() / omega.sqrt());
                if let Some(w32) = arvo_f32(a, b, c, [u.x, u.y]) {
                    let error = (w32.as_dvec3() - reference).length() / omega.sqrt();
                    angle_based_f32 =
                        angle_based_f32.max(if error.is_finite() { error } else { 1.0 });
                } else {
                    angle_based_f32 = 1.0;
                }
            }
        }
        println!(
            "Ω ≈ {omega_target:.0e}: max error / √Ω: ours {ours:.1e}, angle-based f32 {angle_based_f32:.1e}"
        );
        // A few f32 ulps of a unit vector, whatever the size (the angle-based formulas in f32
        // are off by the whole triangle at 1e-4 sr).
        assert!(
            ours_absolute < 1e-6,
            "Ω ≈ {omega_target:e}: error {ours_absolute:e} rad"
        );
    }
}

#[test]
fn polygon_sampling_is_consistent_and_matches_its_pdf() {
    let mut rng = Rng::new(99, 7);
    for case in cases() {
        let polygon = SphericalPolygon::new(case.x, &case.vertices)
            .unwrap_or_else(|| panic!("{}: no spherical polygon", case.name));
        let exact = polygon_solid_angle_f64(
            case.x.as_dvec3(),
            &case
                .vertices
                .iter()
                .map(|v| v.as_dvec3())
                .collect::<Vec<_>>(),
        );
        let omega = polygon.solid_angle() as f64;
        assert!(
            ((omega - exact) / exact).abs() < 1e-4,
            "{}: Ω {omega} vs {exact}",
            case.name
        );
        assert!(!polygon.is_area_sampled(), "{}: Ω = {omega}", case.name);

        // (a), (b): every sample's pdf agrees with pdf(wi), and its ray hits the polygon.
        let samples = checked_samples(&case, &polygon, 100_000, &mut rng);

        // (c): ∫ pdf dω = 1. The tolerance is 4 × the estimator's standard error, computed from
        // the sample variance.
        let (integral, standard_error) =
            integrate_over_sphere(|w| polygon.pdf(w), 1 << 20, &mut rng);
        assert!(
            (integral - 1.0).abs() <= 4.0 * standard_error,
            "{}: ∫pdf = {integral} ± {standard_error}",
            case.name
        );

        // (d): the samples follow the pdf.
        let (statistic, critical) =
            chi_square_test(case.x, &case.vertices, &samples, |w| polygon.pdf(w));
        println!(
            "{}: Ω = {omega:.3e}, ∫pdf = {integral:.4} ± {standard_error:.1e}, χ² = {statistic:.1} (critical {critical:.1})",
            case.name
        );
        assert!(
            statistic < critical,
            "{}: χ² = {statistic} ≥ {critical}",
            case.name
        );
    }
}

#[test]
fn chi_square_test_rejects_a_wrong_sampler() {
    // A square seen at a grazing angle from near one edge: sampling it by area while claiming
    // the uniform solid-angle pdf must be caught.
    let square = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(1.0, 1.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
    ];
    let x = Vec3::new(-0.2, 0.5, 0.15);
    let polygon = SphericalPolygon::new(x, &square).unwrap();
    assert!(!polygon.is_area_sampled());
    let mut rng = Rng::new(1, 2);
    let wrong: Vec<Vec3> = (0..100_000)
        .map(|_| (sample_polygon_area(&square, rng.uniform2()) - x).normalize())
        .collect();
    let (statistic, critical) = chi_square_test(x, &square, &wrong, |w| polygon.pdf(w));
    println!(
        "area samples against the solid-angle pdf: χ² = {statistic:.0} (critical {critical:.1})"
    );
    assert!(
        statistic > critical,
        "χ² = {statistic} < {critical}: wrong sampler accepted"
    );
    // Subtler: one sample in ten from the wrong sampler.
    let mixed: Vec<Vec3> = (0..100_000)
        .map(|k| {
            let u = rng.uniform2();
            match k % 10 {
                0 => (sample_polygon_area(&square, u) - x).normalize(),
                _ => polygon.sample(u).unwrap().0,
            }
        })
        .collect();
    let (statistic, critical) = chi_square_test(x, &square, &mixed, |w| polygon.pdf(w));
    println!("10 % area samples: χ² = {statistic:.0} (critical {critical:.1})");
    assert!(
        statistic > critical,
        "χ² = {statistic} < {critical}: 10 % wrong samples accepted"
    );
    // The right sampler passes the same test.
    let right: Vec<Vec3> = (0..100_000)
        .map(|_| polygon.sample(rng.uniform2()).unwrap().0)
        .collect();
    let (statistic, critical) = chi_square_test(x, &square, &right, |w| polygon.pdf(w));
    assert!(
        statistic < critical,
        "χ² = {statistic} ≥ {critical}: right sampler rejected"
    );
}

#[test]
fn tiny_polygons_fall_back_to_area_sampling() {
    let mut rng = Rng::new(17, 3);
    // Far from the world origin, so that f32 positions are coarse compared with the polygon.
    let centre = Vec3::new(120.0, -45.0, 30.0);
    for (side, distance, tilt) in [
        (1e-3f32, 1.0f32, 0.0f32),
        (1e-3, 1.0, 1.2),
        (1e-4, 10.0, 0.5),
    ] {
        let normal = uniform_sphere(rng.uniform2());
        let frame = Frame::from_normal(normal);
        // View direction tilted by `tilt` from the normal.
        let view = (tilt.cos() * normal + tilt.sin() * frame.t).normalize();
        let x = centre + distance * view;
        let corner = |s: f32, t: f32| centre + 0.5 * side * (s * frame.t + t * frame.b);
        let vertices = vec![
            corner(-1.0, -1.0),
            corner(1.0, -1.0),
            corner(1.0, 1.0),
            corner(-1.0, 1.0),
        ];
        let case = Case {
            name: format!("square {side} at {distance}, tilt {tilt}"),
            x,
            vertices,
        };
        let polygon = SphericalPolygon::new(case.x, &case.vertices).unwrap();
        // Rounding the corners to f32 this far from the origin distorts the square by up to 10 %:
        // compare with the f64 solid angle of the rounded corners.
        let reference = polygon_solid_angle_f64(
            x.as_dvec3(),
            &case
                .vertices
                .iter()
                .map(|v| v.as_dvec3())
                .collect::<Vec<_>>(),
        );
        let omega = polygon.solid_angle() as f64;
        assert!(
            omega <= 1e-6 && omega < SMALL_SOLID_ANGLE as f64,
            "{}: Ω {omega}",
            case.name
        );
        assert!(
            ((omega - reference) / reference).abs() < 1e-5,
            "{}: Ω {omega} vs {reference}",
            case.name
        );
        assert!(polygon.is_area_sampled(), "{}", case.name);
        let samples = checked_samples(&case, &polygon, 20_000, &mut rng);
        // ∫ pdf dω = 1 by uniform sampling of a cone around the polygon (the sphere is hopeless
        // here); tolerance 4 standard errors.
        let axis = (centre.as_dvec3() - x.as_dvec3()).normalize();
        let (t, b) = axis.any_orthonormal_pair();
        let widest = case
            .vertices
            .iter()
            .map(|v| {
                let d = v.as_dvec3() - x.as_dvec3();
                d.cross(axis).length().atan2(d.dot(axis))
            })
            .fold(0.0, f64::max);
        let cos_max = (1.5 * widest).cos(); // a cone around the whole square
        let cone_pdf = 1.0 / (2.0 * PI * (1.0 - cos_max));
        let n = 200_000;
        let (mut sum, mut sum_sq) = (0.0, 0.0);
        for _ in 0..n {
            let u = rng.uniform2().as_dvec2();
            let z = 1.0 - u.x * (1.0 - cos_max);
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = 2.0 * PI * u.y;
            let w = (r * phi.cos() * t + r * phi.sin() * b + z * axis).as_vec3();
            let f = polygon.pdf(w) as f64 / cone_pdf;
            sum += f;
            sum_sq += f * f;
        }
        let mean = sum / n as f64;
        let standard_error = ((sum_sq / n as f64 - mean * mean) / (n - 1) as f64).sqrt();
        // The inside test's edge slack adds a band of width EDGE_SLACK around the polygon: at
        // 1e-10 sr that is +10 %, the limit of what f32 directions resolve.
        let d: Vec<DVec3> = case
            .vertices
            .iter()
            .map(|v| (v.as_dvec3() - x.as_dvec3()).normalize())
            .collect();
        let perimeter: f64 = (0..4).map(|i| d[i].angle_between(d[(i + 1) % 4])).sum();
        let expected = 1.0 + perimeter * EDGE_SLACK / omega;
        println!(
            "{}: Ω = {omega:.2e}, ∫pdf = {mean:.4} ± {standard_error:.1e} (expected {expected:.4})",
            case.name
        );
        assert!(
            (mean - expected).abs() <= 4.0 * standard_error,
            "{}: ∫pdf = {mean} ± {standard_error}, expected {expected}",
            case.name
        );
        let (statistic, critical) =
            chi_square_test(case.x, &case.vertices, &samples, |w| polygon.pdf(w));
        assert!(
            statistic < critical,
            "{}: χ² = {statistic} ≥ {critical}",
            case.name
        );
    }
}

#[test]
fn near_hemisphere_polygon_is_robust() {
    // x at 1e-3 above the centre of a 10 × 10 square: Ω just under 2π.
    let (side, height) = (10.0f32, 1e-3f32);
    let centre = Vec3::new(-2.0, 7.0, 1.0);
    let frame = Frame::from_normal(Vec3::new(0.3, -0.5, 0.8).normalize());
    let corner = |s: f32, t: f32| centre + 0.5 * side * (s * frame.t + t * frame.b);
    let case = Case {
        name: "near-hemisphere square".into(),
        x: centre + height * frame.n,
        vertices: vec![
            corner(-1.0, -1.0),
            corner(1.0, -1.0),
            corner(1.0, 1.0),
            corner(-1.0, 1.0),
        ],
    };
    let polygon = SphericalPolygon::new(case.x, &case.vertices).unwrap();
    let exact = rectangle_solid_angle(side as f64, side as f64, height as f64);
    let omega = polygon.solid_angle() as f64;
    assert!(
        ((omega - exact) / exact).abs() < 1e-5,
        "Ω {omega} vs {exact}"
    );
    assert!(!polygon.is_area_sampled());
    let mut rng = Rng::new(23, 0);
    let samples = checked_samples(&case, &polygon, 100_000, &mut rng);
    let (integral, standard_error) = integrate_over_sphere(|w| polygon.pdf(w), 1 << 20, &mut rng);
    assert!(
        (integral - 1.0).abs() <= 4.0 * standard_error,
        "∫pdf = {integral} ± {standard_error}"
    );
    let (statistic, critical) =
        chi_square_test(case.x, &case.vertices, &samples, |w| polygon.pdf(w));
    assert!(statistic < critical, "χ² = {statistic} ≥ {critical}");
}
