//! The table behind sampling the environment within a window (`docs/method.md` §9.3): a
//! piecewise-constant density over the window's point-independent coordinates
//! `(α, β) ∈ (−1, 1)²`, `α = a / (1 + |a|)` of the gnomonic `a = ω·s / ω·o` (increasing like
//! Bitterli et al. 2015's angle `atan a`, within a factor 2 of its resolution, and with no
//! trigonometry either way), on a grid that is uniform (1/144: 0.4° to 0.8°) except where the
//! environment jumps (a sun's edge), whose intervals are cut 32 times finer, and the exact
//! integrals that draw from it within a box.

use glam::Vec3;
use rayon::prelude::*;
/// Base intervals per axis (1/144 each: 0.4° of angle at the window's normal and edge-on,
/// 0.8° at 45°; the built-in sky's pixels are 0.7°). With 256 (up to 0.9°) the MSE of `window`
/// and `windows2` at equal samples was 2 % higher than with the angles' uniform 0.7°; with 288
/// it is the same, and the table still costs less to build than the angles' did.
pub const GUIDED_BASE_CELLS: usize = 288;
/// Fine cells per base interval where the environment jumps (0.012° to 0.025° each).
pub const GUIDED_REFINE: usize = 32;
/// At most this many base intervals per axis are refined (before widening by one on each
/// side): a sun takes about ten.
const MAX_REFINED: usize = 24;
/// A base interval is refined when the mass its cells could misplace (their supersamples'
/// spread times their area) exceeds this share of the table's total.
const REFINE_SHARE: f64 = 1e-3;
/// Supersamples per side of a base cell.
const SUPERSAMPLES: usize = 3;
/// Intervals per side of the grid on which a fine cell at a jump takes its largest value.
const EDGE_SAMPLES: usize = 4;

const BASE_WIDTH: f64 = 2.0 / GUIDED_BASE_CELLS as f64;

/// The coordinate `α ∈ (−1, 1)` of a direction whose gnomonic coordinate is `a` (`ω·s / ω·o`):
/// `a / (1 + |a|)`, increasing, so the window's bounding box in `a` is a box in `α`.
#[inline]
pub fn coordinate(a: f64) -> f64 {
    a / (1.0 + a.abs())
}

/// The inverse of [`coordinate`]: `a = α / (1 − |α|)`.
#[inline]
pub fn gnomonic(alpha: f64) -> f64 {
    alpha / (1.0 - alpha.abs())
}

/// One axis of the grid: base intervals of [`BASE_WIDTH`], each cut into equal fine cells.
#[derive(Clone, Debug)]
struct Axis {
    /// Fine cell edges from `−1` to `1`.
    edges: Vec<f64>,
    /// `first[b]`: the first fine cell of base interval `b`; `first[BASE] = cells`.
    first: Vec<usize>,
    /// Per base interval its first fine cell and its number of cells (as `f64`, as
    /// [`Self::locate`] scales by it): a fixed-size array, so its index needs no bounds check.
    spans: Box<[(usize, f64); GUIDED_BASE_CELLS]>,
}

impl Axis {
    /// Base interval `b` cut into `GUIDED_REFINE` cells where `refined[b]`, else kept whole.
    fn new(refined: &[bool]) -> Axis {
        let mut edges = Vec::with_capacity(GUIDED_BASE_CELLS + 1);
        let mut first = Vec::with_capacity(GUIDED_BASE_CELLS + 1);
        for (b, &fine) in refined.iter().enumerate() {
            first.push(edges.len());
            let k = if fine { GUIDED_REFINE } else { 1 };
            for j in 0..k {
                edges.push(-1.0 + (b as f64 + j as f64 / k as f64) * BASE_WIDTH);
            }
        }
        first.push(edges.len());
        edges.push(1.0);
        let spans = Box::new(std::array::from_fn(|b| {
            (first[b], (first[b + 1] - first[b]) as f64)
        }));
        Axis {
            edges,
            first,
            spans,
        }
    }

    fn cells(&self) -> usize {
        self.edges.len() - 1
    }

    fn width(&self, i: usize) -> f64 {
        self.edges[i + 1] - self.edges[i]
    }

    /// The fine cell of coordinate `a` and the fraction of it below `a`, in O(1): the base interval,
    /// then the cell within it. The conversions go through `u32` (`max` maps a NaN to 0 first,
    /// a number past `u32::MAX` saturates to the last cell): between `f64` and `usize` they cost
    /// a dozen instructions each without AVX-512, a quarter of what this function cost.
    #[inline]
    fn locate(&self, a: f64) -> (usize, f64) {
        let x = (a + 1.0) / BASE_WIDTH;
        let b = (x.max(0.0) as u32).min(GUIDED_BASE_CELLS as u32 - 1);
        let (f0, cells) = self.spans[b as usize];
        let y = (x - f64::from(b)) * cells;
        let j = y.max(0.0).min(cells - 1.0) as u32;
        (f0 + j as usize, (y - f64::from(j)).clamp(0.0, 1.0))
    }

    fn cell(&self, a: f64) -> usize {
        self.locate(a).0
    }
}

/// The density `T(α, β)`, constant on each cell, as each column's running integral in `β`
/// (`T` is its difference over the cell's width, so the draw and the pdf read the same two
/// numbers), with its summed-area table (whose bilinear interpolation within a cell is `T`'s
/// exact integral from the corner `(−π/2, −π/2)`).
#[derive(Clone, Debug)]
pub struct GuidedTable {
    alpha: Axis,
    beta: Axis,
    /// `S[r·(A+1) + c]`: the integral of `T` over `α < edge c`, `β < edge r`, `A` the cells in
    /// `α` (row-major: the draw in `α` searches along rows).
    summed: Vec<f64>,
    /// `C[c·(B+1) + r]`: column `c`'s integral from `β = −1` to its edge `r`, `B` the cells
    /// in `β` (a column's are contiguous for the draw in `β`).
    column_cdf: Vec<f64>,
    /// Every [`STRIDE`]-th and [`STRIDE`]²-th entry of each row of `S` and of each column's
    /// `C`, contiguous, for the searches.
    summed_index: SearchIndex,
    column_index: SearchIndex,
}

/// Entries `k·STRIDE` (`fine`) and `k·STRIDE²` (`coarse`) of `lines` sequences of `len`
/// numbers each, stored contiguously per sequence: a search scans the coarse entries, then
/// the `STRIDE` fine ones of the block it found, then `STRIDE` of the sequence's own, so it
/// reads three or four cache lines per sequence, the loads of each scan independent of one
/// another, instead of a binary search's ten dependent ones (the table is megabytes, so the
/// loads miss the cache and their latency was most of a draw's cost).
#[derive(Clone, Debug)]
struct SearchIndex {
    fine: Vec<f64>,
    coarse: Vec<f64>,
    fine_len: usize,
    coarse_len: usize,
}

/// The search index's step: eight f64 are one 64-byte cache line.
const STRIDE: usize = 8;

impl SearchIndex {
    /// The index of `lines` sequences of `len` numbers, sequence `i` at `data[i·len..]`.
    fn new(data: &[f64], lines: usize, len: usize) -> Self {
        let fine_len = len.div_ceil(STRIDE);
        let coarse_len = len.div_ceil(STRIDE * STRIDE);
        let mut fine = Vec::with_capacity(lines * fine_len);
        let mut coarse = Vec::with_capacity(lines * coarse_len);
        for line in data.chunks_exact(len).take(lines) {
            fine.extend(line.iter().step_by(STRIDE));
            coarse.extend(line.iter().step_by(STRIDE * STRIDE));
        }
        SearchIndex {
            fine,
            coarse,
            fine_len,
            coarse_len,
        }
    }

    fn fine(&self, line: usize) -> &[f64] {
        &self.fine[line * self.fine_len..(line + 1) * self.fine_len]
    }

    fn coarse(&self, line: usize) -> &[f64] {
        &self.coarse[line * self.coarse_len..(line + 1) * self.coarse_len]
    }
}

/// A nondecreasing sequence that [`first_above`] reads. A trait with `#[inline(always)]`
/// reads rather than closures: closures cannot be marked so on stable, and LLVM left them out of
/// line (compiled for the baseline) inside the packet integrator's AVX2 function.
trait Ramp {
    fn at(&self, j: usize) -> f64;
}

impl Ramp for [f64] {
    #[inline(always)]
    fn at(&self, j: usize) -> f64 {
        self[j]
    }
}

impl<R: Ramp + ?Sized> Ramp for &R {
    #[inline(always)]
    fn at(&self, j: usize) -> f64 {
        (**self).at(j)
    }
}

/// The marginal `M` in `α` at column edge `c` over `β0 < β < β1`, from the summed-area rows
/// around `β0` and `β1` (`[s0, s0 + 1, s1, s1 + 1]`) and the fractions `g0`, `g1` of their
/// cells below `β0`, `β1`.
struct Marginal<'a> {
    rows: [&'a [f64]; 4],
    g: [f64; 2],
}

impl Ramp for Marginal<'_> {
    #[inline(always)]
    fn at(&self, c: usize) -> f64 {
        let [s0, s0n, s1, s1n] = self.rows;
        let [g0, g1] = self.g;
        (s1[c] + g1 * (s1n[c] - s1[c])) - (s0[c] + g0 * (s0n[c] - s0[c]))
    }
}

/// The first `j` in `from..len` with `value(j) > target` (`len` if none) for a nondecreasing
/// `value`, given it at every `STRIDE²`-th `j` (`coarse(k) = value(k·STRIDE²)`) and every
/// `STRIDE`-th (`fine(k) = value(k·STRIDE)`): three short scans, the first from the block of
/// `from` (a draw's answer lies within its box, so the scans skip the entries before it).
#[inline(always)]
fn first_above(
    target: f64,
    from: usize,
    len: usize,
    coarse: impl Ramp,
    fine: impl Ramp,
    value: impl Ramp,
) -> usize {
    if from >= len {
        return len;
    }
    let (coarse_len, fine_len) = (len.div_ceil(STRIDE * STRIDE), len.div_ceil(STRIDE));
    // Invariant: every `j` in `from..` below the scanned position has `value(j) <= target`.
    let mut b = from / (STRIDE * STRIDE);
    while b + 1 < coarse_len && coarse.at(b + 1) <= target {
        b += 1;
    }
    let mut m = (b * STRIDE).max(from / STRIDE);
    let fine_end = ((b + 1) * STRIDE).min(fine_len);
    while m + 1 < fine_end && fine.at(m + 1) <= target {
        m += 1;
    }
    let mut j = (m * STRIDE).max(from);
    let end = ((m + 1) * STRIDE).min(len);
    while j < end && value.at(j) <= target {
        j += 1;
    }
    j
}

/// The window's directions from one shading point, in `(α, β)`: a box, and the table's
/// integral over it (the normaliser of the guided density there).
#[derive(Clone, Copy, Debug)]
pub struct GuidedBox {
    pub(crate) alpha: [f64; 2],
    pub(crate) beta: [f64; 2],
    /// The cells of `α0`, `α1` and `β0`, `β1` and the fractions of them below the coordinates:
    /// found once per point, for `Z` and for every draw.
    alpha_cells: [(usize, f64); 2],
    beta_cells: [(usize, f64); 2],
    integral: f64,
    /// Whether the box reads the window's table of the sky without its sun
    /// ([`crate::light::window::Window::guided_box_split`]).
    pub(crate) sunless: bool,
}

impl GuidedBox {
    /// `Z(x)`: the table's integral over the box (the environment's weight through the
    /// window's bounding box, seen from x).
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// Whether the box reads the table of the environment without its sun.
    pub fn is_sunless(&self) -> bool {
        self.sunless
    }
}

/// `dω / (dα dβ)` at the gnomonic `a = gnomonic(α)`, `b = gnomonic(β)`: the gnomonic map's
/// `(1 + a² + b²)^(−3/2)` times `da/dα · db/dβ = (1 + |a|)² (1 + |b|)²`.
pub fn jacobian(a: f64, b: f64) -> f64 {
    let r2 = 1.0 + a * a + b * b;
    let (da, db) = (1.0 + a.abs(), 1.0 + b.abs());
    da * da * (db * db) / (r2 * r2.sqrt())
}

impl GuidedTable {
    /// `T` for `weight(direction(α, β)) · J(α, β)`, `weight` the environment's sampling weight:
    /// means of supersamples over 0.7° cells; the base intervals whose cells' supersamples
    /// spread most (a sun's edge) are refined; a fine cell takes the largest value on a grid
    /// over it where both of its axes are refined, else its supersamples along the whole axis.
    /// Floored at a millionth of the mean so that every direction through the window can be
    /// drawn.
    /// `direction(a, b)` is the unit direction at the gnomonic coordinates `a = gnomonic(α)`,
    /// `b = gnomonic(β)` (which also give the Jacobian; a base cell's 3 × 3 supersamples need
    /// six).
    /// Columns are filled in parallel (rayon): the table is rebuilt when a window turns.
    pub fn new(
        direction: impl Fn(f64, f64) -> Vec3 + Sync,
        weight: impl Fn(Vec3) -> f32 + Sync,
    ) -> Self {
        let n = GUIDED_BASE_CELLS;
        let value = |alpha: f64, beta: f64| {
            let (a, b) = (gnomonic(alpha), gnomonic(beta));
            let j = jacobian(a, b);
            // The grid's outer edges are edge-on directions, at infinity (`j` is NaN there).
            if j.is_finite() {
                f64::from(weight(direction(a, b))) * j
            } else {
                0.0
            }
        };
        // The base grid: means, and per base interval of each axis the mass its cells could
        // misplace: the spread of the environment's weight over a cell's supersamples times
        // the cell's mean Jacobian and area (the Jacobian is smooth: only jumps count).
        let k = SUPERSAMPLES;
        let mut base = vec![0.0; n * n];
        let mut misplaced = vec![0.0; n * n];
        let offsets: Vec<f64> = (0..k)
            .map(|i| (i as f64 + 0.5) / k as f64 * BASE_WIDTH)
            .collect();
        // The supersamples' gnomonic coordinates along either axis (the grid is the same in α
        // and β).
        let tangents: Vec<f64> = (0..n)
            .flat_map(|i| {
                let e0 = -1.0 + i as f64 * BASE_WIDTH;
                offsets.iter().map(move |o| gnomonic(e0 + o))
            })
            .collect();
        let columns = base.par_chunks_mut(n).zip(misplaced.par_chunks_mut(n));
        columns.enumerate().for_each(|(c, (base, misplaced))| {
            let ta = &tangents[c * k..(c + 1) * k];
            for r in 0..n {
                let tb = &tangents[r * k..(r + 1) * k];
                let (mut sum, mut sum_j, mut lo, mut hi) = (0.0, 0.0, f64::INFINITY, 0.0f64);
                for &a in ta {
                    for &b in tb {
                        let w = f64::from(weight(direction(a, b)));
                        let j = jacobian(a, b);
                        sum += w * j;
                        sum_j += j;
                        lo = lo.min(w);
                        hi = hi.max(w);
                    }
                }
                let samples = (k * k) as f64;
                base[r] = sum / samples;
                misplaced[r] = (hi - lo) * sum_j / samples * BASE_WIDTH * BASE_WIDTH;
            }
        });
        let (mut spread_alpha, mut spread_beta) = (vec![0.0; n], vec![0.0; n]);
        for (i, m) in misplaced.iter().enumerate() {
            spread_alpha[i / n] += m;
            spread_beta[i % n] += m;
        }
        let total: f64 = base.iter().sum::<f64>() * BASE_WIDTH * BASE_WIDTH;
        let alpha = Axis::new(&refined(&spread_alpha, total));
        let beta = Axis::new(&refined(&spread_beta, total));
        let (na, nb) = (alpha.cells(), beta.cells());
        let mut weights = vec![0.0; na * nb];
        weights
            .par_chunks_mut(nb)
            .enumerate()
            .for_each(|(c, column)| {
                let whole_c = alpha.width(c) > 0.5 * BASE_WIDTH;
                for (r, weight) in column.iter_mut().enumerate() {
                    let whole_r = beta.width(r) > 0.5 * BASE_WIDTH;
                    *weight = if whole_c && whole_r {
                        let (bc, br) = (alpha.base_of(c), beta.base_of(r));
                        base[bc * n + br]
                    } else if !whole_c && !whole_r {
                        // A fine cell where both axes jump (a sun's edge): the largest value on a
                        // 5 × 5 grid over the cell, its corners and sides included. A sun that
                        // the environment's pixels put over any part of the cell then sets its
                        // value (each pixel spans dozens of fine cells, so a part of one in a cell
                        // holds a corner or a stretch of side): a centre sample that missed it
                        // drew those sun directions at the sky's density, with weights a thousand
                        // times the mean. The cost is the cell's sky part drawn at the sun's
                        // density (zeros, half a fine cell wide around the sun on average).
                        let (a0, wa) = (alpha.edges[c], alpha.width(c));
                        let (b0, wb) = (beta.edges[r], beta.width(r));
                        let grid = (0..=EDGE_SAMPLES).map(|i| i as f64 / EDGE_SAMPLES as f64);
                        grid.clone()
                            .flat_map(|i| grid.clone().map(move |j| (i, j)))
                            .map(|(i, j)| value(a0 + i * wa, b0 + j * wb))
                            .fold(0.0, f64::max)
                    } else {
                        // A cell refined along one axis only: its supersamples along the other.
                        let along = |axis: &Axis, i: usize, whole: bool| -> Vec<f64> {
                            if whole {
                                offsets.iter().map(|o| axis.edges[i] + o).collect()
                            } else {
                                vec![0.5 * (axis.edges[i] + axis.edges[i + 1])]
                            }
                        };
                        let (pa, pb) = (along(&alpha, c, whole_c), along(&beta, r, whole_r));
                        let sum: f64 = pa
                            .iter()
                            .flat_map(|&a| pb.iter().map(move |&b| (a, b)))
                            .map(|(a, b)| value(a, b))
                            .sum();
                        sum / (pa.len() * pb.len()) as f64
                    };
                }
            });
        let mean = total / 4.0;
        let floor = if mean > 0.0 && mean.is_finite() {
            1e-6 * mean
        } else {
            1.0
        };
        for w in &mut weights {
            // Also replaces a NaN (`max` keeps the number).
            *w = w.max(floor);
        }
        let (ma, mb) = (na + 1, nb + 1);
        let mut column_cdf = vec![0.0; na * mb];
        let mut summed = vec![0.0; ma * mb];
        for c in 0..na {
            let wa = alpha.width(c);
            for r in 0..nb {
                column_cdf[c * mb + r + 1] =
                    column_cdf[c * mb + r] + weights[c * nb + r] * beta.width(r);
                summed[(r + 1) * ma + c + 1] =
                    summed[(r + 1) * ma + c] + column_cdf[c * mb + r + 1] * wa;
            }
        }
        GuidedTable {
            summed_index: SearchIndex::new(&summed, mb, ma),
            column_index: SearchIndex::new(&column_cdf, na, mb),
            alpha,
            beta,
            summed,
            column_cdf,
        }
    }

    /// `T` on cell `(c, r)`: the column's running integral over the cell, over its width.
    #[inline(always)]
    fn weight(&self, c: usize, r: usize) -> f64 {
        let at = c * (self.beta.cells() + 1) + r;
        (self.column_cdf[at + 1] - self.column_cdf[at]) / self.beta.width(r)
    }

    /// Cells per axis `(α, β)`.
    pub fn cells(&self) -> (usize, usize) {
        (self.alpha.cells(), self.beta.cells())
    }

    /// `T` at `(α, β)`.
    pub fn density(&self, alpha: f64, beta: f64) -> f64 {
        self.weight(self.alpha.cell(alpha), self.beta.cell(beta))
    }

    /// The integral of `T` over `[−1, α] × [−1, β]`: bilinear in the summed-area table,
    /// which is exact for a piecewise-constant density.
    pub fn integral_to(&self, alpha: f64, beta: f64) -> f64 {
        self.integral_at(self.alpha.locate(alpha), self.beta.locate(beta))
    }

    /// [`Self::integral_to`] at located coordinates: `(c, fa)` in `α`, `(r, fb)` in `β`.
    #[inline]
    fn integral_at(&self, (c, fa): (usize, f64), (r, fb): (usize, f64)) -> f64 {
        let m = self.alpha.edges.len();
        let k = r * m + c;
        // Slices of two, so that each row costs one bounds check.
        let (lo, hi) = (&self.summed[k..k + 2], &self.summed[k + m..k + m + 2]);
        let (s00, s10, s01, s11) = (lo[0], lo[1], hi[0], hi[1]);
        s00 + fa * (s10 - s00) + fb * (s01 - s00) + fa * fb * (s11 - s10 - s01 + s00)
    }

    /// The box `[α0, α1] × [β0, β1]` with its integral (`None` if it is empty).
    #[inline(always)]
    pub fn guided_box(&self, alpha: [f64; 2], beta: [f64; 2]) -> Option<GuidedBox> {
        let alpha_cells = alpha.map(|a| self.alpha.locate(a));
        let beta_cells = beta.map(|b| self.beta.locate(b));
        let [a0, a1] = alpha_cells;
        let [b0, b1] = beta_cells;
        let integral =
            self.integral_at(a1, b1) - self.integral_at(a0, b1) - self.integral_at(a1, b0)
                + self.integral_at(a0, b0);
        (integral > 0.0 && integral.is_finite()).then_some(GuidedBox {
            alpha,
            beta,
            alpha_cells,
            beta_cells,
            integral,
            sunless: false,
        })
    }

    /// Draws `(α, β)` in the box with density `T / Z`: the coordinates, and `T` there.
    #[inline(always)]
    pub fn sample(&self, b: &GuidedBox, u: [f64; 2]) -> Option<(f64, f64, f64)> {
        let (alpha, c) = self.sample_alpha(b, u[0])?;
        let (beta, r) = self.sample_beta(c, b, u[1])?;
        Some((alpha, beta, self.weight(c, r)))
    }

    /// Inverts the marginal CDF in `α` over the box's `β` range (piecewise linear, with a
    /// node at each column edge): a search along the summed-area table's rows at `β0` and
    /// `β1` ([`first_above`]), then a linear step within the column. The coordinate and its column.
    #[inline(always)]
    fn sample_alpha(&self, b: &GuidedBox, u: f64) -> Option<(f64, usize)> {
        let m = self.alpha.cells() + 1;
        let [(r0, g0), (r1, g1)] = b.beta_cells;
        // M at column edge c; the index's rows give it at every STRIDE-th and STRIDE²-th edge.
        let around = [r0, r0 + 1, r1, r1 + 1];
        let g = [g0, g1];
        let marginal = Marginal {
            rows: around.map(|r| &self.summed[r * m..(r + 1) * m]),
            g,
        };
        let fine = Marginal {
            rows: around.map(|r| self.summed_index.fine(r)),
            g,
        };
        let coarse = Marginal {
            rows: around.map(|r| self.summed_index.coarse(r)),
            g,
        };
        let [(c0, f0), (c1, _)] = b.alpha_cells;
        let at_start = marginal.at(c0) + f0 * (marginal.at(c0 + 1) - marginal.at(c0));
        let target = at_start + u * b.integral;
        // The first column in [c0, c1] whose upper edge's M passes the target (else c1).
        let above = first_above(target, c0 + 1, c1 + 2, coarse, fine, &marginal);
        let c = above.max(c0 + 1).min(c1 + 1) - 1;
        let (e0, width) = (self.alpha.edges[c], self.alpha.width(c));
        let (m0, m1) = (marginal.at(c), marginal.at(c + 1));
        let density = (m1 - m0) / width;
        if !(density > 0.0 && density.is_finite()) {
            return None;
        }
        let start = b.alpha[0].max(e0);
        let end = b.alpha[1].min(e0 + width).max(start);
        Some(((e0 + (target - m0) / density).clamp(start, end), c))
    }

    /// Inverts column `c`'s CDF in `β` within `[β0, β1]`: the coordinate and its row.
    #[inline(always)]
    fn sample_beta(&self, c: usize, b: &GuidedBox, u: f64) -> Option<(f64, usize)> {
        let (beta, [(r0, g0), (r1, g1)]) = (b.beta, b.beta_cells);
        let mb = self.beta.cells() + 1;
        let cdf = &self.column_cdf[c * mb..(c + 1) * mb];
        let f0 = cdf[r0] + g0 * (cdf[r0 + 1] - cdf[r0]);
        let f1 = cdf[r1] + g1 * (cdf[r1 + 1] - cdf[r1]);
        let target = f0 + u * (f1 - f0);
        // The first row in [r0, r1] whose upper edge's running integral passes the target
        // (else r1).
        let (fine, coarse) = (self.column_index.fine(c), self.column_index.coarse(c));
        let above = first_above(target, r0 + 1, r1 + 2, coarse, fine, cdf);
        let r = above.max(r0 + 1).min(r1 + 1) - 1;
        let e0 = self.beta.edges[r];
        let start = beta[0].max(e0);
        let end = beta[1].min(self.beta.edges[r + 1]).max(start);
        let weight = self.weight(c, r);
        // An `if`, not `bool::then` with a closure, which LLVM left out of line (see `Ramp`).
        if weight > 0.0 {
            Some(((e0 + (target - cdf[r]) / weight).clamp(start, end), r))
        } else {
            None
        }
    }
}

impl Axis {
    /// The base interval fine cell `i` lies in.
    fn base_of(&self, i: usize) -> usize {
        self.first.partition_point(|&f| f <= i) - 1
    }
}

/// Which base intervals to refine: those whose misplaceable mass exceeds [`REFINE_SHARE`] of
/// `total`, the [`MAX_REFINED`] largest at most, each widened by one interval on either side
/// (a jump that the supersamples of one cell missed shows in its neighbour's).
fn refined(spread: &[f64], total: f64) -> Vec<bool> {
    let mut order: Vec<usize> = (0..spread.len())
        .filter(|&i| spread[i] > REFINE_SHARE * total)
        .collect();
    order.sort_by(|&a, &b| spread[b].total_cmp(&spread[a]));
    order.truncate(MAX_REFINED);
    let mut fine = vec![false; spread.len()];
    for i in order {
        let end = (i + 2).min(spread.len());
        fine[i.saturating_sub(1)..end].fill(true);
    }
    fine
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    /// Directions of a window facing +z; a sun of 2.6° radius 1000 times as bright as the sky.
    fn table(sun_radiance: f32) -> GuidedTable {
        let sun = Vec3::new(0.2, 0.1, 1.0).normalize();
        GuidedTable::new(
            |a, b| Vec3::new(a as f32, b as f32, 1.0).normalize(),
            |w| {
                if w.dot(sun) > 0.045f32.cos() {
                    sun_radiance
                } else {
                    1.0
                }
            },
        )
    }

    fn overlap(lo: f64, hi: f64, e0: f64, e1: f64) -> f64 {
        (hi.min(e1) - lo.max(e0)).max(0.0)
    }

    #[test]
    fn refines_around_the_sun_only() {
        let t = table(1000.0);
        let (na, nb) = t.cells();
        let most = GUIDED_BASE_CELLS + (MAX_REFINED + 2) * (GUIDED_REFINE - 1);
        assert!(na > GUIDED_BASE_CELLS && na <= most, "{na} cells in α");
        assert!(nb > GUIDED_BASE_CELLS && nb <= most, "{nb} cells in β");
        // The sun's centre is in fine cells, a direction far from it in a whole one.
        let (sun_alpha, sun_beta) = (coordinate(0.2), coordinate(0.1));
        assert!(t.alpha.width(t.alpha.cell(sun_alpha)) < 0.5 * BASE_WIDTH);
        assert!(t.beta.width(t.beta.cell(sun_beta)) < 0.5 * BASE_WIDTH);
        assert!(t.alpha.width(t.alpha.cell(-0.6)) > 0.5 * BASE_WIDTH);
        // Without a jump nothing is refined.
        assert_eq!(table(1.0).cells(), (GUIDED_BASE_CELLS, GUIDED_BASE_CELLS));
        // Cells tile the axis, and `locate` finds the cell a coordinate lies in.
        for axis in [&t.alpha, &t.beta] {
            assert!(axis.edges.windows(2).all(|e| e[1] > e[0]));
            for i in (0..axis.cells()).step_by(7) {
                let mid = 0.5 * (axis.edges[i] + axis.edges[i + 1]);
                let (c, f) = axis.locate(mid);
                assert_eq!(c, i);
                assert!((f - 0.5).abs() < 1e-6, "fraction {f}");
            }
        }
    }

    /// The summed-area table's integral over a box equals the sum over cells of `T` times the
    /// cell's overlap with the box (exact but for rounding: 1e-9 relative). Negative case: the
    /// same sum with every cell taken as 0.7° wide (the uniform grid's widths) differs.
    #[test]
    fn box_integrals_are_exact_sums_over_cells() {
        let t = table(1000.0);
        let (na, nb) = t.cells();
        let mut rng = Rng::new(5, 0);
        let (sun_alpha, sun_beta) = (coordinate(0.2), coordinate(0.1));
        let mut wrong_widths_detected = false;
        for _ in 0..20 {
            // Boxes around the sun, of 0.02 to 0.27 sides (1.5° to 20°).
            let half = |r: f32| (0.01 + 0.25 * f64::from(r)) * 0.5 + 0.005;
            let (ha, hb) = (half(rng.uniform()), half(rng.uniform()));
            let shift = |r: f32| 0.05 * (f64::from(r) - 0.5);
            let ca = sun_alpha + shift(rng.uniform());
            let cb = sun_beta + shift(rng.uniform());
            let (alpha, beta) = ([ca - ha, ca + ha], [cb - hb, cb + hb]);
            let Some(b) = t.guided_box(alpha, beta) else {
                panic!("empty box {alpha:?} × {beta:?}");
            };
            let (mut sum, mut uniform_sum) = (0.0, 0.0);
            for c in 0..na {
                let (e0, e1) = (t.alpha.edges[c], t.alpha.edges[c + 1]);
                let oa = overlap(alpha[0], alpha[1], e0, e1);
                if oa == 0.0 {
                    continue;
                }
                for r in 0..nb {
                    let (f0, f1) = (t.beta.edges[r], t.beta.edges[r + 1]);
                    let ob = overlap(beta[0], beta[1], f0, f1);
                    let w = t.weight(c, r);
                    sum += w * oa * ob;
                    uniform_sum += w
                        * (oa / (e1 - e0)).min(1.0)
                        * BASE_WIDTH
                        * (ob / (f1 - f0)).min(1.0)
                        * BASE_WIDTH;
                }
            }
            let z = b.integral();
            assert!((z - sum).abs() <= 1e-9 * sum, "Z = {z}, Σ = {sum}");
            wrong_widths_detected |= (z - uniform_sum).abs() > 1e-3 * sum;
        }
        assert!(
            wrong_widths_detected,
            "uniform widths were never told apart"
        );
    }

    /// The three-scan search from `from` finds what a binary search over the whole sequence
    /// finds, raised to `from`, for every target between and beyond the values, sequence
    /// lengths around the strides, starts in every block, and runs of equal values. Negative
    /// case: an index of other values (the sequence halved) in front of the same last scan
    /// gives other answers.
    #[test]
    fn the_indexed_search_finds_the_first_value_above() {
        let mut rng = Rng::new(9, 0);
        let mut wrong_index_differs = false;
        for len in [1, 2, 7, 8, 9, 63, 64, 65, 200, 598] {
            // Nondecreasing, with runs of equal values.
            let mut values = Vec::with_capacity(len);
            let mut v = 0.0;
            for _ in 0..len {
                if rng.uniform() < 0.7 {
                    v += f64::from(rng.uniform());
                }
                values.push(v);
            }
            let index = SearchIndex::new(&values, 1, len);
            let (fine, coarse) = (index.fine(0), index.coarse(0));
            let halved: Vec<f64> = values.iter().map(|x| 0.5 * x).collect();
            let wrong = SearchIndex::new(&halved, 1, len);
            let starts = [0, 1, 7, 8, 9, 63, 64, 65, 130, len - 1, len, len + 3];
            for from in starts {
                // A shorter end too: the draws search up to their box's last cell.
                for end in [len, len.saturating_sub(5).max(1)] {
                    for t in 0..200 {
                        let target = -0.5 + (v + 1.0) * t as f64 / 199.0;
                        let below = values[..end].partition_point(|&x| x <= target);
                        let expected = below.max(from.min(end));
                        let found = first_above(target, from, end, coarse, fine, &values[..]);
                        assert_eq!(
                            found, expected,
                            "len {len}, from {from}, end {end}, {target}"
                        );
                        let (wf, wc) = (wrong.fine(0), wrong.coarse(0));
                        let misled = first_above(target, from, end, wc, wf, &values[..]);
                        wrong_index_differs |= misled != expected;
                    }
                }
            }
        }
        assert!(wrong_index_differs, "a wrong index was never told apart");
    }

    /// The draw as it was first written, the oracle for the faster one: every coordinate located
    /// again, and each search a binary search over the whole row or column.
    fn reference_sample(t: &GuidedTable, b: &GuidedBox, u: [f64; 2]) -> Option<(f64, f64, f64)> {
        let m = t.alpha.cells() + 1;
        let (r0, g0) = t.beta.locate(b.beta[0]);
        let (r1, g1) = t.beta.locate(b.beta[1]);
        let s = |r: usize, c: usize| t.summed[r * m + c];
        let marginal = |c: usize| {
            (s(r1, c) + g1 * (s(r1 + 1, c) - s(r1, c)))
                - (s(r0, c) + g0 * (s(r0 + 1, c) - s(r0, c)))
        };
        let (c0, f0) = t.alpha.locate(b.alpha[0]);
        let c1 = t.alpha.cell(b.alpha[1]);
        let target = marginal(c0) + f0 * (marginal(c0 + 1) - marginal(c0)) + u[0] * b.integral;
        let above = (0..m)
            .collect::<Vec<_>>()
            .partition_point(|&j| marginal(j) <= target);
        let c = above.max(c0 + 1).min(c1 + 1) - 1;
        let (e0, width) = (t.alpha.edges[c], t.alpha.width(c));
        let (m0, m1) = (marginal(c), marginal(c + 1));
        let density = (m1 - m0) / width;
        if !(density > 0.0 && density.is_finite()) {
            return None;
        }
        let start = b.alpha[0].max(e0);
        let end = b.alpha[1].min(e0 + width).max(start);
        let alpha = (e0 + (target - m0) / density).clamp(start, end);
        let mb = t.beta.cells() + 1;
        let cdf = &t.column_cdf[c * mb..(c + 1) * mb];
        let f = cdf[r0] + g0 * (cdf[r0 + 1] - cdf[r0]);
        let target = f + u[1] * (cdf[r1] + g1 * (cdf[r1 + 1] - cdf[r1]) - f);
        let r = cdf
            .partition_point(|&x| x <= target)
            .max(r0 + 1)
            .min(r1 + 1)
            - 1;
        let e0 = t.beta.edges[r];
        let start = b.beta[0].max(e0);
        let end = b.beta[1].min(t.beta.edges[r + 1]).max(start);
        let weight = t.weight(c, r);
        let beta = (e0 + (target - cdf[r]) / weight).clamp(start, end);
        (weight > 0.0).then_some((alpha, beta, weight))
    }

    /// The draw (boxes located once, searches from the box's first cell) returns bit for bit
    /// what the reference draw returns, for boxes of every size around and away from the sun
    /// and a sky without refinement; `Z` equals the four `integral_to` at the box's corners.
    /// Negative case: the draw given the cells of a box shifted by half a fine cell in `β` (stale
    /// located cells) returns other draws.
    #[test]
    fn draws_equal_the_reference_draws_bit_for_bit() {
        let mut rng = Rng::new(12, 0);
        let mut shifted_differs = false;
        for (t, centre) in [
            (table(1000.0), (coordinate(0.2), coordinate(0.1))),
            (table(1.0), (-0.7, 0.4)),
        ] {
            for _ in 0..60 {
                let half = |r: f32| 0.002 + 0.6 * f64::from(r).powi(2);
                let (ha, hb) = (half(rng.uniform()), half(rng.uniform()));
                let shift = |r: f32| 0.3 * (f64::from(r) - 0.5);
                let ca = centre.0 + shift(rng.uniform());
                let cb = centre.1 + shift(rng.uniform());
                let clip = |x: f64| x.clamp(-0.95, 0.95);
                let (alpha, beta) = (
                    [clip(ca - ha), clip(ca + ha)],
                    [clip(cb - hb), clip(cb + hb)],
                );
                let Some(b) = t.guided_box(alpha, beta) else {
                    panic!("empty box {alpha:?} × {beta:?}");
                };
                let z = t.integral_to(alpha[1], beta[1])
                    - t.integral_to(alpha[0], beta[1])
                    - t.integral_to(alpha[1], beta[0])
                    + t.integral_to(alpha[0], beta[0]);
                assert_eq!(b.integral().to_bits(), z.to_bits());
                let fine = 0.5 * BASE_WIDTH / GUIDED_REFINE as f64;
                let shifted = t.guided_box(alpha, [beta[0] + fine, beta[1] + fine]);
                for _ in 0..200 {
                    let v = rng.uniform2();
                    let u = [f64::from(v.x), f64::from(v.y)];
                    let got = t.sample(&b, u).map(|(a, c, w)| [a, c, w].map(f64::to_bits));
                    let want =
                        reference_sample(&t, &b, u).map(|(a, c, w)| [a, c, w].map(f64::to_bits));
                    assert_eq!(got, want, "box {alpha:?} × {beta:?}, u {u:?}");
                    if let Some(s) = &shifted {
                        // The box's own coordinates with the cells of the shifted box.
                        let stale = GuidedBox {
                            beta_cells: s.beta_cells,
                            ..b
                        };
                        let off = t
                            .sample(&stale, u)
                            .map(|(a, c, w)| [a, c, w].map(f64::to_bits));
                        shifted_differs |= off != want;
                    }
                }
            }
        }
        assert!(shifted_differs, "stale cells were never told apart");
    }

    /// No direction in the sun lies in a cell valued below the sun (such a cell would draw it
    /// at the sky's density, with a weight a thousand times the mean): for random directions
    /// around the sun, `T` of their cell is at least their own value (1 % slack for the
    /// Jacobian's change across a cell). Negative case: the value at the cell's centre, what
    /// a fine cell took before, is the sky's for some of them.
    #[test]
    fn no_sun_direction_lies_in_a_cell_valued_as_sky() {
        let t = table(1000.0);
        let sun = Vec3::new(0.2, 0.1, 1.0).normalize();
        let value = |a: f64, b: f64| {
            let w = Vec3::new(gnomonic(a) as f32, gnomonic(b) as f32, 1.0).normalize();
            let l = if w.dot(sun) > 0.045f32.cos() {
                1000.0
            } else {
                1.0
            };
            l * jacobian(gnomonic(a), gnomonic(b))
        };
        let (sun_alpha, sun_beta) = (coordinate(0.2), coordinate(0.1));
        let mut rng = Rng::new(8, 0);
        let (mut in_sun, mut centre_misses) = (0, 0);
        for _ in 0..200_000 {
            let a = sun_alpha + 0.1 * (f64::from(rng.uniform()) - 0.5);
            let b = sun_beta + 0.1 * (f64::from(rng.uniform()) - 0.5);
            let v = value(a, b);
            if v < 100.0 {
                continue;
            }
            in_sun += 1;
            assert!(
                t.density(a, b) >= 0.99 * v,
                "({a}, {b}): T {} < {v}",
                t.density(a, b)
            );
            let (c, r) = (t.alpha.cell(a), t.beta.cell(b));
            let centre = value(
                0.5 * (t.alpha.edges[c] + t.alpha.edges[c + 1]),
                0.5 * (t.beta.edges[r] + t.beta.edges[r + 1]),
            );
            centre_misses += usize::from(centre < 0.5 * v);
        }
        assert!(in_sun > 10_000, "{in_sun} directions in the sun");
        assert!(centre_misses > 0, "no cell centre missed the sun");
    }

    /// `locate` (conversions through `u32`) returns bit for bit what it returned with
    /// saturating conversions to `usize`, for coordinates across the axis, on and beside every
    /// cell edge, past both ends, infinite and NaN. Negative case: rounding `x` to the nearest
    /// base interval instead of down is told apart.
    #[test]
    fn locate_equals_the_saturating_reference() {
        let reference = |axis: &Axis, a: f64, round: bool| {
            let x = (a + 1.0) / BASE_WIDTH;
            let x = if round { x.round() } else { x };
            let b = (x.max(0.0) as usize).min(GUIDED_BASE_CELLS - 1);
            let (f0, f1) = (axis.first[b], axis.first[b + 1]);
            let y = (x - b as f64) * (f1 - f0) as f64;
            let j = (y.max(0.0) as usize).min(f1 - f0 - 1);
            (f0 + j, (y - j as f64).clamp(0.0, 1.0))
        };
        let t = table(1000.0);
        let mut rng = Rng::new(21, 0);
        let mut coordinates = vec![f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e300, -1e300];
        coordinates.extend((0..2000).map(|_| 2.4 * f64::from(rng.uniform()) - 1.2));
        let mut rounding_differs = false;
        for axis in [&t.alpha, &t.beta] {
            let beside =
                |e: f64| [-1i64, 0, 1].map(|d| f64::from_bits((e.to_bits() as i64 + d) as u64));
            let edges = axis.edges.iter().flat_map(|&e| beside(e));
            for a in coordinates.iter().copied().chain(edges) {
                let (c, f) = axis.locate(a);
                let (rc, rf) = reference(axis, a, false);
                assert_eq!((c, f.to_bits()), (rc, rf.to_bits()), "at {a}");
                rounding_differs |= reference(axis, a, true).0 != c;
            }
        }
        assert!(rounding_differs, "rounding was never told apart");
    }

    /// The coordinates are increasing and `gnomonic` inverts `coordinate`; `jacobian` is the
    /// solid angle of a small cell over its area in `(α, β)` (the cell's corners' spherical
    /// quadrilateral, to 1e-4). Negative case: the angles' Jacobian `(1 + a²)(1 + b²) / r³`
    /// is told apart.
    #[test]
    fn the_jacobian_is_the_solid_angle_per_coordinate_area() {
        use glam::DVec3;
        // Van Oosterom and Strackee's solid angle of the triangle of unit vectors p, q, r.
        let triangle = |p: DVec3, q: DVec3, r: DVec3| {
            let y = p.dot(q.cross(r)).abs();
            2.0 * y.atan2(1.0 + p.dot(q) + q.dot(r) + r.dot(p))
        };
        let direction =
            |alpha: f64, beta: f64| DVec3::new(gnomonic(alpha), gnomonic(beta), 1.0).normalize();
        let mut rng = Rng::new(22, 0);
        let mut angles_differ = false;
        let mut previous = f64::NEG_INFINITY;
        for k in 0..400 {
            let a = (f64::from(rng.uniform()) - 0.5) * 40.0;
            assert!(
                (gnomonic(coordinate(a)) - a).abs() <= 1e-12 * (1.0 + a.abs()),
                "{a}"
            );
            let u = -0.99 + 1.98 * k as f64 / 399.0;
            assert!(coordinate(gnomonic(u)) > previous, "not increasing at {u}");
            previous = coordinate(gnomonic(u));
            let (alpha, beta) = (
                1.9 * (f64::from(rng.uniform()) - 0.5),
                1.9 * (f64::from(rng.uniform()) - 0.5),
            );
            let d = 1e-5;
            let corners = [(0.0, 0.0), (d, 0.0), (d, d), (0.0, d)]
                .map(|(i, j)| direction(alpha - 0.5 * d + i, beta - 0.5 * d + j));
            let omega = triangle(corners[0], corners[1], corners[2])
                + triangle(corners[0], corners[2], corners[3]);
            let (ga, gb) = (gnomonic(alpha), gnomonic(beta));
            let j = jacobian(ga, gb);
            assert!(
                (omega / (d * d) - j).abs() <= 1e-4 * j,
                "({alpha}, {beta}): {} vs {j}",
                omega / (d * d)
            );
            let r2 = 1.0 + ga * ga + gb * gb;
            let angles = (1.0 + ga * ga) * (1.0 + gb * gb) / (r2 * r2.sqrt());
            angles_differ |= (angles - j).abs() > 1e-2 * j;
        }
        assert!(angles_differ, "the angles' Jacobian was never told apart");
    }

    /// Drawn coordinates stay in the box, and the reported `T` is the table's at them.
    #[test]
    fn draws_stay_in_the_box_and_report_their_cell() {
        let t = table(1000.0);
        let Some(b) = t.guided_box([0.1, 0.3], [0.0, 0.2]) else {
            panic!("empty box");
        };
        let mut rng = Rng::new(6, 0);
        let mut differing = 0;
        for _ in 0..20_000 {
            let u = rng.uniform2();
            let Some((a, c, w)) = t.sample(&b, [f64::from(u.x), f64::from(u.y)]) else {
                panic!("no draw at {u}");
            };
            assert!(
                (0.1..=0.3).contains(&a) && (0.0..=0.2).contains(&c),
                "({a}, {c})"
            );
            differing += usize::from(t.density(a, c) != w);
        }
        // Only a draw that rounds onto a cell edge may read the neighbouring cell.
        assert!(differing <= 20, "{differing} draws report another cell's T");
    }
}
