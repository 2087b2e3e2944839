//! Owen-scrambled Sobol' points with a Z-order (Morton) pixel index, after pbrt-v4's
//! `ZSobolSampler` (Ahmed and Wonka 2020) with Burley's (2020) hash-based scrambles.
//!
//! Sample `pass` of pixel `(x, y)` is point number `morton(x, y) · 2^16 + pass` of one global
//! sequence. Each draw (each call of [`ZSobol::uniform`] or [`ZSobol::uniform2`], counted by a
//! dimension counter) takes that index through a nested scramble of its bits keyed by the
//! dimension (so draws are decorrelated from each other and every pixel visits its points in
//! an order of its own), then evaluates the first one or two Sobol' dimensions there and Owen-
//! scrambles them (keyed by the dimension again). Because a nested scramble maps every aligned
//! block of `2^k` indices onto an aligned block, the first `2^k` passes of a pixel are, in
//! every 1D draw, one point in each `1/2^k` interval, and in every 2D draw a (0, k, 2)-net: any
//! prefix of passes is well distributed, and the image depends only on the seed, the pixel and
//! the pass, never on how threads split the work. One pair of draws is not padded: the first
//! vertex's light direction ([`JOINT_DRAW`]) shares the camera draw's scrambled index, and the
//! camera takes Sobol' dimensions 2 and 3 of it (a (2, k, 2)-net), so that the camera's jitter
//! and the light direction form one (3, k, 4)-net.
//!
//! pbrt fixes the sample count in advance and places it in the low bits so that neighbouring
//! pixels' samples also tile one larger net (blue-noise error) at exactly that count. A
//! progressive viewer does not know its sample count, so the pass gets a fixed 16 bits
//! ([`PASSES_PER_EPOCH`]): a pixel's own samples stay stratified at every pass count, and the
//! blue-noise tiling between pixels is given up. Then the pixel's bits only reach the last
//! bits of each point, so with one output scramble for all pixels every pixel would see nearly
//! the same net, and neighbouring pixels' errors would be alike (blotches, not noise): the
//! output scrambles are keyed by the pixel too, which makes pixels' errors independent. Passes
//! beyond 2^16 start a new epoch with independent scrambles, which keeps the estimate unbiased.
//!
//! Cost: a draw's scramble seeds before the pixel is mixed in depend only on the seed, the
//! epoch and the draw, so [`ZSobolPass`] hashes them once per tile and pass. The scrambles work
//! on bit-reversed values and x86-64 has no bit-reversal instruction (it takes about 16
//! instructions), so the draws reverse no more than they must: they take the first two
//! dimensions from the scrambled index as it comes, bit-reversed (the second by a subset sum
//! rather than a superset sum), and reverse only each output's 32 bits, before and after its
//! Owen scramble. Those 32-bit steps are alike for every coordinate, so coordinates finished
//! together ([`ZSobol::uniform2`], [`ZSobol::uniforms_uniform2`]) compile, for AVX2, to vector
//! instructions (byte shuffles for the reversals). Together these take a draw from about 100
//! instructions to about 80 (fig8a).
//!
//! Those vectors are only two or four lanes wide, and the 64-bit hashes before them are
//! scalar. The pixels of a packet (the consecutive pixels whose camera rays are traced
//! together) share the pass and so every draw's seed: [`ZSobolPass::packet`] computes their
//! first [`PACKET_DRAWS`] draws together, each step for all eight pixels at once (full AVX2
//! vectors; 64-bit multiplications, which AVX2 lacks, take three 32-bit ones), and each
//! pixel's sampler then reads them from its table. A draw then takes about 26 instructions
//! per pixel, 35 with its share of the packet's set-up, and a direct-light render of the
//! peer scenes 5–10% fewer instructions (light sampling; 2–7% for antishadow). Four tabled
//! draws save about half as much, eight less than six: a direct-light path makes six, and
//! draws that a path never makes are wasted.

/// Passes per epoch: the pass occupies the low `LOG2_PASSES` bits of the index.
pub const LOG2_PASSES: u32 = 16;
pub const PASSES_PER_EPOCH: u32 = 1 << LOG2_PASSES;

/// The draw that shares the first draw's scrambled index: in the integrator's order (camera
/// jitter; then per vertex light pick, technique pick, light direction) the first vertex's
/// light direction. It takes Sobol' dimensions 0 and 1 of that index (a (0, 2)-net, as every
/// other draw) and the camera's jitter takes dimensions 2 and 3 (a (2, 2)-net in the plane),
/// so that the two form one (3, 4)-net per pixel: where the light's visibility changes across
/// a pixel (a penumbra), a point's position and its light direction are stratified together,
/// not each on its own (`docs/method.md` §6.0).
pub const JOINT_DRAW: usize = 3;

/// Draws whose scramble seeds [`ZSobolPass`] computes once for all pixels: the draws of a path
/// of five vertices. Later draws hash their seed as they go.
const TABLED_DIMENSIONS: usize = 32;

/// Draws that [`ZSobolPass::packet`] computes for all pixels of a packet at once: those of a
/// direct-light path (camera jitter; light pick, technique pick and light direction; lobe and
/// BSDF direction). A draw that a path does not make is wasted work, so longer paths compute
/// their later draws one by one.
pub const PACKET_DRAWS: usize = 6;

/// What the samplers of every pixel in one pass share: the index's pass bits and the seeds of
/// each draw's scrambles before the pixel is mixed in, which depend only on the seed, the
/// epoch and the draw. Made once per tile and pass, they save each draw a 64-bit hash.
#[derive(Clone, Debug)]
pub struct ZSobolPass {
    /// The pass within its epoch: the low bits of the index.
    pass_bits: u64,
    /// The seed and epoch, hashed.
    key: u64,
    /// [`dimension_seed`] of the first draws.
    dimension_seeds: [u64; TABLED_DIMENSIONS],
}

impl ZSobolPass {
    /// The samplers of pass `pass` under `seed`.
    pub fn new(seed: u64, pass: u32) -> Self {
        let epoch = (pass >> LOG2_PASSES) as u64;
        let key = mix_bits(seed ^ mix_bits(epoch.wrapping_add(0x5851_F42D_4C95_7F2D)));
        ZSobolPass {
            pass_bits: (pass & (PASSES_PER_EPOCH - 1)) as u64,
            key,
            dimension_seeds: std::array::from_fn(|d| dimension_seed(key, d)),
        }
    }

    /// The sampler of pixel `(x, y)` in this pass.
    #[inline(always)]
    pub fn pixel(&self, x: u32, y: u32) -> ZSobol<'_> {
        let morton = morton2(x, y);
        ZSobol {
            pass: self,
            index_mixed: self.index_mixed(morton),
            pixel_key: pixel_key(morton),
            dimension: 0,
            drawn: None,
        }
    }

    /// The samplers of pixels `(x[i], y)` in this pass, the same numbers as [`Self::pixel`]
    /// gives, with their first [`PACKET_DRAWS`] draws computed here. Every step below is the
    /// same for all `P` pixels (lanes), so that where compiled for AVX2 the loops over lanes
    /// become vector instructions.
    #[inline(always)]
    pub fn packet<const P: usize>(&self, x: [u32; P], y: u32) -> [ZSobol<'_>; P] {
        const { assert!(PACKET_DRAWS <= TABLED_DIMENSIONS) };
        let (mut index_mixed, mut pixel_keys) = ([0; P], [0; P]);
        for i in 0..P {
            let morton = morton2(x[i], y);
            index_mixed[i] = self.index_mixed(morton);
            pixel_keys[i] = pixel_key(morton);
        }
        let mut drawn = [[[0.0; 2]; PACKET_DRAWS]; P];
        let mut camera_rev = [0; P];
        for (d, &h) in self.dimension_seeds[..PACKET_DRAWS].iter().enumerate() {
            // The 64-bit hashes (four lanes to an AVX2 vector) apart from the 32-bit steps
            // (eight lanes), which would otherwise run four lanes at a time with them.
            let (mut index_rev, mut seeds) = ([0; P], [0; P]);
            for i in 0..P {
                index_rev[i] = match d == JOINT_DRAW {
                    true => camera_rev[i],
                    false => nested_scramble_rev_mixed(index_mixed[i], h),
                };
                seeds[i] = mix_bits(h ^ pixel_keys[i]);
            }
            if d == 0 {
                camera_rev = index_rev;
            }
            // Both coordinates, as `uniform2` takes them; `uniform` takes the first.
            let (mut coordinates, mut scrambles) = ([[0; P]; 2], [[0; P]; 2]);
            let camera = d == 0;
            for i in 0..P {
                coordinates[0][i] = first_coordinate(index_rev[i], camera);
                coordinates[1][i] = second_coordinate(index_rev[i], camera);
                scrambles[0][i] = seeds[i] as u32;
                scrambles[1][i] = (seeds[i] >> 32) as u32;
            }
            let mut u = [[0.0; P]; 2];
            for c in 0..2 {
                for i in 0..P {
                    u[c][i] = scrambled_unit(coordinates[c][i], scrambles[c][i]);
                }
            }
            for (i, drawn) in drawn.iter_mut().enumerate() {
                drawn[d] = [u[0][i], u[1][i]];
            }
        }
        std::array::from_fn(|i| ZSobol {
            pass: self,
            index_mixed: index_mixed[i],
            pixel_key: pixel_keys[i],
            dimension: 0,
            drawn: Some(drawn[i]),
        })
    }

    /// `morton << LOG2_PASSES | pass`, bit-reversed, through the nested scramble's first step.
    #[inline(always)]
    fn index_mixed(&self, morton: u64) -> u64 {
        nested_scramble_premix(((morton << LOG2_PASSES) | self.pass_bits).reverse_bits())
    }
}

/// The hash of a pixel's Morton code that keys its output scrambles.
#[inline(always)]
fn pixel_key(morton: u64) -> u64 {
    mix_bits(morton ^ 0xD1B5_4A32_D192_ED03)
}

/// The seed of draw `dimension`'s scrambles under `key`, before the pixel is mixed in.
#[inline]
fn dimension_seed(key: u64, dimension: usize) -> u64 {
    mix_bits(key ^ (dimension as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15))
}

/// The sampler of one pixel sample (one path): a position in the global sequence and a
/// counter of draws.
#[derive(Clone, Debug)]
pub struct ZSobol<'a> {
    /// What all pixels of this pass share.
    pass: &'a ZSobolPass,
    /// `morton(x, y) << LOG2_PASSES | pass`, bit-reversed (as the scramble takes it), through
    /// the nested scramble's first step, which does not depend on the draw: done once here
    /// rather than at every draw.
    index_mixed: u64,
    /// The pixel, hashed: it keys the output scrambles, so each pixel's points are a net
    /// scrambled on its own.
    pixel_key: u64,
    /// Draws so far: each one is its own (padded) dimension.
    dimension: usize,
    /// Both coordinates of the first draws, if computed with the packet's other pixels.
    drawn: Option<[[f32; 2]; PACKET_DRAWS]>,
}

impl ZSobol<'_> {
    /// The next `draws` draws, if the packet computed them all; a group that runs past the
    /// table is computed as a whole, which gives the same numbers.
    #[inline(always)]
    fn take_drawn(&mut self, draws: usize) -> Option<&[[f32; 2]]> {
        let drawn = self
            .drawn
            .as_ref()?
            .get(self.dimension..self.dimension + draws)?;
        self.dimension += draws;
        Some(drawn)
    }

    /// The scrambled index, bit-reversed (for [`JOINT_DRAW`] the first draw's), the output
    /// scrambles' seeds of the next draw, and whether it is the first (the camera's, which
    /// takes Sobol' dimensions 2 and 3).
    #[inline(always)]
    fn next_draw(&mut self) -> (u64, u64, bool) {
        let d = self.dimension;
        let h = match self.pass.dimension_seeds.get(d) {
            Some(&h) => h,
            None => dimension_seed(self.pass.key, d),
        };
        self.dimension += 1;
        // The joint draw scrambles the index as the camera's draw does, whether or not that
        // one was drawn.
        let index_key = match d == JOINT_DRAW {
            true => self.pass.dimension_seeds[0],
            false => h,
        };
        (
            nested_scramble_rev_mixed(self.index_mixed, index_key),
            mix_bits(h ^ self.pixel_key),
            d == 0,
        )
    }

    /// Uniform in [0, 1): the first Sobol' dimension (van der Corput) of this draw's index
    /// (dimension 2 for the camera's draw; [`JOINT_DRAW`]'s index is the camera's).
    #[inline(always)]
    pub fn uniform(&mut self) -> f32 {
        if let Some(&[[u, _]]) = self.take_drawn(1) {
            return u;
        }
        let (index_rev, seeds, camera) = self.next_draw();
        scrambled_unit(first_coordinate(index_rev, camera), seeds as u32)
    }

    /// `N ≤ 2` uniform numbers in [0, 1) and then a point on [0, 1)², as `N` calls of
    /// [`ZSobol::uniform`] and one of [`ZSobol::uniform2`] give them: drawn together, their
    /// coordinates' reversals and scrambles run side by side, four lanes of vector
    /// instructions where compiled for AVX2 (a lane left over scrambles a constant).
    #[inline(always)]
    pub fn uniforms_uniform2<const N: usize>(&mut self) -> ([f32; N], glam::Vec2) {
        const { assert!(N <= 2) };
        if let Some(drawn) = self.take_drawn(N + 1) {
            return (
                std::array::from_fn(|i| drawn[i][0]),
                glam::Vec2::from(drawn[N]),
            );
        }
        let mut lanes = [(0, 0); 4];
        for lane in &mut lanes[..N] {
            let (index_rev, seeds, camera) = self.next_draw();
            *lane = (first_coordinate(index_rev, camera), seeds as u32);
        }
        let (index_rev, seeds, camera) = self.next_draw();
        lanes[N] = (first_coordinate(index_rev, camera), seeds as u32);
        lanes[N + 1] = (second_coordinate(index_rev, camera), (seeds >> 32) as u32);
        let u = lanes.map(|(coordinate, seed)| scrambled_unit(coordinate, seed));
        (
            std::array::from_fn(|i| u[i]),
            glam::Vec2::new(u[N], u[N + 1]),
        )
    }

    /// Uniform on [0, 1)²: the first two Sobol' dimensions of this draw's index, which form a
    /// (0, 2)-sequence, each Owen-scrambled with its own seed (dimensions 2 and 3 for the
    /// camera's draw; [`JOINT_DRAW`]'s index is the camera's).
    #[inline(always)]
    pub fn uniform2(&mut self) -> glam::Vec2 {
        if let Some(&[u]) = self.take_drawn(1) {
            return glam::Vec2::from(u);
        }
        let (index_rev, seeds, camera) = self.next_draw();
        // The two lanes run the same steps: compiled for AVX2, the reversals and scrambles of
        // both are vector instructions.
        glam::Vec2::new(
            scrambled_unit(first_coordinate(index_rev, camera), seeds as u32),
            scrambled_unit(second_coordinate(index_rev, camera), (seeds >> 32) as u32),
        )
    }
}

/// A Sobol' coordinate (digit `i`, worth `2^-(i+1)`, at bit `31 - i`) Owen-scrambled under
/// `seed`, as a float in [0, 1) like `Rng::uniform`: the scramble takes the digits reversed.
#[inline(always)]
fn scrambled_unit(coordinate: u32, seed: u32) -> f32 {
    let v = owen_scramble_rev(coordinate.reverse_bits(), seed).reverse_bits();
    (v >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// The Morton (Z-order) code of a pixel: the bits of `x` and `y` interleaved, `x` lowest.
#[inline]
pub fn morton2(x: u32, y: u32) -> u64 {
    fn spread(v: u32) -> u64 {
        let mut v = v as u64;
        v = (v | (v << 16)) & 0x0000_FFFF_0000_FFFF;
        v = (v | (v << 8)) & 0x00FF_00FF_00FF_00FF;
        v = (v | (v << 4)) & 0x0F0F_0F0F_0F0F_0F0F;
        v = (v | (v << 2)) & 0x3333_3333_3333_3333;
        (v | (v << 1)) & 0x5555_5555_5555_5555
    }
    spread(x) | (spread(y) << 1)
}

/// The first Sobol' dimension (van der Corput) of an index given bit-reversed (index bit `j`
/// at bit `63 - j`), as a 32-bit fraction (digit `i`, worth `2^-(i+1)`, at bit `31 - i`). Its
/// generator matrix is the identity: digit `i` is index bit `i`, the reversed index's high half.
#[inline]
pub fn sobol0(index_rev: u64) -> u32 {
    (index_rev >> 32) as u32
}

/// The second Sobol' dimension (primitive polynomial x + 1) of an index given bit-reversed,
/// as [`sobol0`]. Its generator matrix is Pascal's triangle mod 2: index bit `j` flips digit
/// `i` when `binom(j, i)` is odd, that is (Lucas) when the bits of `i` are a subset of those
/// of `j`. Digit `i < 32` only sees the low five bits of `j`, so index bits `j` and `j + 32`
/// act alike: fold the reversed index's halves (index bit `j` and `j + 32` both land at bit
/// `31 - j`). Then the fraction's bit `q = 31 - i` is the parity of the folded bits at subsets
/// of `q` (complementing five bits turns supersets into subsets): a subset sum over the five
/// bits of a position, five shift-and-mask steps for all digits at once.
#[inline]
pub fn sobol1(index_rev: u64) -> u32 {
    const MASKS: [u32; 5] = [
        0xAAAA_AAAA,
        0xCCCC_CCCC,
        0xF0F0_F0F0,
        0xFF00_FF00,
        0xFFFF_0000,
    ];
    let mut v = (index_rev ^ (index_rev >> 32)) as u32;
    for (b, mask) in MASKS.iter().enumerate() {
        v ^= (v << (1 << b)) & mask;
    }
    v
}

/// A draw's first coordinate: Sobol' dimension 0 of its index, or 2 for the camera's draw.
#[inline(always)]
fn first_coordinate(index_rev: u64, camera: bool) -> u32 {
    match camera {
        true => sobol2(index_rev),
        false => sobol0(index_rev),
    }
}

/// A draw's second coordinate: Sobol' dimension 1 of its index, or 3 for the camera's draw.
#[inline(always)]
fn second_coordinate(index_rev: u64, camera: bool) -> u32 {
    match camera {
        true => sobol3(index_rev),
        false => sobol1(index_rev),
    }
}

/// The third Sobol' dimension (primitive polynomial x² + x + 1, Joe and Kuo's initial numbers
/// 1, 3) of an index given bit-reversed, as [`sobol0`]: index bits 0–31 (as `sobol0`, which
/// sees those alone), by a table per byte of the reversed index's high half.
#[inline]
pub fn sobol2(index_rev: u64) -> u32 {
    by_bytes(&SOBOL2, index_rev)
}

/// The fourth Sobol' dimension (x³ + x + 1, initial numbers 1, 3, 1), as [`sobol2`].
#[inline]
pub fn sobol3(index_rev: u64) -> u32 {
    by_bytes(&SOBOL3, index_rev)
}

/// A dimension's columns XORed over the index bits set, four table lookups.
#[inline(always)]
fn by_bytes(tables: &[[u32; 256]; 4], index_rev: u64) -> u32 {
    let high = (index_rev >> 32) as u32;
    tables[0][(high & 0xff) as usize]
        ^ tables[1][((high >> 8) & 0xff) as usize]
        ^ tables[2][((high >> 16) & 0xff) as usize]
        ^ tables[3][(high >> 24) as usize]
}

static SOBOL2: [[u32; 256]; 4] = byte_tables(&directions(2, 1, [1, 3, 0]));
static SOBOL3: [[u32; 256]; 4] = byte_tables(&directions(3, 1, [1, 3, 1]));

/// The generator matrix's columns `v_k` (output digit 0 in the top bit) of the dimension with
/// a primitive polynomial of degree `s` and inner coefficients `a`, from its initial numbers
/// `m` (Bratley and Fox's recurrence, as Joe and Kuo tabulate them).
const fn directions(s: usize, a: u32, m: [u32; 3]) -> [u32; 32] {
    let mut v = [0u32; 32];
    let mut k = 0;
    while k < 32 {
        if k < s {
            v[k] = m[k] << (31 - k);
        } else {
            let mut x = v[k - s] ^ (v[k - s] >> s);
            let mut j = 1;
            while j < s {
                if (a >> (s - 1 - j)) & 1 == 1 {
                    x ^= v[k - j];
                }
                j += 1;
            }
            v[k] = x;
        }
        k += 1;
    }
    v
}

/// For each byte `b` of the reversed index's high half (index bit `k` at bit `31 − k`) and
/// each value of it, the XOR of the columns of the index bits it holds.
const fn byte_tables(v: &[u32; 32]) -> [[u32; 256]; 4] {
    let mut t = [[0u32; 256]; 4];
    let mut b = 0;
    while b < 4 {
        let mut value = 0;
        while value < 256 {
            let mut x = 0;
            let mut bit = 0;
            while bit < 8 {
                if (value >> bit) & 1 == 1 {
                    x ^= v[31 - (8 * b + bit)];
                }
                bit += 1;
            }
            t[b][value] = x;
            value += 1;
        }
        b += 1;
    }
    t
}

/// Owen scrambling of a digit-reversed value (Burley 2020, after Laine and Karras 2011): every
/// step flips a bit by a function of the bits below it, i.e. of the coarser digits, so each
/// digit is permuted depending on the digits before it, as a nested uniform scramble does.
#[inline]
pub fn owen_scramble_rev(mut v: u32, seed: u32) -> u32 {
    v ^= v.wrapping_mul(0x3d20_adea);
    v = v.wrapping_add(seed);
    v = v.wrapping_mul((seed >> 16) | 1);
    v ^= v.wrapping_mul(0x0552_6c56);
    v ^= v.wrapping_mul(0x53a2_2864);
    v
}

/// A nested scramble of an index: bit `i` is flipped by a function of the bits above it and
/// the seed, the same construction as [`owen_scramble_rev`] on the bit-reversed index, in 64
/// bits. It maps every aligned block of `2^k` indices onto an aligned block of `2^k`, and the
/// low (pass) bits of a pixel are permuted by its own high (Morton) bits.
#[inline]
pub fn nested_scramble(index: u64, seed: u64) -> u64 {
    nested_scramble_rev(index.reverse_bits(), seed).reverse_bits()
}

/// [`nested_scramble`] on the bit-reversed index, returning it bit-reversed: each step flips
/// a bit by a function of the bits below it.
#[inline]
pub fn nested_scramble_rev(v: u64, seed: u64) -> u64 {
    nested_scramble_rev_mixed(nested_scramble_premix(v), seed)
}

/// The first step of [`nested_scramble_rev`], the one that does not depend on the seed.
#[inline(always)]
fn nested_scramble_premix(v: u64) -> u64 {
    v ^ v.wrapping_mul(0x3d20_adea_9b5c_6f12)
}

/// The steps of [`nested_scramble_rev`] after [`nested_scramble_premix`].
#[inline(always)]
fn nested_scramble_rev_mixed(mut v: u64, seed: u64) -> u64 {
    v = v.wrapping_add(seed);
    v = v.wrapping_mul((seed >> 32) | 1);
    v ^= v.wrapping_mul(0x0552_6c56_e1a4_c3d6);
    v ^= v.wrapping_mul(0x53a2_2864_27f0_5b8a);
    v
}

/// A 64-bit finaliser (pbrt's `MixBits`): every input bit affects every output bit.
#[inline]
pub fn mix_bits(mut v: u64) -> u64 {
    v ^= v >> 31;
    v = v.wrapping_mul(0x7fb5_d329_728e_a185);
    v ^= v >> 27;
    v = v.wrapping_mul(0x81da_def4_bc2d_d44d);
    v ^ (v >> 33)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The second dimension's generator matrix columns as pbrt-v4's `SobolMatrices32` lists
    /// them (output digit 0 in the top bit): index bits 0–7, 31 and 32.
    #[test]
    fn second_dimension_matches_pbrt_matrices() {
        let columns: [(u32, u32); 10] = [
            (0, 0x8000_0000),
            (1, 0xc000_0000),
            (2, 0xa000_0000),
            (3, 0xf000_0000),
            (4, 0x8800_0000),
            (5, 0xcc00_0000),
            (6, 0xaa00_0000),
            (7, 0xff00_0000),
            (31, 0xffff_ffff),
            (32, 0x8000_0000),
        ];
        for (j, column) in columns {
            assert_eq!(sobol1((1u64 << j).reverse_bits()), column, "column {j}");
        }
        // Linear over GF(2): the point of a sum of index bits is the XOR of their columns.
        let point = |index: u64| sobol1(index.reverse_bits());
        assert_eq!(point(0b101), point(0b100) ^ point(0b001));
    }

    /// The third and fourth dimensions' generator matrix columns (the point of index `2^j`),
    /// as SciPy's unscrambled `qmc.Sobol(d=4)` gives them (the same sets of points over the
    /// first 64 indices): index bits 0–7 and 31; and linear over GF(2).
    #[test]
    fn third_and_fourth_dimensions_match_joe_and_kuo() {
        let columns: [(u32, u32, u32); 9] = [
            (0, 0x8000_0000, 0x8000_0000),
            (1, 0xc000_0000, 0xc000_0000),
            (2, 0x6000_0000, 0x2000_0000),
            (3, 0x9000_0000, 0x5000_0000),
            (4, 0xe800_0000, 0xf800_0000),
            (5, 0x5c00_0000, 0x7400_0000),
            (6, 0x8e00_0000, 0xa200_0000),
            (7, 0xc500_0000, 0x9300_0000),
            (31, 0xc500_5555, 0x5005_0093),
        ];
        for (j, two, three) in columns {
            let index_rev = (1u64 << j).reverse_bits();
            assert_eq!(sobol2(index_rev), two, "dimension 2, column {j}");
            assert_eq!(sobol3(index_rev), three, "dimension 3, column {j}");
        }
        let point = |index: u64| (sobol2(index.reverse_bits()), sobol3(index.reverse_bits()));
        let (a, b, c) = (point(0b1101), point(0b1000), point(0b0101));
        assert_eq!(a, (b.0 ^ c.0, b.1 ^ c.1));
        // The table-driven dimensions against the recurrence bit by bit, on many indices.
        let mut v = 0x0123_4567_89ab_cdef_u64;
        for _ in 0..10_000 {
            assert_eq!(
                sobol2(v.reverse_bits()),
                reference::sobol_rev(v, 2).reverse_bits()
            );
            assert_eq!(
                sobol3(v.reverse_bits()),
                reference::sobol_rev(v, 3).reverse_bits()
            );
            v = v
                .wrapping_mul(0x5851_F42D_4C95_7F2D)
                .wrapping_add(0x1405_7B7E_F767_814F);
        }
    }

    #[test]
    fn nested_scramble_keeps_aligned_blocks() {
        for seed in [1u64, 0xdead_beef, u64::MAX] {
            for k in [1u32, 4, 8] {
                let base = 0x1234_5600_u64 << 8;
                let mut image: Vec<u64> = (0..1u64 << k)
                    .map(|s| nested_scramble(base | s, seed))
                    .collect();
                let block = image[0] >> k;
                assert!(image.iter().all(|&i| i >> k == block));
                image.sort_unstable();
                image.dedup();
                assert_eq!(image.len(), 1 << k, "not a bijection on the block");
            }
        }
    }

    /// The sampler as first written, draw by draw: the oracle that the restructured one (the
    /// per-pass table of seeds, the reversals merged or narrowed) returns the same numbers.
    /// The hashes and scrambles it shares with the sampler did not change.
    mod reference {
        use super::super::{
            PASSES_PER_EPOCH, mix_bits, morton2, nested_scramble_rev, owen_scramble_rev,
        };

        pub struct ZSobol {
            index_rev: u64,
            key: u64,
            pixel_key: u64,
            dimension: u64,
            /// The first draw's scrambled index, which draw 3 reads.
            camera: u64,
        }

        impl ZSobol {
            pub fn new(seed: u64, x: u32, y: u32, pass: u32) -> Self {
                let epoch = (pass >> 16) as u64;
                let index = (morton2(x, y) << 16) | (pass & (PASSES_PER_EPOCH - 1)) as u64;
                ZSobol {
                    index_rev: index.reverse_bits(),
                    key: mix_bits(seed ^ mix_bits(epoch.wrapping_add(0x5851_F42D_4C95_7F2D))),
                    pixel_key: mix_bits(morton2(x, y) ^ 0xD1B5_4A32_D192_ED03),
                    dimension: 0,
                    camera: 0,
                }
            }

            /// The draw's index (for draw 3 the first draw's), its seeds, and whether it is
            /// the first draw, which takes Sobol' dimensions 2 and 3.
            fn next_draw(&mut self) -> (u64, u64, bool) {
                let h = mix_bits(self.key ^ self.dimension.wrapping_mul(0x9E37_79B9_7F4A_7C15));
                let d = self.dimension;
                self.dimension += 1;
                let index = nested_scramble_rev(self.index_rev, h).reverse_bits();
                if d == 0 {
                    self.camera = index;
                }
                match d == 3 {
                    true => (self.camera, mix_bits(h ^ self.pixel_key), false),
                    false => (index, mix_bits(h ^ self.pixel_key), d == 0),
                }
            }

            pub fn uniform(&mut self) -> f32 {
                let (index, seeds, camera) = self.next_draw();
                let first = match camera {
                    true => sobol_rev(index, 2),
                    false => index as u32,
                };
                unit(owen_scramble_rev(first, seeds as u32))
            }

            pub fn uniform2(&mut self) -> glam::Vec2 {
                let (index, seeds, camera) = self.next_draw();
                let (first, second) = match camera {
                    true => (sobol_rev(index, 2), sobol_rev(index, 3)),
                    false => (index as u32, sobol1_rev(index)),
                };
                glam::Vec2::new(
                    unit(owen_scramble_rev(first, seeds as u32)),
                    unit(owen_scramble_rev(second, (seeds >> 32) as u32)),
                )
            }
        }

        /// Sobol' dimension 2 or 3 of `index`'s low 32 bits, digit-reversed, from the
        /// direction numbers' recurrence bit by bit.
        pub fn sobol_rev(index: u64, dimension: usize) -> u32 {
            let (s, a, m): (usize, u32, &[u32]) = match dimension {
                2 => (2, 1, &[1, 3]),
                _ => (3, 1, &[1, 3, 1]),
            };
            let mut v = Vec::with_capacity(32);
            for k in 0..32 {
                let column = if k < s {
                    m[k] << (31 - k)
                } else {
                    let mut x = v[k - s] ^ (v[k - s] >> s);
                    for j in 1..s {
                        if (a >> (s - 1 - j)) & 1 == 1 {
                            x ^= v[k - j];
                        }
                    }
                    x
                };
                v.push(column);
            }
            let point = (0..32)
                .filter(|k| (index >> k) & 1 == 1)
                .fold(0u32, |x, k| x ^ v[k]);
            point.reverse_bits()
        }

        fn unit(v_rev: u32) -> f32 {
            (v_rev.reverse_bits() >> 8) as f32 * (1.0 / 16_777_216.0)
        }

        pub fn sobol1_rev(index: u64) -> u32 {
            const MASKS: [u64; 6] = [
                0x5555_5555_5555_5555,
                0x3333_3333_3333_3333,
                0x0F0F_0F0F_0F0F_0F0F,
                0x00FF_00FF_00FF_00FF,
                0x0000_FFFF_0000_FFFF,
                0x0000_0000_FFFF_FFFF,
            ];
            let mut v = index;
            for (b, mask) in MASKS.iter().enumerate() {
                v ^= (v >> (1 << b)) & mask;
            }
            v as u32
        }
    }

    /// Every draw equals the reference's bit for bit: seeds, pixels up to the Morton code's
    /// top bits, passes of later epochs, 1D and 2D draws interleaved, and more draws than the
    /// table holds.
    #[test]
    fn draws_match_the_reference_sampler() {
        let pixels = [
            (0, 0),
            (1, 0),
            (0, 1),
            (37, 411),
            (1919, 1079),
            (65_535, 65_535),
            (u32::MAX, u32::MAX),
        ];
        let passes = (0..64).chain([255, 65_535, 65_536, 65_537, 1 << 20, u32::MAX]);
        let mut draws = 0;
        for seed in [0, 1, 0xdead_beef, u64::MAX] {
            for pass in passes.clone() {
                let sampler = ZSobolPass::new(seed, pass);
                for (x, y) in pixels {
                    let (mut new, mut old) = (
                        sampler.pixel(x, y),
                        reference::ZSobol::new(seed, x, y, pass),
                    );
                    for d in 0..TABLED_DIMENSIONS + 8 {
                        // An irregular mix of 1D and 2D draws, alone and together.
                        let bits = |v: &[f32]| v.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
                        let (a, b) = match (d * 7 + x as usize) % 5 {
                            0 => (
                                new.uniform2().to_array().to_vec(),
                                old.uniform2().to_array().to_vec(),
                            ),
                            1 => {
                                let ([u, v], w) = new.uniforms_uniform2();
                                let (old_u, old_v, old_w) =
                                    (old.uniform(), old.uniform(), old.uniform2());
                                (vec![u, v, w.x, w.y], vec![old_u, old_v, old_w.x, old_w.y])
                            }
                            2 => {
                                let ([u], w) = new.uniforms_uniform2();
                                let (old_u, old_w) = (old.uniform(), old.uniform2());
                                (vec![u, w.x, w.y], vec![old_u, old_w.x, old_w.y])
                            }
                            _ => (vec![new.uniform()], vec![old.uniform()]),
                        };
                        assert_eq!(bits(&a), bits(&b));
                        draws += 1;
                    }
                }
            }
        }
        assert!(draws > 10_000);
    }

    #[test]
    fn first_two_dimensions_match_the_reference() {
        let mut v = 0x0123_4567_89ab_cdef_u64;
        for _ in 0..10_000 {
            let v_rev = v.reverse_bits();
            assert_eq!(sobol0(v_rev), (v as u32).reverse_bits(), "index {v:#x}");
            let expected = reference::sobol1_rev(v).reverse_bits();
            assert_eq!(sobol1(v_rev), expected, "index {v:#x}");
            v = v
                .wrapping_mul(0x5851_F42D_4C95_7F2D)
                .wrapping_add(0x1405_7B7E_F767_814F);
        }
    }

    #[test]
    fn morton_interleaves() {
        assert_eq!(morton2(0, 0), 0);
        assert_eq!(morton2(1, 0), 1);
        assert_eq!(morton2(0, 1), 2);
        assert_eq!(morton2(3, 3), 15);
        assert_eq!(morton2(u32::MAX, 0), 0x5555_5555_5555_5555);
    }
}
