//! The environment: radiance arriving from infinitely far, from an equirectangular image or a
//! constant, importance-sampled (`docs/method.md` §9).
//!
//! Mapping (Blender's *Environment Texture*, glTF axes, +Y up), for a unit direction `d` in the
//! map's frame: `u = 0.5 + atan2(d.z, d.x) / 2π`, row fraction from the top `v = acos(d.y) / π`.
//! The map is turned about +Y: a world direction `w` reads the map at `R_y(rotation) · w`,
//! which is what a Blender *Mapping* node (type Point) with Z rotation `rotation` in front of the
//! Environment Texture does (Blender's Z is glTF's Y).
//!
//! The image is read as Blender reads it: the pixel a direction falls in (*Closest*), or
//! bilinearly between the four nearest pixel centres (*Linear*, the default), wrapping in both
//! directions as Cycles' environment images do. The sampling density stays piecewise constant
//! on the pixels; with *Linear* a pixel's weight is the largest of its 3 × 3 neighbourhood's,
//! every pixel the filter can read there, so the density is positive wherever the filtered
//! radiance is, and the estimate `L / pdf` stays exact (`docs/method.md` §9.6).

use glam::{Vec2, Vec3};
use std::f32::consts::{PI, TAU};

use super::area::luminance;
use crate::asset::environment::{EnvImage, EnvMap, EnvironmentDesc, Interpolation};
use crate::sampling::Distribution1D;

/// An environment ready to sample.
#[derive(Clone, Debug)]
pub struct Environment {
    map: Map,
    /// The radiance scale (the desc's strength).
    strength: f32,
    /// `(sin, cos)` of the rotation about +Y.
    rotation: (f32, f32),
    /// Luminance power, W: what the pick among lights uses.
    power: f32,
}

#[derive(Clone, Debug)]
enum Map {
    Constant(Vec3),
    Image {
        width: u32,
        height: u32,
        pixels: Vec<Vec3>,
        interpolation: Interpolation,
        /// Rows by their summed weights.
        rows: Distribution1D,
        /// Each row's pixels by weight ([`reach_weight`] of [`sampling_weight`]).
        columns: Vec<Distribution1D>,
        /// The sun, if the image has one, split off for the window technique.
        hot: Option<HotSpot>,
    },
}

/// A pixel is hot when its weight exceeds this multiple of the image's solid-angle mean.
const HOT_RATIO: f32 = 100.0;
/// The hot pixels are split off only if they lie within a cap of this radius (radians) and hold
/// at least [`HOT_MIN_SHARE`] of the image's weight: one compact sun, which a window either
/// shows or does not from most points.
const HOT_MAX_RADIUS: f32 = 0.25;
const HOT_MIN_SHARE: f32 = 0.05;

/// The environment's sun, as the window technique sees it (`docs/method.md` §9.4): the image
/// is split as `L = K + S`, where `K` is `L` with each hot pixel replaced by `fill`, the mean of
/// the pixels around them (a sky with no sun in it, which a window's table follows without a
/// jump), and `S = L − fill` on the hot pixels, drawn exactly pixel by pixel.
#[derive(Clone, Debug)]
struct HotSpot {
    /// A pixel is hot when its sampling weight is above this.
    threshold: f32,
    /// `K` on the hot pixels.
    fill: Vec3,
    /// The pixels `S` reaches (the hot pixels, and with *Linear* the pixels around them),
    /// indices `j · width + i` in increasing order, and a pick among them by their
    /// [`reach_weight`] of `weight(S)` × solid angle.
    pixels: Vec<u32>,
    pick: Distribution1D,
    /// The pick's total, `∫ weight(S) dω` over the reached pixels (before the strength).
    power: f32,
    /// A cap in the map's frame holding every hot pixel: its centre and the sine of its radius.
    centre: Vec3,
    sin_radius: f32,
}

/// The weight a pixel gets in the sampling distribution: its mean channel, positive wherever
/// any channel is (so every direction with radiance can be drawn).
fn sampling_weight(c: Vec3) -> f32 {
    (c.x + c.y + c.z) / 3.0
}

impl Environment {
    /// `scene_radius`: the radius of a sphere bounding the scene, which sets the power (the
    /// light falling on that sphere).
    pub fn new(desc: &EnvironmentDesc, scene_radius: f32) -> Self {
        let rotation = desc.rotation_degrees.to_radians().sin_cos();
        let strength = desc.strength.max(0.0);
        let (map, mean_luminance) = match &desc.map {
            EnvMap::Constant(c) => (Map::Constant(*c), luminance(*c)),
            EnvMap::Image { image, .. } => image_map(image, desc.interpolation),
        };
        // Power onto a sphere of radius r in radiance L from every direction: 4π² r² L
        // (pbrt-v4's uniform infinite light); the image's solid-angle mean luminance stands in.
        let power = 4.0 * PI * PI * scene_radius * scene_radius * mean_luminance * strength;
        Environment {
            map,
            strength,
            rotation,
            power,
        }
    }

    /// Luminance power, for picking among lights.
    pub fn power(&self) -> f32 {
        if self.power.is_finite() {
            self.power
        } else {
            0.0
        }
    }

    pub fn is_constant(&self) -> bool {
        matches!(self.map, Map::Constant(_))
    }

    /// The map's direction for world direction `w`: `R_y(rotation) · w`.
    fn to_map(&self, w: Vec3) -> Vec3 {
        let (s, c) = self.rotation;
        Vec3::new(w.x * c + w.z * s, w.y, -w.x * s + w.z * c)
    }

    /// The world direction for map direction `m`: `R_y(−rotation) · m`.
    fn to_world(&self, m: Vec3) -> Vec3 {
        let (s, c) = self.rotation;
        Vec3::new(m.x * c - m.z * s, m.y, m.x * s + m.z * c)
    }

    /// Radiance arriving from the unit world direction `w` (towards the sky).
    pub fn radiance(&self, w: Vec3) -> Vec3 {
        match &self.map {
            Map::Constant(c) => *c * self.strength,
            Map::Image { .. } => self.pixel_pdf(w).0 * self.strength,
        }
    }

    /// A unit world direction drawn proportional to the map's weight times the `sin θ` of the
    /// equirectangular map, and its solid-angle pdf; uniform on the sphere for a constant.
    #[inline(always)]
    pub fn sample(&self, u: Vec2) -> Option<(Vec3, f32)> {
        match &self.map {
            Map::Constant(_) => {
                let z = 1.0 - 2.0 * u.x;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let (s, c) = (TAU * u.y).sin_cos();
                Some((Vec3::new(r * c, z, r * s), 1.0 / (4.0 * PI)))
            }
            Map::Image {
                width,
                height,
                rows,
                columns,
                ..
            } => {
                let (j, p_row, v_in) = rows.sample(u.y)?;
                let (i, p_column, u_in) = columns[j].sample(u.x)?;
                let uu = (i as f32 + u_in) / *width as f32;
                let vv = (j as f32 + v_in) / *height as f32;
                let (sin_theta, cos_theta) = (PI * vv).sin_cos();
                if sin_theta <= 0.0 {
                    return None;
                }
                let (sin_phi, cos_phi) = (TAU * (uu - 0.5)).sin_cos();
                let m = Vec3::new(sin_theta * cos_phi, cos_theta, sin_theta * sin_phi);
                let pdf_uv = p_row * p_column * (*width * *height) as f32;
                Some((self.to_world(m), pdf_uv / (2.0 * PI * PI * sin_theta)))
            }
        }
    }

    /// The solid-angle pdf of [`Self::sample`] for the unit world direction `w`.
    pub fn pdf(&self, w: Vec3) -> f32 {
        match &self.map {
            Map::Constant(_) => 1.0 / (4.0 * PI),
            Map::Image {
                width,
                height,
                rows,
                columns,
                ..
            } => {
                let m = self.to_map(w);
                // From the horizontal part: accurate near the poles, where 1 − y² cancels.
                let sin_theta = (m.x * m.x + m.z * m.z).sqrt();
                if sin_theta <= 0.0 {
                    return 0.0;
                }
                let (i, j) = pixel_of(m, *width, *height);
                let pdf_uv = rows.pmf(j as usize)
                    * columns[j as usize].pmf(i as usize)
                    * (*width * *height) as f32;
                pdf_uv / (2.0 * PI * PI * sin_theta)
            }
        }
    }

    /// [`Self::radiance`] and [`Self::pdf`] at once, from one pixel lookup.
    #[inline(always)]
    pub fn radiance_pdf(&self, w: Vec3) -> (Vec3, f32) {
        let (pixel, pdf, _) = self.pixel_pdf(w);
        (pixel * self.strength, pdf)
    }

    /// The map's value along `w` before the strength, [`Self::pdf`], and the pixel's index
    /// `j · width + i` (`None` for a constant), for the sun's pdf.
    #[inline(always)]
    fn pixel_pdf(&self, w: Vec3) -> (Vec3, f32, Option<u32>) {
        match &self.map {
            Map::Constant(c) => (*c, 1.0 / (4.0 * PI), None),
            Map::Image {
                width,
                height,
                pixels,
                interpolation,
                rows,
                columns,
                ..
            } => {
                let m = self.to_map(w);
                let uv = map_uv(m);
                let (i, j) = pixel_at(uv, *width, *height);
                let index = j * width + i;
                let le = match interpolation {
                    Interpolation::Closest => pixels[index as usize],
                    Interpolation::Linear => bilinear(pixels, *width, *height, uv),
                };
                let sin_theta = (m.x * m.x + m.z * m.z).sqrt();
                if sin_theta <= 0.0 {
                    return (le, 0.0, Some(index));
                }
                let pdf_uv = rows.pmf(j as usize)
                    * columns[j as usize].pmf(i as usize)
                    * (*width * *height) as f32;
                (le, pdf_uv / (2.0 * PI * PI * sin_theta), Some(index))
            }
        }
    }

    /// The weight [`Self::sample`] gives direction `w`, up to a constant: what a technique
    /// proportional to the environment within a window follows (with *Linear*, the largest
    /// weight the filter reads around `w`'s pixel, so that it bounds the filtered radiance).
    pub fn sampling_weight(&self, w: Vec3) -> f32 {
        self.reached(w, sampling_weight)
    }

    /// The weight of the environment without its sun, `K` (`L` where the image has no hot spot),
    /// as [`Self::sampling_weight`] reads it: what a window's table follows.
    pub fn sky_weight(&self, w: Vec3) -> f32 {
        let hot = self.hot();
        self.reached(w, |pixel| {
            sampling_weight(match hot {
                Some(hot) if hot.excess(pixel).is_some() => hot.fill,
                _ => pixel,
            })
        })
    }

    /// [`reach_weight`] of `weight` at the pixel `w` falls in, times the strength.
    fn reached(&self, w: Vec3, weight: impl Fn(Vec3) -> f32) -> f32 {
        match &self.map {
            Map::Constant(c) => weight(*c) * self.strength,
            Map::Image {
                width,
                height,
                pixels,
                interpolation,
                ..
            } => {
                let (i, j) = pixel_of(self.to_map(w), *width, *height);
                let value = |a: u32, b: u32| weight(pixels[(b * width + a) as usize]);
                reach_weight(*interpolation, *width, *height, i, j, value) * self.strength
            }
        }
    }

    /// The sun and the image's width and height, if the map is an image with a sun.
    fn hot_image(&self) -> Option<(&HotSpot, u32, u32)> {
        match &self.map {
            Map::Image {
                width,
                height,
                hot: Some(hot),
                ..
            } => Some((hot, *width, *height)),
            _ => None,
        }
    }

    fn hot(&self) -> Option<&HotSpot> {
        self.hot_image().map(|(hot, _, _)| hot)
    }

    /// The sun's power `∫ weight(S) dω` in the units of [`Self::sky_weight`]'s integrals, and
    /// the cap that holds it (world centre, sine of its radius); `None` without a hot spot.
    pub fn hot_spot(&self) -> Option<(f32, Vec3, f32)> {
        self.hot().map(|h| {
            (
                h.power * self.strength,
                self.to_world(h.centre),
                h.sin_radius,
            )
        })
    }

    /// A direction drawn proportional to `S` (a hot pixel by its weight × solid angle, then
    /// uniform in its solid angle); its density is [`Self::hot_pdf`].
    #[inline(always)]
    pub fn sample_hot(&self, u: Vec2) -> Option<Vec3> {
        let (hot, width, height) = self.hot_image()?;
        let (k, _, u_in) = hot.pick.sample(u.x)?;
        let index = *hot.pixels.get(k)?;
        let (i, j) = (index % width, index / width);
        let phi = TAU * ((i as f32 + u_in) / width as f32 - 0.5);
        let (z0, z1) = row_cosines(j, height);
        let z = z0 + u.y * (z1 - z0);
        let r = (1.0 - z * z).max(0.0).sqrt();
        let (sin_phi, cos_phi) = phi.sin_cos();
        Some(self.to_world(Vec3::new(r * cos_phi, z, r * sin_phi)))
    }

    /// The solid-angle density of [`Self::sample_hot`] at `w`: its pick's probability of the
    /// pixel `w` falls in over that pixel's solid angle, 0 on a pixel it never picks (and
    /// without a hot spot).
    pub fn hot_pdf(&self, w: Vec3) -> f32 {
        let Some((hot, width, height)) = self.hot_image() else {
            return 0.0;
        };
        let (i, j) = pixel_of(self.to_map(w), width, height);
        hot.pdf(j * width + i, width, height)
    }

    /// [`Self::radiance_pdf`] and [`Self::hot_pdf`] from one pixel lookup.
    #[inline(always)]
    pub fn radiance_pdfs(&self, w: Vec3) -> (Vec3, f32, f32) {
        let (pixel, p_env, index) = self.pixel_pdf(w);
        let p_hot = match (self.hot_image(), index) {
            (Some((hot, width, height)), Some(index)) => hot.pdf(index, width, height),
            _ => 0.0,
        };
        (pixel * self.strength, p_env, p_hot)
    }
}

impl HotSpot {
    /// `weight(S)` for a pixel's value before the strength, if the pixel is hot.
    fn excess(&self, pixel: Vec3) -> Option<f32> {
        hot_excess(pixel, self.threshold, self.fill)
    }

    /// The density of the pick's draws at pixel `index` (`j · width + i`): its pmf over its
    /// solid angle.
    fn pdf(&self, index: u32, width: u32, height: u32) -> f32 {
        let Ok(k) = self.pixels.binary_search(&index) else {
            return 0.0;
        };
        let (z0, z1) = row_cosines(index / width, height);
        self.pick.pmf(k) / ((TAU / width as f32) * (z0 - z1))
    }
}

/// How far a pixel's sides along its rows, arcs of latitude circles, bulge past the great
/// circles through its corners in a map `width` pixels wide: at most the sagitta `Δφ² / 8` of an
/// arc `Δφ` wide (`sin θ cos θ · Δφ² / 8` at colatitude `θ`). Distance from a point along a great
/// circle's arc is greatest at an end, so no point of a pixel lies farther from a point than
/// its farthest corner plus this.
fn row_arc_bulge(width: u32) -> f32 {
    (TAU / width as f32).powi(2) / 8.0
}

/// How many pixels around its own a direction's filtered value reads: 1 for *Linear* (the
/// four nearest centres lie within the 3 × 3 block around it), 0 for *Closest*.
fn reach(interpolation: Interpolation) -> i64 {
    match interpolation {
        Interpolation::Linear => 1,
        Interpolation::Closest => 0,
    }
}

/// The largest `value` over the pixels a direction in pixel `(i, j)` may read
/// ([`reach`], wrapping as [`bilinear`] does): a bound on the filtered `value` in that pixel.
fn reach_weight(
    interpolation: Interpolation,
    width: u32,
    height: u32,
    i: u32,
    j: u32,
    value: impl Fn(u32, u32) -> f32,
) -> f32 {
    let r = reach(interpolation);
    let mut most = 0.0f32;
    for dj in -r..=r {
        let b = (j as i64 + dj).rem_euclid(height as i64) as u32;
        for di in -r..=r {
            let a = (i as i64 + di).rem_euclid(width as i64) as u32;
            most = most.max(value(a, b));
        }
    }
    most
}

/// Cycles' bilinear lookup of an environment image (`EXTENSION_REPEAT`): at `(u·w − ½,
/// v·h − ½)` between the four nearest pixel centres, the pixel indices wrapping in both
/// directions (across a pole the top row is read with the bottom one, as Cycles does).
fn bilinear(pixels: &[Vec3], width: u32, height: u32, (u, v): (f32, f32)) -> Vec3 {
    let x = u * width as f32 - 0.5;
    let y = v * height as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (tx, ty) = (x - x0, y - y0);
    let wrap = |k: f32, n: u32| (k as i64).rem_euclid(n as i64) as u32;
    let (i0, i1) = (wrap(x0, width), wrap(x0 + 1.0, width));
    let (j0, j1) = (wrap(y0, height), wrap(y0 + 1.0, height));
    let p = |i: u32, j: u32| pixels[(j * width + i) as usize];
    (p(i0, j0) * (1.0 - tx) + p(i1, j0) * tx) * (1.0 - ty)
        + (p(i0, j1) * (1.0 - tx) + p(i1, j1) * tx) * ty
}

/// `weight(L) − weight(fill)` if `weight(L)` is above `threshold`: at load and when drawing
/// and evaluating, the same test on the same number, so a pixel is hot for all or none.
fn hot_excess(pixel: Vec3, threshold: f32, fill: Vec3) -> Option<f32> {
    let w = sampling_weight(pixel);
    (w > threshold).then(|| (w - sampling_weight(fill)).max(0.0))
}

/// `(cos θ0, cos θ1)` at the top and bottom of row `j` (decreasing: θ grows down the image).
fn row_cosines(j: u32, height: u32) -> (f32, f32) {
    let theta = |j: u32| PI * j as f32 / height as f32;
    (theta(j).cos(), theta(j + 1).cos())
}

/// A map direction's image coordinates: `u` across, `v` down from the top, both in [0, 1].
fn map_uv(m: Vec3) -> (f32, f32) {
    (0.5 + m.z.atan2(m.x) / TAU, m.y.clamp(-1.0, 1.0).acos() / PI)
}

/// The pixel (column, row) a map direction falls in.
fn pixel_of(m: Vec3, width: u32, height: u32) -> (u32, u32) {
    pixel_at(map_uv(m), width, height)
}

/// The pixel (column, row) that image coordinates `(u, v)` fall in.
fn pixel_at((u, v): (f32, f32), width: u32, height: u32) -> (u32, u32) {
    let i = ((u * width as f32) as u32).min(width - 1);
    let j = ((v * height as f32) as u32).min(height - 1);
    (i, j)
}

/// The image's sampling distribution and its solid-angle mean luminance.
fn image_map(image: &EnvImage, interpolation: Interpolation) -> (Map, f32) {
    let (w, h) = (image.width, image.height);
    let weight = |i: u32, j: u32| sampling_weight(image.pixel(i, j));
    let mut columns = Vec::with_capacity(h as usize);
    let mut row_weights = Vec::with_capacity(h as usize);
    let mut luminance_sum = 0.0f64;
    for j in 0..h {
        let theta0 = PI * j as f32 / h as f32;
        let theta1 = PI * (j + 1) as f32 / h as f32;
        let sin_centre = (0.5 * (theta0 + theta1)).sin();
        // Each pixel's solid angle: 2π/w · (cos θ0 − cos θ1).
        let pixel_solid_angle = (TAU / w as f32) * (theta0.cos() - theta1.cos());
        let row =
            Distribution1D::new((0..w).map(|i| reach_weight(interpolation, w, h, i, j, weight)));
        luminance_sum += (0..w)
            .map(|i| f64::from(luminance(image.pixel(i, j)) * pixel_solid_angle))
            .sum::<f64>();
        row_weights.push(row.total() * sin_centre);
        columns.push(row);
    }
    let mean = (luminance_sum / (4.0 * std::f64::consts::PI)) as f32;
    (
        Map::Image {
            width: w,
            height: h,
            pixels: image.pixels.clone(),
            interpolation,
            rows: Distribution1D::new(row_weights),
            columns,
            hot: hot_spot(image, interpolation),
        },
        mean,
    )
}

/// The image's sun: the pixels above [`HOT_RATIO`] times the mean weight, if they are compact
/// and hold enough of it ([`HotSpot`]).
fn hot_spot(image: &EnvImage, interpolation: Interpolation) -> Option<HotSpot> {
    let (w, h) = (image.width, image.height);
    let solid_angle = |j: u32| {
        let (z0, z1) = row_cosines(j, h);
        (TAU / w as f32) * (z0 - z1)
    };
    let weight_of = |i: u32, j: u32| sampling_weight(image.pixel(i, j));
    let mut total = 0.0f64;
    for j in 0..h {
        let omega = f64::from(solid_angle(j));
        total += (0..w)
            .map(|i| f64::from(weight_of(i, j)) * omega)
            .sum::<f64>();
    }
    let threshold = HOT_RATIO * (total / (4.0 * std::f64::consts::PI)) as f32;
    if !(threshold > 0.0 && threshold.is_finite()) {
        return None;
    }
    // The test of `hot_excess`.
    let hot = |i: u32, j: u32| weight_of(i, j) > threshold;
    let pixels: Vec<u32> = (0..h)
        .flat_map(|j| (0..w).map(move |i| (i, j)))
        .filter(|&(i, j)| hot(i, j))
        .map(|(i, j)| j * w + i)
        .collect();
    if pixels.is_empty() {
        return None;
    }
    // `fill`: the mean of the pixels next to a hot one (the sky around the sun).
    let (mut fill, mut around) = (Vec3::ZERO, 0u32);
    for &p in &pixels {
        let (i, j) = (p % w, p / w);
        let neighbours = [
            ((i + w - 1) % w, j),
            ((i + 1) % w, j),
            (i, j.saturating_sub(1)),
            (i, (j + 1).min(h - 1)),
        ];
        for (a, b) in neighbours {
            if !hot(a, b) {
                fill += image.pixel(a, b);
                around += 1;
            }
        }
    }
    let fill = if around > 0 {
        fill / around as f32
    } else {
        Vec3::ZERO
    };
    // `S` as the filter reads it: every pixel within reach of a hot one, by the largest excess
    // within its reach, so that the pick covers wherever the filtered `S` is positive.
    let r = reach(interpolation);
    let mut reached: Vec<u32> = pixels
        .iter()
        .flat_map(|&p| {
            let (i, j) = ((p % w) as i64, (p / w) as i64);
            (-r..=r).flat_map(move |dj| {
                (-r..=r).map(move |di| {
                    let a = (i + di).rem_euclid(w as i64) as u32;
                    let b = (j + dj).rem_euclid(h as i64) as u32;
                    b * w + a
                })
            })
        })
        .collect();
    reached.sort_unstable();
    reached.dedup();
    let s_of = |i: u32, j: u32| hot_excess(image.pixel(i, j), threshold, fill).unwrap_or(0.0);
    let excess = |p: u32| reach_weight(interpolation, w, h, p % w, p / w, s_of);
    let pick = Distribution1D::new(reached.iter().map(|&p| excess(p) * solid_angle(p / w)));
    let power = pick.total();
    // The cap: about the weighted mean of the reached pixels' centres, out to the farthest
    // corner of `pixels` (the test of compactness) and of `reached` (the cap).
    let direction = |u: f32, v: f32| {
        let (sin_theta, cos_theta) = (PI * v).sin_cos();
        let (sin_phi, cos_phi) = (TAU * (u - 0.5)).sin_cos();
        Vec3::new(sin_theta * cos_phi, cos_theta, sin_theta * sin_phi)
    };
    let centre = reached
        .iter()
        .map(|&p| {
            let (i, j) = (p % w, p / w);
            direction((i as f32 + 0.5) / w as f32, (j as f32 + 0.5) / h as f32)
                * excess(p)
                * solid_angle(j)
        })
        .sum::<Vec3>()
        .try_normalize()?;
    let radius_of = |set: &[u32]| {
        let cos_radius = set
            .iter()
            .flat_map(|&p| {
                let (i, j) = (p % w, p / w);
                [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(di, dj)| {
                    direction((i + di) as f32 / w as f32, (j + dj) as f32 / h as f32)
                })
            })
            .map(|d| d.dot(centre))
            .fold(1.0f32, f32::min);
        // Past the farthest corner: the bulge of a pixel's sides along its rows, and 1e-5 rad
        // for the rounding of these f32 directions (a few 1e-6 rad at a sun's radius; a cap
        // too small by that would only cost variance, §9.4 of docs/method.md).
        cos_radius.clamp(-1.0, 1.0).acos() + row_arc_bulge(w) + 1e-5
    };
    let (radius, cap_radius) = (radius_of(&pixels), radius_of(&reached));
    let share = f64::from(power) / total;
    (radius <= HOT_MAX_RADIUS && share >= f64::from(HOT_MIN_SHARE)).then(|| HotSpot {
        threshold,
        fill,
        pixels: reached,
        pick,
        power,
        centre,
        sin_radius: cap_radius.min(PI / 2.0).sin(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    /// No point on a pixel's sides lies farther from a direction than its farthest corner plus
    /// [`row_arc_bulge`] (what the sun's cap adds to its corners); and the bulge is there: some
    /// point lies farther than the farthest corner alone, so the margin cannot be left out.
    #[test]
    fn a_pixel_lies_within_its_corners_and_the_bulge() {
        let direction = |u: f64, v: f64| {
            let (sin_theta, cos_theta) = (std::f64::consts::PI * v).sin_cos();
            let (sin_phi, cos_phi) = (std::f64::consts::TAU * (u - 0.5)).sin_cos();
            glam::DVec3::new(sin_theta * cos_phi, cos_theta, sin_theta * sin_phi)
        };
        let mut rng = crate::sampling::Rng::new(5, 0);
        let mut bulged = 0;
        for w in [16u32, 64, 512, 4096] {
            let h = w / 2;
            let bulge = f64::from(row_arc_bulge(w));
            for _ in 0..2000 {
                let i = (rng.uniform() * w as f32) as u32 % w;
                let j = (rng.uniform() * h as f32) as u32 % h;
                let (u0, v0) = (f64::from(i) / f64::from(w), f64::from(j) / f64::from(h));
                let (du, dv) = (1.0 / f64::from(w), 1.0 / f64::from(h));
                // A centre up to about a radian from the pixel.
                let c = (direction(u0 + 0.5 * du, v0 + 0.5 * dv)
                    + glam::DVec3::new(
                        f64::from(rng.uniform()) - 0.5,
                        f64::from(rng.uniform()) - 0.5,
                        f64::from(rng.uniform()) - 0.5,
                    ) * 2.0
                        * f64::from(rng.uniform()).powi(3))
                .normalize();
                let angle = |d: glam::DVec3| d.dot(c).clamp(-1.0, 1.0).acos();
                let corners = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
                    .map(|(a, b)| angle(direction(u0 + a * du, v0 + b * dv)))
                    .into_iter()
                    .fold(0.0, f64::max);
                let sides = (0..=64).flat_map(|k| {
                    let t = f64::from(k) / 64.0;
                    [(t, 0.0), (t, 1.0), (0.0, t), (1.0, t)]
                });
                let farthest = sides
                    .map(|(a, b)| angle(direction(u0 + a * du, v0 + b * dv)))
                    .fold(0.0, f64::max);
                assert!(
                    farthest <= corners + bulge + 1e-12,
                    "{w} × {h}, pixel ({i}, {j}): {farthest} past {corners} + {bulge}"
                );
                if farthest > corners + 1e-12 {
                    bulged += 1;
                }
            }
        }
        assert!(bulged > 0, "no pixel side bulged past its corners");
    }

    #[test]
    fn mapping_follows_blender() {
        // +X is the image's centre column, the top row is +Y.
        let image = EnvImage {
            width: 4,
            height: 2,
            pixels: (0..8).map(|k| Vec3::splat(k as f32 + 1.0)).collect(),
        };
        let desc = EnvironmentDesc {
            map: EnvMap::Image {
                file: None,
                image: Arc::new(image),
            },
            strength: 1.0,
            rotation_degrees: 0.0,
            interpolation: Interpolation::Closest,
        };
        let env = Environment::new(&desc, 1.0);
        let up_x = Vec3::new(1.0, 0.3, 0.01).normalize();
        assert_eq!(env.radiance(up_x), Vec3::splat(3.0)); // row 0, u just over 0.5: column 2
        let down_minus_z = Vec3::new(0.01, -0.3, -1.0).normalize();
        assert_eq!(env.radiance(down_minus_z), Vec3::splat(6.0)); // row 1, u ≈ 0.25: column 1
        // Turned by 90° about +Y, the map's +X column is seen from world +Z.
        let turned = Environment::new(
            &EnvironmentDesc {
                rotation_degrees: 90.0,
                ..desc
            },
            1.0,
        );
        let from_z = Vec3::new(-0.01, 0.3, 1.0).normalize();
        assert_eq!(turned.radiance(from_z), Vec3::splat(3.0));
    }
}
