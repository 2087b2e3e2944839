//! Scene building blocks shared by the integration tests.
#![allow(dead_code)]

use glam::{Mat4, Vec3};
use portalview::asset::desc::{MaterialDesc, MeshDesc, PortalDesc, SceneDesc};
use portalview::camera::Camera;
use portalview::light::Strategy;
use portalview::material::Material;
use portalview::render::film::Film;
use portalview::render::integrator::{Integrator, RenderSettings};
use portalview::render::stats::Stats;
use portalview::sampling::{Rng, Sampler};
use portalview::scene::Scene;

pub use portalview::asset::builtin::flat_mesh as flat;

/// A portal from a convex polygon given in world space.
pub fn portal(name: &str, target: &str, alpha: f32, corners: &[Vec3]) -> PortalDesc {
    PortalDesc {
        name: name.to_owned(),
        target: target.to_owned(),
        alpha,
        auto_alpha: false,
        local_triangles: (1..corners.len() - 1)
            .map(|i| [corners[0], corners[i], corners[i + 1]])
            .collect(),
        world_from_local: Mat4::IDENTITY,
        node_index: None,
    }
}

/// A square of half-size `h` centred at `c`, in the plane with normal `n` (its front).
pub fn square(c: Vec3, n: Vec3, h: f32) -> Vec<Vec3> {
    let n = n.normalize();
    let t = n.any_orthonormal_vector();
    let b = n.cross(t);
    vec![
        c - h * t - h * b,
        c + h * t - h * b,
        c + h * t + h * b,
        c - h * t + h * b,
    ]
}

pub fn camera(eye: Vec3, target: Vec3) -> Option<Camera> {
    Some(Camera {
        eye,
        target,
        up: Vec3::Y,
        yfov: 0.8,
        aspect: 1.0,
    })
}

/// A white diffuse floor at y = 0 and a polygon light `light` (front = its winding).
pub fn floor_and_light(albedo: f32, light: Vec<Vec3>, le: f32) -> SceneDesc {
    SceneDesc {
        name: "test".into(),
        materials: vec![
            MaterialDesc {
                ..MaterialDesc::diffuse("floor", Vec3::splat(albedo))
            },
            MaterialDesc::emitter("light", Vec3::splat(le), false),
        ],
        meshes: vec![
            flat(
                "floor",
                0,
                &[vec![
                    Vec3::new(-50.0, 0.0, -50.0),
                    Vec3::new(-50.0, 0.0, 50.0),
                    Vec3::new(50.0, 0.0, 50.0),
                    Vec3::new(50.0, 0.0, -50.0),
                ]],
            ),
            flat("light", 1, &[light]),
        ],
        portals: vec![],
        lamps: vec![],
        warnings: Vec::new(),
        images: Vec::new(),
        camera: camera(Vec3::new(0.0, 3.0, 3.0), Vec3::ZERO),
        environment: None,
    }
}

/// Lambert's closed-form irradiance at `x` (normal `n`) from a polygon of radiance `le`:
/// `E = Le/2 · |Σ angle(v_i, v_{i+1}) · (n · unit(v_i × v_{i+1}))|`.
pub fn lambert_irradiance(x: Vec3, n: Vec3, polygon: &[Vec3], le: f32) -> f32 {
    let k = polygon.len();
    let sum: f32 = (0..k)
        .map(|i| {
            let a = (polygon[i] - x).normalize();
            let b = (polygon[(i + 1) % k] - x).normalize();
            let angle = a.dot(b).clamp(-1.0, 1.0).acos();
            angle * n.dot(a.cross(b).normalize())
        })
        .sum();
    0.5 * le * sum.abs()
}

/// Mean and standard error of a sample.
pub fn mean_and_se(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, (var / n).sqrt())
}

/// Makes material `index` a pure Lambertian (glTF materials carry a specular layer).
pub fn lambertian(mut scene: Scene, index: usize, albedo: f32) -> Scene {
    let mut geometry = std::sync::Arc::try_unwrap(scene.geometry).ok().unwrap();
    geometry.materials[index] = Material::lambertian(Vec3::splat(albedo));
    scene.geometry = std::sync::Arc::new(geometry);
    scene
}

/// Rectangles tiling the rectangle `[0, su] × [0, sv]` of the plane through `origin` spanned by
/// the unit axes `u`, `v`, minus the disjoint rectangular `holes` `(u0, u1, v0, v1)`: the cells
/// of the grid through every hole's sides, less those inside a hole. Wound around `u × v`.
pub fn plate(
    origin: Vec3,
    (u, su): (Vec3, f32),
    (v, sv): (Vec3, f32),
    holes: &[(f32, f32, f32, f32)],
) -> Vec<Vec<Vec3>> {
    let mut us: Vec<f32> = [0.0, su].into_iter().collect();
    let mut vs: Vec<f32> = [0.0, sv].into_iter().collect();
    for &(u0, u1, v0, v1) in holes {
        us.extend([u0, u1]);
        vs.extend([v0, v1]);
    }
    us.sort_by(f32::total_cmp);
    vs.sort_by(f32::total_cmp);
    let mut rects = vec![];
    for a in us.windows(2) {
        for b in vs.windows(2) {
            let (cu, cv) = (0.5 * (a[0] + a[1]), 0.5 * (b[0] + b[1]));
            let in_hole = holes
                .iter()
                .any(|&(u0, u1, v0, v1)| (u0..u1).contains(&cu) && (v0..v1).contains(&cv));
            if a[1] > a[0] && b[1] > b[0] && !in_hole {
                let p = |s: f32, t: f32| origin + s * u + t * v;
                rects.push(vec![
                    p(a[0], b[0]),
                    p(a[1], b[0]),
                    p(a[1], b[1]),
                    p(a[0], b[1]),
                ]);
            }
        }
    }
    rects
}

/// A floor, a light of half-size 0.6 at height 2 facing down, and under it at height 1.5 an
/// opaque plate with two windows side by side, each a portal of the light: points below see
/// the light through both.
pub fn two_windows() -> SceneDesc {
    let light = square(Vec3::new(0.0, 2.0, 0.0), -Vec3::Y, 0.6);
    let mut desc = floor_and_light(0.6, light, 20.0);
    desc.materials
        .push(MaterialDesc::diffuse("plate", Vec3::splat(0.3)));
    let windows = [(2.5, 2.9, 2.8, 3.2), (3.1, 3.5, 2.8, 3.2)];
    let origin = Vec3::new(-3.0, 1.5, -3.0);
    desc.meshes.push(flat(
        "plate",
        2,
        &plate(origin, (Vec3::X, 6.0), (Vec3::Z, 6.0), &windows),
    ));
    for (k, &(u0, u1, v0, v1)) in windows.iter().enumerate() {
        let p = |s: f32, t: f32| origin + Vec3::new(s, 0.0, t);
        let corners = [p(u0, v0), p(u1, v0), p(u1, v1), p(u0, v1)];
        desc.portals
            .push(portal(&format!("window{k}"), "light", 0.1, &corners));
    }
    desc.camera = camera(Vec3::new(0.0, 1.3, 2.8), Vec3::new(0.0, 0.0, -0.3));
    desc
}

/// A light of half-size 0.4 at height 2 facing down, in a box (x, z in [-0.6, 0.6], y in
/// [1, 2.05]) with an opening in its floor and one in its +x wall, a portal on each: points
/// below and to the side see the light through both openings, at an angle to each other.
pub fn box_with_two_openings() -> SceneDesc {
    let light = square(Vec3::new(0.0, 2.0, 0.0), -Vec3::Y, 0.4);
    let mut desc = floor_and_light(0.6, light, 20.0);
    desc.materials
        .push(MaterialDesc::diffuse("box", Vec3::splat(0.3)));
    let (h, y0, y1) = (0.6, 1.0, 2.05);
    let bottom_hole = (0.15, 1.05, 0.15, 1.05);
    let side_hole = (0.1, 0.9, 0.3, 0.9);
    let bottom_origin = Vec3::new(-h, y0, -h);
    let side_origin = Vec3::new(h, y0, -h);
    let mut faces = plate(
        bottom_origin,
        (Vec3::X, 2.0 * h),
        (Vec3::Z, 2.0 * h),
        &[bottom_hole],
    );
    faces.extend(plate(
        side_origin,
        (Vec3::Y, y1 - y0),
        (Vec3::Z, 2.0 * h),
        &[side_hole],
    ));
    let solid = [
        (
            Vec3::new(-h, y0, -h),
            (Vec3::Y, y1 - y0),
            (Vec3::Z, 2.0 * h),
        ),
        (
            Vec3::new(-h, y0, -h),
            (Vec3::X, 2.0 * h),
            (Vec3::Y, y1 - y0),
        ),
        (Vec3::new(-h, y0, h), (Vec3::X, 2.0 * h), (Vec3::Y, y1 - y0)),
        (
            Vec3::new(-h, y1, -h),
            (Vec3::X, 2.0 * h),
            (Vec3::Z, 2.0 * h),
        ),
    ];
    for (origin, u, v) in solid {
        faces.extend(plate(origin, u, v, &[]));
    }
    desc.meshes.push(flat("box", 2, &faces));
    let corners = |origin: Vec3, u: Vec3, v: Vec3, (u0, u1, v0, v1): (f32, f32, f32, f32)| {
        let p = |s: f32, t: f32| origin + s * u + t * v;
        [p(u0, v0), p(u1, v0), p(u1, v1), p(u0, v1)]
    };
    let bottom = corners(bottom_origin, Vec3::X, Vec3::Z, bottom_hole);
    let side = corners(side_origin, Vec3::Y, Vec3::Z, side_hole);
    desc.portals.push(portal("bottom", "light", 0.1, &bottom));
    desc.portals.push(portal("side", "light", 0.1, &side));
    desc.camera = camera(Vec3::new(2.6, 1.2, 2.2), Vec3::new(0.3, 0.4, 0.0));
    desc
}

/// Two lights of different power, each with a portal, over a floor and nothing else: points
/// see both, and the renderer picks one by power.
pub fn two_lights() -> SceneDesc {
    let first = square(Vec3::new(-0.8, 2.0, 0.0), -Vec3::Y, 0.4);
    let mut desc = floor_and_light(0.6, first, 10.0);
    desc.materials
        .push(MaterialDesc::emitter("second", Vec3::splat(60.0), false));
    let normal = Vec3::new(-0.3, -1.0, 0.1);
    desc.meshes.push(flat(
        "second",
        2,
        &[square(Vec3::new(0.9, 1.8, 0.3), normal, 0.25)],
    ));
    let first_portal = square(Vec3::new(-0.8, 1.6, 0.0), -Vec3::Y, 0.2);
    let second_portal = square(Vec3::new(0.8, 1.4, 0.33), normal, 0.35);
    desc.portals
        .push(portal("first", "light", 0.1, &first_portal));
    desc.portals
        .push(portal("second", "second", 0.1, &second_portal));
    desc
}

/// The radiance leaving floor point `x`, estimated by the full renderer (light sampling by
/// `strategy`, MIS with BSDF sampling) from `n` camera-like rays that hit it.
pub fn floor_radiance(
    scene: &Scene,
    (strategy, alpha): (Strategy, Option<f32>),
    x: Vec3,
    n: usize,
    seed: u64,
) -> (f64, f64) {
    let settings = RenderSettings {
        strategy,
        alpha,
        seed,
        ..RenderSettings::default()
    };
    floor_radiance_with(scene, settings, x, n)
}

/// [`floor_radiance`] with all of the renderer's settings given (its seed among them).
pub fn floor_radiance_with(
    scene: &Scene,
    settings: RenderSettings,
    x: Vec3,
    n: usize,
) -> (f64, f64) {
    let seed = settings.seed;
    let integrator = Integrator::new(scene, settings);
    let eye = x + Vec3::new(0.3, 1.0, 0.2);
    let mut stats = Stats::default();
    let values: Vec<f64> = (0..n)
        .map(|i| {
            let mut rng = Sampler::from(Rng::keyed(seed, &[i as u64]));
            let l = integrator.radiance(eye, (x - eye).normalize(), &mut rng, &mut stats);
            assert!(l.is_finite(), "non-finite radiance at {x}");
            l.x as f64
        })
        .collect();
    mean_and_se(&values)
}

/// A UV sphere of radius `r` around `c` (`segments` around, `rings` from pole to pole), wound
/// outwards: a bulb, as many triangles as a modelling tool gives it.
pub fn uv_sphere(
    node: &str,
    material: usize,
    c: Vec3,
    r: f32,
    (segments, rings): (u32, u32),
) -> MeshDesc {
    let mut positions = vec![c + r * Vec3::Y];
    for i in 1..rings {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        for k in 0..segments {
            let phi = std::f32::consts::TAU * k as f32 / segments as f32;
            positions.push(
                c + r * Vec3::new(
                    theta.sin() * phi.cos(),
                    theta.cos(),
                    theta.sin() * phi.sin(),
                ),
            );
        }
    }
    positions.push(c - r * Vec3::Y);
    let ring = |i: u32, k: u32| 1 + (i - 1) * segments + k % segments;
    let bottom = positions.len() as u32 - 1;
    let mut indices = vec![];
    for k in 0..segments {
        indices.push([0, ring(1, k + 1), ring(1, k)]);
        for i in 1..rings - 1 {
            indices.push([ring(i, k), ring(i, k + 1), ring(i + 1, k + 1)]);
            indices.push([ring(i, k), ring(i + 1, k + 1), ring(i + 1, k)]);
        }
        indices.push([bottom, ring(rings - 1, k), ring(rings - 1, k + 1)]);
    }
    let normals = positions.iter().map(|&p| (p - c).normalize()).collect();
    MeshDesc {
        node_name: node.to_owned(),
        material,
        positions,
        normals,
        indices,
        ..Default::default()
    }
}

/// An open cylinder along x (a neon tube): radius `r`, from `c.x − half` to `c.x + half`,
/// `segments` sides, wound outwards.
pub fn tube(
    node: &str,
    material: usize,
    c: Vec3,
    (half, r): (f32, f32),
    segments: u32,
) -> MeshDesc {
    let mut positions = vec![];
    for k in 0..segments {
        let phi = std::f32::consts::TAU * k as f32 / segments as f32;
        let around = r * Vec3::new(0.0, phi.cos(), phi.sin());
        positions.push(c + around - half * Vec3::X);
        positions.push(c + around + half * Vec3::X);
    }
    let mut indices = vec![];
    for k in 0..segments {
        let (a, b) = (2 * k, 2 * ((k + 1) % segments));
        indices.push([a, b, b + 1]);
        indices.push([a, b + 1, a + 1]);
    }
    let normals = positions
        .iter()
        .map(|&p| Vec3::new(0.0, p.y - c.y, p.z - c.z).normalize())
        .collect();
    MeshDesc {
        node_name: node.to_owned(),
        material,
        positions,
        normals,
        indices,
        ..Default::default()
    }
}

/// The solid walls of a box `lo..hi` (grey, double-sided) with `holes` in its bottom face,
/// given as `(x0, x1, z0, z1)` offsets from `lo`.
fn box_with_holes(desc: &mut SceneDesc, lo: Vec3, hi: Vec3, holes: &[(f32, f32, f32, f32)]) {
    desc.materials
        .push(MaterialDesc::diffuse("shade", Vec3::splat(0.3)));
    let material = desc.materials.len() - 1;
    desc.meshes
        .push(flat("shade", material, &box_faces(lo, hi, holes, &[])));
}

/// The six faces of the box `lo..hi` as rectangles, with `bottom` and `top` holes given as
/// `(x0, x1, z0, z1)` offsets from `lo` (see [`plate`]).
pub fn box_faces(
    lo: Vec3,
    hi: Vec3,
    bottom: &[(f32, f32, f32, f32)],
    top: &[(f32, f32, f32, f32)],
) -> Vec<Vec<Vec3>> {
    let size = hi - lo;
    let mut faces = plate(lo, (Vec3::X, size.x), (Vec3::Z, size.z), bottom);
    for (origin, u, v) in [
        (lo, (Vec3::Y, size.y), (Vec3::Z, size.z)),
        (
            Vec3::new(hi.x, lo.y, lo.z),
            (Vec3::Y, size.y),
            (Vec3::Z, size.z),
        ),
        (lo, (Vec3::X, size.x), (Vec3::Y, size.y)),
        (
            Vec3::new(lo.x, lo.y, hi.z),
            (Vec3::X, size.x),
            (Vec3::Y, size.y),
        ),
    ] {
        faces.extend(plate(origin, u, v, &[]));
    }
    faces.extend(plate(
        Vec3::new(lo.x, hi.y, lo.z),
        (Vec3::X, size.x),
        (Vec3::Z, size.z),
        top,
    ));
    faces
}

/// A floor and a bulb of 12 × 8 facets (86 vertices: more than the exact hull takes, so its
/// solid is the bounding prism) in a closed box with its whole bottom open, a portal across the
/// opening: below it, points see the whole bulb (antiumbra) or part of it (antipenumbra).
pub fn bulb_in_shade() -> SceneDesc {
    let mut desc = floor_and_light(0.6, square(Vec3::Y, Vec3::Y, 0.1), 20.0);
    desc.meshes[1] = uv_sphere("bulb", 1, Vec3::new(0.0, 1.55, 0.0), 0.12, (12, 8));
    let (lo, hi) = (Vec3::new(-0.3, 1.2, -0.3), Vec3::new(0.3, 1.8, 0.3));
    box_with_holes(&mut desc, lo, hi, &[(0.0, 0.6, 0.0, 0.6)]);
    let opening = [
        Vec3::new(-0.3, 1.2, -0.3),
        Vec3::new(0.3, 1.2, -0.3),
        Vec3::new(0.3, 1.2, 0.3),
        Vec3::new(-0.3, 1.2, 0.3),
    ];
    desc.portals.push(portal("opening", "bulb", 0.1, &opening));
    desc.camera = camera(Vec3::new(0.0, 2.2, 2.4), Vec3::new(0.0, 0.4, 0.0));
    desc
}

/// A bulb in a wide closed box (a shade that bulges far past its opening) with a small hole in
/// its bottom, a portal across the hole, and a ceiling panel elsewhere in the room: the box's
/// sides are far outside the box around the bulb and the portal.
pub fn bulging_shade(panel_le: f32) -> SceneDesc {
    let panel = square(Vec3::new(-1.5, 2.5, 0.0), -Vec3::Y, 0.2);
    let mut desc = floor_and_light(0.6, panel, panel_le);
    desc.materials
        .push(MaterialDesc::emitter("bulb", Vec3::splat(20.0), false));
    desc.meshes.push(uv_sphere(
        "bulb",
        desc.materials.len() - 1,
        Vec3::new(0.0, 1.5, 0.0),
        0.05,
        (12, 8),
    ));
    let (lo, hi) = (Vec3::new(-0.4, 1.2, -0.4), Vec3::new(0.4, 1.8, 0.4));
    box_with_holes(&mut desc, lo, hi, &[(0.3, 0.5, 0.3, 0.5)]);
    let opening = [
        Vec3::new(-0.1, 1.2, -0.1),
        Vec3::new(0.1, 1.2, -0.1),
        Vec3::new(0.1, 1.2, 0.1),
        Vec3::new(-0.1, 1.2, 0.1),
    ];
    desc.portals.push(portal("opening", "bulb", 0.1, &opening));
    desc
}

/// A floor and a neon tube of 8 sides (16 vertices: hulled exactly) in a box, over a slot in
/// the box's bottom narrower and shorter than the tube, a portal in the slot: far below,
/// every direction through the slot meets the tube (antiantumbra).
pub fn tube_over_a_slot() -> SceneDesc {
    let mut desc = floor_and_light(0.6, square(Vec3::Y, Vec3::Y, 0.1), 30.0);
    desc.meshes[1] = tube("tube", 1, Vec3::new(0.0, 1.28, 0.0), (0.5, 0.05), 8);
    let (lo, hi) = (Vec3::new(-0.6, 1.2, -0.3), Vec3::new(0.6, 1.45, 0.3));
    let slot = (0.2, 1.0, 0.27, 0.33);
    box_with_holes(&mut desc, lo, hi, &[slot]);
    let corners = [
        lo + Vec3::new(slot.0, 0.0, slot.2),
        lo + Vec3::new(slot.1, 0.0, slot.2),
        lo + Vec3::new(slot.1, 0.0, slot.3),
        lo + Vec3::new(slot.0, 0.0, slot.3),
    ];
    desc.portals.push(portal("slot", "tube", 0.1, &corners));
    desc.camera = camera(Vec3::new(0.0, 2.0, 2.0), Vec3::new(0.0, 0.3, 0.0));
    desc
}

// ---- comparing two images ----

/// Wilson–Hilferty's approximation of the chi-square quantile at significance 1e-3.
pub fn chi_square_critical(dof: usize) -> f64 {
    let k = dof as f64;
    let z = 3.090; // the standard normal's 0.999 quantile
    k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3)
}

/// One block of a comparison of two images: the mean of the reference `b`, and the difference
/// `a − b` with its standard error.
#[derive(Clone, Copy, Debug)]
pub struct Block {
    pub mean: f64,
    pub difference: f64,
    pub se: f64,
}

/// Per-block differences between two images (blocks of `b × b` pixels, luminance), image `a`
/// scaled by `scale_a` (1 but for the sensitivity check): the standard error of each block's
/// difference comes from the per-pixel sample variances of both. Blocks darker than 1e-3 of
/// the brightest carry no information at these sample counts (their variance estimates rest
/// on a handful of rare hits), so they are left out.
pub fn block_differences(a: &Film, b: &Film, block: u32, scale_a: f64) -> Vec<Block> {
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
                    sa += scale_a * lum(ma[i]);
                    sb += lum(mb[i]);
                    vsum += scale_a * scale_a * lum(va[i]) + lum(vb[i]);
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
        .map(|(ma, mb, se)| Block {
            mean: mb,
            difference: ma - mb,
            se,
        })
        .collect()
}

/// Whether two independent estimates of one image agree. Their blocks' z-scores `z_i` must look
/// like N(0, 1): sum of squares within chi-square at 1e-3, no block beyond 5 sigma. And the
/// projection of the z-scores on the pattern a global scale error `k` would give them,
/// `E[z_i] = k · m_i / se_i`, must be within 4: `T = Σ z_i·w_i / |w|`, `w_i = m_i / se_i`, is
/// N(0, 1) for agreeing images, and the most powerful test of a scale error, which the
/// chi-square over all blocks dilutes among the noisy ones.
pub fn consistent(blocks: &[Block]) -> bool {
    let z: Vec<f64> = blocks.iter().map(|b| b.difference / b.se).collect();
    let ss: f64 = z.iter().map(|v| v * v).sum();
    ss <= chi_square_critical(z.len())
        && z.iter().all(|v| v.abs() < 5.0)
        && scale_statistic(blocks).abs() <= 4.0
}

/// Asserts that `image` agrees with `reference` ([`consistent`] over blocks of 6 × 6 pixels,
/// more than 10 of them lit); with `negative`, also that `image` scaled by 1.03 does not, which
/// shows the test can fail for a 3% bias.
pub fn assert_agrees(label: &str, image: &Film, reference: &Film, negative: bool) {
    let blocks = block_differences(image, reference, 6, 1.0);
    assert!(blocks.len() > 10, "{label}: too few lit blocks");
    assert!(
        consistent(&blocks),
        "{label}: (difference, standard error) = {blocks:?}"
    );
    if negative {
        let scaled = block_differences(image, reference, 6, 1.03);
        assert!(!consistent(&scaled), "{label}: a 3% error went undetected");
    }
}

/// `T` of [`consistent`].
pub fn scale_statistic(blocks: &[Block]) -> f64 {
    let w: Vec<f64> = blocks.iter().map(|b| b.mean / b.se).collect();
    let norm = w.iter().map(|v| v * v).sum::<f64>().sqrt();
    blocks
        .iter()
        .zip(&w)
        .map(|(b, w)| b.difference / b.se * w)
        .sum::<f64>()
        / norm
}

/// Settings for `strategy` at `max_depth` with independent random numbers (block z-scores and
/// standard errors rest on per-pixel sample variances), seeded.
pub fn independent(
    strategy: portalview::light::Strategy,
    max_depth: u32,
    seed: u64,
) -> RenderSettings {
    RenderSettings {
        strategy,
        max_depth,
        seed,
        sampler: portalview::sampling::SamplerKind::Independent,
        ..RenderSettings::default()
    }
}
