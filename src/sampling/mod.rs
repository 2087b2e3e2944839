//! Domain-free sampling maths: random numbers, warps with their pdfs, convex polygons and
//! spherical polygons.

pub mod lanes;
pub mod polygon;
pub mod sobol;
pub mod spherical;

use glam::{Vec2, Vec3};
use lanes::{F32s, Mask, Vec2s, Vec3s};

/// PCG32 (O'Neill 2014): small, fast, and seeded per pixel and pass so that an image does not
/// depend on how work was split across threads.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
    inc: u64,
}

impl Rng {
    const MULT: u64 = 6364136223846793005;

    /// A generator for stream `stream` of seed `seed`; different streams are independent.
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = Rng {
            state: 0,
            inc: (stream << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(seed);
        rng.next_u32();
        rng
    }

    /// A generator keyed by several integers (seed, pixel, pass, ...), mixed by SplitMix64.
    pub fn keyed(seed: u64, keys: &[u64]) -> Self {
        let mut h = splitmix64(seed);
        for &k in keys {
            h = splitmix64(h ^ k);
        }
        Rng::new(h, splitmix64(h ^ 0x9E37_79B9_7F4A_7C15))
    }

    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(Self::MULT).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1).
    pub fn uniform(&mut self) -> f32 {
        // 24 random bits: exactly representable, never 1.0.
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    pub fn uniform2(&mut self) -> Vec2 {
        Vec2::new(self.uniform(), self.uniform())
    }
}

/// Which random numbers a render draws: a closed set, chosen per render.
#[derive(
    Clone,
    Copy,
    Debug,
    Default,
    PartialEq,
    Eq,
    Hash,
    serde::Serialize,
    serde::Deserialize,
    clap::ValueEnum,
)]
pub enum SamplerKind {
    /// Independent uniform numbers (PCG32): what the statistical tests assume.
    Independent,
    // The doc line is the CLI's help text too: no rustdoc link in it (see `sobol::ZSobol`).
    /// Owen-scrambled Sobol' points in Z-order: stratified per pixel.
    #[default]
    Sobol,
}

impl SamplerKind {
    pub const ALL: [SamplerKind; 2] = [SamplerKind::Independent, SamplerKind::Sobol];

    pub fn name(self) -> &'static str {
        match self {
            SamplerKind::Independent => "independent",
            SamplerKind::Sobol => "sobol",
        }
    }

    /// The samplers of pass `pass` under `seed`: what they share is computed here, once (per
    /// tile), then [`PassSampler::start`] starts each pixel's.
    pub fn pass(self, seed: u64, pass: u32) -> PassSampler {
        match self {
            SamplerKind::Independent => PassSampler::Independent { seed, pass },
            SamplerKind::Sobol => PassSampler::Sobol(sobol::ZSobolPass::new(seed, pass)),
        }
    }
}

/// The samplers of one pass of a render ([`SamplerKind::pass`]).
// One per tile, on the stack: boxing the Sobol' table would allocate for nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum PassSampler {
    Independent { seed: u64, pass: u32 },
    Sobol(sobol::ZSobolPass),
}

impl PassSampler {
    /// The sampler of pixel `(x, y)` in an image `width` pixels wide: it depends on nothing
    /// else than the seed and the pass, so an image does not depend on how threads split the
    /// work.
    #[inline(always)]
    pub fn start(&self, x: u32, y: u32, width: u32) -> Sampler<'_> {
        match self {
            &PassSampler::Independent { seed, pass } => {
                let index = y as u64 * width as u64 + x as u64;
                Sampler::Independent(Rng::keyed(seed, &[pass as u64, index]))
            }
            PassSampler::Sobol(pass) => Sampler::Sobol(pass.pixel(x, y)),
        }
    }

    /// The samplers of pixels `(x[i], y)`, the same numbers as [`PassSampler::start`] gives:
    /// for a packet of pixels traced together, whose first Sobol' draws are computed together.
    #[inline(always)]
    pub fn start_packet<const P: usize>(
        &self,
        x: [u32; P],
        y: u32,
        width: u32,
    ) -> [Sampler<'_>; P] {
        match self {
            // A lone pixel computes each draw when it needs it: none is wasted.
            PassSampler::Sobol(pass) if P > 1 => pass.packet(x, y).map(Sampler::Sobol),
            _ => x.map(|x| self.start(x, y, width)),
        }
    }
}

/// The random numbers of one path: the integrator draws them in a fixed order (camera, then
/// per vertex light pick, technique pick, light direction, lobe, BSDF direction), so that with
/// Sobol' points each draw is a dimension of its own.
#[derive(Clone, Debug)]
pub enum Sampler<'a> {
    Independent(Rng),
    Sobol(sobol::ZSobol<'a>),
}

impl Sampler<'_> {
    /// Uniform in [0, 1).
    #[inline(always)]
    pub fn uniform(&mut self) -> f32 {
        match self {
            Sampler::Independent(rng) => rng.uniform(),
            Sampler::Sobol(s) => s.uniform(),
        }
    }

    /// `N ≤ 2` calls of [`Sampler::uniform`] and then one of [`Sampler::uniform2`], the same
    /// numbers (the Sobol' sampler finishes them side by side).
    #[inline(always)]
    pub fn uniforms_uniform2<const N: usize>(&mut self) -> ([f32; N], Vec2) {
        match self {
            Sampler::Independent(rng) => {
                let mut u = [0.0; N];
                for u in &mut u {
                    *u = rng.uniform();
                }
                (u, rng.uniform2())
            }
            Sampler::Sobol(s) => s.uniforms_uniform2(),
        }
    }

    /// Uniform on [0, 1)², stratified jointly by the Sobol' sampler.
    #[inline(always)]
    pub fn uniform2(&mut self) -> Vec2 {
        match self {
            Sampler::Independent(rng) => rng.uniform2(),
            Sampler::Sobol(s) => s.uniform2(),
        }
    }
}

impl From<Rng> for Sampler<'_> {
    fn from(rng: Rng) -> Self {
        Sampler::Independent(rng)
    }
}

fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The item whose share of `[0, 1)` holds `v`, the shares being `weight(item)` in order; the
/// last one when round-off leaves `v` just past them all.
#[inline(always)]
pub fn pick_by_weight<'a, T: 'a>(
    items: impl IntoIterator<Item = &'a T>,
    weight: impl Fn(&T) -> f32,
    mut v: f32,
) -> Option<&'a T> {
    let mut last = None;
    for item in items {
        let w = weight(item);
        if v < w {
            return Some(item);
        }
        v -= w;
        last = Some(item);
    }
    last
}

/// The largest f32 below 1: a stretched uniform number stays in [0, 1).
pub const ONE_BELOW: f32 = 1.0 - f32::EPSILON / 2.0;

/// `(v_i, v_{i+1})` around a closed polygon, the last vertex paired with the first. Hot loops
/// use this rather than indexing by `(i + 1) % n`, whose integer division costs more than the
/// geometry each step does.
#[inline]
pub fn cyclic_pairs<T: Copy>(v: &[T]) -> impl Iterator<Item = (T, T)> + Clone + '_ {
    v.iter()
        .copied()
        .zip(v.iter().skip(1).chain(v.first()).copied())
}

/// `(sin a, cos a)` for `|a| ≤ π/4`, by Taylor polynomials whose truncation error there is
/// below 2e-9, under f32 rounding: several times cheaper than libm's general `sin_cos`, and
/// the warps only need this range.
#[inline(always)]
pub fn sin_cos_quarter(a: f32) -> (f32, f32) {
    let a2 = a * a;
    let sin =
        a * (1.0 + a2 * (-1.0 / 6.0 + a2 * (1.0 / 120.0 + a2 * (-1.0 / 5040.0 + a2 / 362_880.0))));
    let cos = 1.0
        + a2 * (-0.5
            + a2 * (1.0 / 24.0 + a2 * (-1.0 / 720.0 + a2 * (1.0 / 40_320.0 - a2 / 3_628_800.0))));
    (sin, cos)
}

/// [`sin_cos_quarter`] in lanes.
#[inline(always)]
pub fn sin_cos_quarter_lanes(a: F32s) -> (F32s, F32s) {
    let a2 = a * a;
    let sin =
        a * (1.0 + a2 * (-1.0 / 6.0 + a2 * (1.0 / 120.0 + a2 * (-1.0 / 5040.0 + a2 / 362_880.0))));
    let cos = 1.0
        + a2 * (-0.5
            + a2 * (1.0 / 24.0 + a2 * (-1.0 / 720.0 + a2 * (1.0 / 40_320.0 - a2 / 3_628_800.0))));
    (sin, cos)
}

/// `(sin 2πu, cos 2πu)`: the angle reduced to within 45° of a multiple of 90°.
#[inline]
pub fn sin_cos_turn(u: f32) -> (f32, f32) {
    let quadrant = (4.0 * u).round();
    let (s, c) = sin_cos_quarter(std::f32::consts::TAU * (u - 0.25 * quadrant));
    match quadrant as i32 & 3 {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// An orthonormal basis around `n` (Duff et al. 2017), so that `local.z` maps to `n`.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    pub t: Vec3,
    pub b: Vec3,
    pub n: Vec3,
}

impl Frame {
    #[inline(always)]
    pub fn from_normal(n: Vec3) -> Self {
        let sign = 1.0_f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        Frame {
            t: Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
            b: Vec3::new(b, sign + n.y * n.y * a, -n.y),
            n,
        }
    }
    #[inline(always)]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.t * v.x + self.b * v.y + self.n * v.z
    }
    #[inline(always)]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }
}

/// [`Frame`] in lanes.
#[derive(Clone, Copy, Debug)]
pub struct Frames {
    pub t: Vec3s,
    pub b: Vec3s,
    pub n: Vec3s,
}

impl Frames {
    /// [`Frame::from_normal`] in lanes.
    #[inline(always)]
    pub fn from_normal(n: Vec3s) -> Self {
        let sign = n.z.map(|z| 1.0_f32.copysign(z));
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        Frames {
            t: Vec3s::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
            b: Vec3s::new(b, sign + n.y * n.y * a, -n.y),
            n,
        }
    }

    #[inline(always)]
    pub fn to_world(&self, v: Vec3s) -> Vec3s {
        self.t.scale(v.x) + self.b.scale(v.y) + self.n.scale(v.z)
    }

    #[inline(always)]
    pub fn to_local(&self, v: Vec3s) -> Vec3s {
        Vec3s::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }

    /// Lane `i`.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> Frame {
        Frame {
            t: self.t.lane(i),
            b: self.b.lane(i),
            n: self.n.lane(i),
        }
    }
}

/// A uniform direction on the unit sphere (pdf [`UNIFORM_SPHERE_PDF`]).
#[inline(always)]
pub fn sample_uniform_sphere(u: Vec2) -> Vec3 {
    let z = 1.0 - 2.0 * u.x;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (s, c) = (std::f32::consts::TAU * u.y).sin_cos();
    Vec3::new(r * c, z, r * s)
}

/// The solid-angle pdf of [`sample_uniform_sphere`].
pub const UNIFORM_SPHERE_PDF: f32 = 1.0 / (4.0 * std::f32::consts::PI);

/// Cosine-weighted hemisphere around +z (Malley's method on a concentric disk).
#[inline(always)]
pub fn sample_cosine_hemisphere(u: Vec2) -> Vec3 {
    let d = sample_concentric_disk(u);
    let z = (1.0 - d.length_squared()).max(0.0).sqrt();
    Vec3::new(d.x, d.y, z)
}

/// [`sample_cosine_hemisphere`] in lanes.
#[inline(always)]
pub fn sample_cosine_hemisphere_lanes(u: Vec2s) -> Vec3s {
    let d = sample_concentric_disk_lanes(u);
    let z = (1.0 - ((d.x * d.x) + (d.y * d.y)))
        .max(F32s::splat(0.0))
        .sqrt();
    Vec3s::new(d.x, d.y, z)
}

pub fn cosine_hemisphere_pdf(cos_theta: f32) -> f32 {
    cos_theta.max(0.0) * std::f32::consts::FRAC_1_PI
}

/// [`cosine_hemisphere_pdf`] in lanes.
#[inline(always)]
pub fn cosine_hemisphere_pdf_lanes(cos_theta: F32s) -> F32s {
    cos_theta.max(F32s::splat(0.0)) * std::f32::consts::FRAC_1_PI
}

/// Shirley–Chiu concentric map from the unit square to the unit disk.
#[inline(always)]
pub fn sample_concentric_disk(u: Vec2) -> Vec2 {
    let o = 2.0 * u - Vec2::ONE;
    if o == Vec2::ZERO {
        return Vec2::ZERO;
    }
    // θ = π/4 · o.y/o.x, or π/2 − π/4 · o.x/o.y, whose cosine and sine swap those of the
    // quarter angle.
    if o.x.abs() > o.y.abs() {
        let (s, c) = sin_cos_quarter(std::f32::consts::FRAC_PI_4 * (o.y / o.x));
        o.x * Vec2::new(c, s)
    } else {
        let (s, c) = sin_cos_quarter(std::f32::consts::FRAC_PI_4 * (o.x / o.y));
        o.y * Vec2::new(s, c)
    }
}

/// [`sample_concentric_disk`] in lanes: both branches, then each lane's.
#[inline(always)]
pub fn sample_concentric_disk_lanes(u: Vec2s) -> Vec2s {
    let (ox, oy) = (2.0 * u.x - 1.0, 2.0 * u.y - 1.0);
    let mut zero: Mask = ox.test(F32s::splat(0.0), |a, b| a == b);
    for (zero, &y) in zero
        .iter_mut()
        .zip(&oy.test(F32s::splat(0.0), |a, b| a == b))
    {
        *zero &= y;
    }
    let x_wider = ox.abs().test(oy.abs(), |a, b| a > b);
    let ratio = F32s::select(x_wider, oy / ox, ox / oy);
    let (s, c) = sin_cos_quarter_lanes(std::f32::consts::FRAC_PI_4 * ratio);
    let x = F32s::select(x_wider, ox * c, oy * s);
    let y = F32s::select(x_wider, ox * s, oy * c);
    let none = F32s::splat(0.0);
    Vec2s {
        x: F32s::select(zero, none, x),
        y: F32s::select(zero, none, y),
    }
}

/// Uniform barycentric coordinates (b0, b1) on a triangle (the square-root map).
#[inline(always)]
pub fn sample_uniform_triangle(u: Vec2) -> Vec2 {
    let su = u.x.sqrt();
    Vec2::new(1.0 - su, u.y * su)
}

/// A discrete distribution over weights, sampled by inverting its CDF.
#[derive(Clone, Debug, Default)]
pub struct Distribution1D {
    cdf: Vec<f32>,
    total: f32,
}

impl Distribution1D {
    /// Negative and non-finite weights count as zero.
    pub fn new(weights: impl IntoIterator<Item = f32>) -> Self {
        let mut cdf = Vec::new();
        let mut total = 0.0f64;
        for w in weights {
            total += if w.is_finite() && w > 0.0 {
                w as f64
            } else {
                0.0
            };
            cdf.push(total as f32);
        }
        Distribution1D {
            cdf,
            total: total as f32,
        }
    }

    pub fn len(&self) -> usize {
        self.cdf.len()
    }
    pub fn is_empty(&self) -> bool {
        self.total <= 0.0
    }
    pub fn total(&self) -> f32 {
        self.total
    }

    /// Picks an index with probability proportional to its weight; returns it, its
    /// probability, and `u` rescaled to [0, 1) within the chosen bin (for reuse).
    #[inline(always)]
    pub fn sample(&self, u: f32) -> Option<(usize, f32, f32)> {
        if self.is_empty() {
            return None;
        }
        if self.cdf.len() == 1 {
            return Some((0, 1.0, u));
        }
        let target = u * self.total;
        let i = self
            .cdf
            .partition_point(|&c| c <= target)
            .min(self.cdf.len() - 1);
        let lo = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        let w = self.cdf[i] - lo;
        if w <= 0.0 {
            return None;
        }
        let u_remapped = ((target - lo) / w).clamp(0.0, 1.0 - f32::EPSILON);
        Some((i, w / self.total, u_remapped))
    }

    /// The probability of picking `i`.
    pub fn pmf(&self, i: usize) -> f32 {
        if self.is_empty() || i >= self.cdf.len() {
            return 0.0;
        }
        let lo = if i == 0 { 0.0 } else { self.cdf[i - 1] };
        (self.cdf[i] - lo) / self.total
    }
}

/// The power heuristic (beta = 2) for two techniques with pdfs `pa` (the one used) and `pb`.
pub fn power_heuristic(pa: f32, pb: f32) -> f32 {
    // From the ratio of the smaller pdf to the larger, so that no square overflows (a pdf
    // above 1.8e19, a near-delta lobe's, squared is infinite) or underflows to 0/0.
    if pa.is_nan() || pa <= 0.0 {
        return 0.0;
    }
    if pb.is_nan() || pb <= 0.0 {
        return 1.0;
    }
    if pa.is_infinite() && pb.is_infinite() {
        return 0.5;
    }
    if pa >= pb {
        let r = pb / pa;
        1.0 / (1.0 + r * r)
    } else {
        let r2 = (pa / pb) * (pa / pb);
        r2 / (1.0 + r2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn power_heuristic_has_no_overflow() {
        // Weights of two techniques sum to 1, for ordinary pdfs and for ones whose squares
        // overflow (a near-delta lobe) or underflow.
        for (a, b) in [
            (1.0, 3.0),
            (1e20, 1.0),
            (1e30, 1e29),
            (1e-30, 1e-29),
            (0.0, 2.0),
            (f32::INFINITY, 1.0),
            (f32::INFINITY, f32::INFINITY),
        ] {
            let sum = power_heuristic(a, b) + power_heuristic(b, a);
            assert!((sum - 1.0).abs() < 1e-6, "({a}, {b}): {sum}");
        }
        // The earlier form returned 0 here (1e20² is infinite): the larger pdf takes it all.
        assert_eq!(power_heuristic(1e20, 1.0), 1.0);
        assert!((power_heuristic(1e30, 1e29) - 100.0 / 101.0).abs() < 1e-6);
        assert!((power_heuristic(1.0, 3.0) - 0.1).abs() < 1e-7);
        assert_eq!(power_heuristic(0.0, 0.0), 0.0);
    }

    #[test]
    fn fast_sin_cos_match_libm() {
        let (mut worst_quarter, mut worst_turn) = (0.0f32, 0.0f32);
        for i in 0..=100_000 {
            let u = i as f32 / 100_000.0;
            let a = std::f32::consts::FRAC_PI_4 * (2.0 * u - 1.0);
            let (s, c) = sin_cos_quarter(a);
            let (es, ec) = (a as f64).sin_cos();
            worst_quarter =
                worst_quarter.max((s as f64 - es).abs().max((c as f64 - ec).abs()) as f32);
            let (s, c) = sin_cos_turn(u);
            let (es, ec) = (std::f64::consts::TAU * u as f64).sin_cos();
            worst_turn = worst_turn.max((s as f64 - es).abs().max((c as f64 - ec).abs()) as f32);
        }
        // f32 rounding of the argument and the terms, not the polynomial, bounds the error.
        assert!(worst_quarter < 2e-7, "quarter: {worst_quarter}");
        assert!(worst_turn < 5e-7, "turn: {worst_turn}");
    }

    /// The draws of every pixel of a packet, bit for bit, one by one against its own sampler:
    /// both kinds, packets of 8 and 1 pixels, partial ones, passes of later epochs, the three
    /// calls in a random order, groups that straddle the table's end, and draws past it.
    #[test]
    fn packet_samplers_match_pixel_samplers() {
        fn draw(rng: &mut Sampler, call: u32) -> Vec<u32> {
            let u = match call {
                0 => vec![rng.uniform()],
                1 => rng.uniform2().to_array().to_vec(),
                2 => {
                    let ([u], v) = rng.uniforms_uniform2();
                    vec![u, v.x, v.y]
                }
                _ => {
                    let ([u, w], v) = rng.uniforms_uniform2();
                    vec![u, w, v.x, v.y]
                }
            };
            u.iter().map(|u| u.to_bits()).collect()
        }
        fn check<const P: usize>(samplers: &PassSampler, rng: &mut Rng, width: u32) {
            let n = 1 + rng.next_u32() % P as u32;
            let (x, y) = (rng.next_u32() % (width - 7), rng.next_u32() % 4096);
            let xs = std::array::from_fn(|i| x + (i as u32).min(n - 1));
            let mut packet = samplers.start_packet::<P>(xs, y, width);
            let mut pixels = xs.map(|x| samplers.start(x, y, width));
            let calls: Vec<u32> = (0..8).map(|_| rng.next_u32() % 4).collect();
            for (i, (a, b)) in packet.iter_mut().zip(&mut pixels).enumerate() {
                for &call in &calls {
                    assert_eq!(draw(a, call), draw(b, call), "pixel {i} of ({x}, {y})");
                }
            }
        }
        let mut rng = Rng::new(7, 11);
        // Passes at the epochs' edges, and random ones.
        let mut passes = vec![0, 1, 17, 65_535, 65_536, 65_537, 1 << 20, u32::MAX];
        passes.extend((0..4).map(|_| rng.next_u32()));
        for kind in SamplerKind::ALL {
            for seed in [0, 1, 0xdead_beef, u64::MAX] {
                for &pass in &passes {
                    let samplers = kind.pass(seed, pass);
                    for width in [8, 100, 1 << 20, u32::MAX] {
                        for _ in 0..8 {
                            check::<8>(&samplers, &mut rng, width);
                            check::<1>(&samplers, &mut rng, width);
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn lane_warps_and_frames_match_the_scalar_ones() {
        use lanes::LANES;
        let mut rng = Rng::new(11, 3);
        let bits = |v: Vec3| v.to_array().map(f32::to_bits);
        for round in 0..256 {
            let mut u: [Vec2; LANES] = std::array::from_fn(|_| rng.uniform2());
            // The disk's centre and its diagonals, where the branches meet.
            if round == 0 {
                u[0] = Vec2::splat(0.5);
                u[1] = Vec2::new(0.75, 0.75);
                u[2] = Vec2::new(0.25, 0.75);
                u[3] = Vec2::ZERO;
            }
            let n: [Vec3; LANES] = std::array::from_fn(|i| match i {
                // Both signs of z, and the poles.
                6 => Vec3::Z,
                7 => -Vec3::Z,
                _ => sample_uniform_sphere(rng.uniform2()),
            });
            let v: [Vec3; LANES] = std::array::from_fn(|_| sample_uniform_sphere(rng.uniform2()));
            let disk = sample_concentric_disk_lanes(Vec2s::from_fn(|i| u[i]));
            let wi = sample_cosine_hemisphere_lanes(Vec2s::from_fn(|i| u[i]));
            let frames = Frames::from_normal(Vec3s::from_fn(|i| n[i]));
            let vs = Vec3s::from_fn(|i| v[i]);
            let (world, local) = (frames.to_world(vs), frames.to_local(vs));
            let pdf = cosine_hemisphere_pdf_lanes(wi.z);
            for i in 0..LANES {
                let d = sample_concentric_disk(u[i]);
                assert_eq!(
                    disk.lane(i).to_array().map(f32::to_bits),
                    d.to_array().map(f32::to_bits)
                );
                let w = sample_cosine_hemisphere(u[i]);
                assert_eq!(bits(wi.lane(i)), bits(w));
                assert_eq!(pdf.0[i].to_bits(), cosine_hemisphere_pdf(w.z).to_bits());
                let frame = Frame::from_normal(n[i]);
                let lane = frames.lane(i);
                assert_eq!([bits(lane.t), bits(lane.b)], [bits(frame.t), bits(frame.b)]);
                assert_eq!(bits(world.lane(i)), bits(frame.to_world(v[i])));
                assert_eq!(bits(local.lane(i)), bits(frame.to_local(v[i])));
            }
        }
    }

    #[test]
    fn cyclic_pairs_close_the_polygon() {
        let pairs: Vec<_> = cyclic_pairs(&[1, 2, 3]).collect();
        assert_eq!(pairs, [(1, 2), (2, 3), (3, 1)]);
        assert_eq!(cyclic_pairs::<i32>(&[]).count(), 0);
        assert_eq!(cyclic_pairs(&[7]).collect::<Vec<_>>(), [(7, 7)]);
    }
}
