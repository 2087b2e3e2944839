//! portalview's own traversal layout over obvhs's tree. obvhs builds the tree and collapses it
//! to eight children per node (its CWBVH); each node is converted once into its eight children's
//! boxes as f32 in structure-of-arrays form. The boxes are the union of the triangles' own
//! bounds, widened only by the triangle test's rounding ([`pad`]; tighter than the CWBVH's
//! byte-quantised ones), so testing a node is six loads, six subtractions and six
//! multiplications for all eight children, with nothing to decode and no octant bookkeeping.
//!
//! Every traversal here gives an answer that does not depend on the order it visits nodes in:
//! occlusion is yes or no, and the closest hit is the least (distance, triangle) pair, ties
//! going to the lower triangle number. So the single-ray forms (any order, nearest child first)
//! and the packet forms (one order for eight rays) answer the same, bit for bit, and the scalar
//! and AVX2 forms too (they compute the same IEEE operations in the same order).

use glam::Vec3A;
use obvhs::{cwbvh::CwBvh, ray::Ray, triangle::Triangle};
use std::mem::MaybeUninit;

use super::RtTri;

/// Where a child word keeps a leaf's triangle count (0 for an inner node).
const COUNT_SHIFT: u32 = 29;
/// The most triangles the layout numbers (the first triangle of a leaf is below this).
pub const MAX_TRIANGLES: usize = 1 << COUNT_SHIFT;

/// Far distances, and the best distance a box is culled against, are scaled by this before
/// the comparison. pbrt's robust slab test (after Ize) scales by 1 + 2γ₃ so that rounding never
/// makes a ray miss a box it crosses; the margin here is wider (2⁻¹⁵, about 250 ulps) because
/// the triangle test's distances carry their own rounding: a ray through a vertex that several
/// triangles share gets distances to them a few ulps apart, and a box entered a few ulps
/// beyond the best so far may still hold the least pair (distance, triangle).
const FAR_SCALE: f32 = 1.0 + 1.0 / 32768.0;

/// Eight children's boxes, and what each child is.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
pub struct Node {
    /// The children's lower bounds along x, y and z (`bounds[0..3]`), then their upper bounds
    /// (`bounds[3..6]`); see [`Node::EMPTY`] for an empty slot's.
    bounds: [[f32; 8]; 6],
    /// Per child: an inner node's index, or a leaf's first triangle with its triangle count
    /// above [`COUNT_SHIFT`].
    child: [u32; 8],
}

impl Node {
    /// Every slot empty: lower bounds +∞ and upper bounds −∞, a box that every ray misses
    /// (whichever way it goes along an axis, it enters at +∞ and leaves at −∞, with no 0·∞).
    /// An empty slot's word is a leaf of triangle 0, harmless if it were ever entered.
    const EMPTY: Node = Node {
        bounds: [
            [f32::INFINITY; 8],
            [f32::INFINITY; 8],
            [f32::INFINITY; 8],
            [f32::NEG_INFINITY; 8],
            [f32::NEG_INFINITY; 8],
            [f32::NEG_INFINITY; 8],
        ],
        child: [1 << COUNT_SHIFT; 8],
    };
}

/// The converted tree: node 0 is the root.
pub struct WideBvh {
    nodes: Vec<Node>,
}

/// A box as its two corners.
type Bounds = (Vec3A, Vec3A);

impl WideBvh {
    /// The layout of `cwbvh`, whose primitive `i` is `triangles[i]` (after the reordering that
    /// makes `primitive_indices` the identity), node for node. The tree must be at most
    /// `super::MAX_CWBVH_DEPTH` levels deep (the conversion recurses once per level) and number
    /// fewer than [`MAX_TRIANGLES`] triangles.
    pub fn new(cwbvh: &CwBvh, triangles: &[Triangle]) -> WideBvh {
        let mut nodes = vec![Node::EMPTY; cwbvh.nodes.len()];
        if !nodes.is_empty() {
            convert(cwbvh, triangles, 0, &mut nodes);
        }
        WideBvh { nodes }
    }

    /// Moves every child box's faces inward by `fraction` of its size: a layout that misses
    /// rays grazing box faces, for the tests' negative case.
    #[cfg(test)]
    pub fn shrink(&mut self, fraction: f32) {
        for node in &mut self.nodes {
            for axis in 0..3 {
                for j in 0..8 {
                    let (lo, hi) = (node.bounds[axis][j], node.bounds[3 + axis][j]);
                    if lo.is_finite() && hi.is_finite() {
                        let inset = (hi - lo) * fraction;
                        node.bounds[axis][j] = lo + inset;
                        node.bounds[3 + axis][j] = hi - inset;
                    }
                }
            }
        }
    }

    /// Bytes the layout takes.
    pub fn bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<Node>()
    }

    /// The closest hit along `ray` among the triangles `intersect` tests (it returns the
    /// distance to triangle `id` within the ray's `[tmin, tmax]`, or infinity): the triangle
    /// and its distance, the least pair (distance, triangle) below `ray.tmax`, so `t` in
    /// `[tmin, tmax)`. Children, leaves among them, are visited nearest first, and those
    /// entered beyond the best so far skipped. Scalar node tests: see [`Self::closest_avx2`].
    #[inline(always)]
    pub fn closest(
        &self,
        ray: &Ray,
        intersect: impl FnMut(&Ray, usize) -> f32,
    ) -> Option<(u32, f32)> {
        self.walk_closest::<false>(ray, intersect)
    }

    /// [`Self::closest`] with the node tests in AVX2 registers.
    ///
    /// # Safety
    /// The CPU has AVX2.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    #[allow(unsafe_code)]
    pub unsafe fn closest_avx2(
        &self,
        ray: &Ray,
        intersect: impl FnMut(&Ray, usize) -> f32,
    ) -> Option<(u32, f32)> {
        self.walk_closest::<true>(ray, intersect)
    }

    /// [`Self::closest`]; with `AVX2`, only where the CPU has it (the two public functions
    /// above hold that contract).
    #[inline(always)]
    fn walk_closest<const AVX2: bool>(
        &self,
        ray: &Ray,
        mut intersect: impl FnMut(&Ray, usize) -> f32,
    ) -> Option<(u32, f32)> {
        let slabs = Slabs::<AVX2>::new(ray);
        let mut r = *ray;
        // The best so far: (r.tmax, best); (tmax, 0) accepts only distances below tmax.
        let (mut best, mut found) = (0u32, false);
        let mut stack = Stack::<(u32, f32)>::new();
        stack.push((0, ray.tmin));
        while let Some((word, t_entry)) = stack.pop() {
            if t_entry > r.tmax * FAR_SCALE {
                continue;
            }
            let count = word >> COUNT_SHIFT;
            if count != 0 {
                let first = word & (MAX_TRIANGLES as u32 - 1);
                for id in first..first + count {
                    let t = intersect(&r, id as usize);
                    if t < r.tmax || (t == r.tmax && id < best) {
                        (r.tmax, best, found) = (t, id, true);
                    }
                }
                continue;
            }
            let node = &self.nodes[word as usize];
            let (mut mask, t_near) = slabs.hits(node, r.tmax);
            let pushed = stack.len();
            while mask != 0 {
                let j = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                stack.push((node.child[j], t_near[j]));
            }
            stack.sort_nearest_on_top(pushed);
        }
        found.then_some((best, r.tmax))
    }

    /// A triangle on `ray` (one that `intersect` puts below `ray.tmax`: `t` in `[tmin,
    /// tmax)`), the first found. Inner children are visited farthest first: a shadow ray is
    /// most often blocked near the light it goes to (by the shade or the fixture around it),
    /// not near the point it leaves. A leaf's triangles are tested as soon as the leaf is
    /// entered (deferring them too tested the light's own leaf, at the far end of every
    /// shadow ray, first). Scalar node tests: see [`Self::any_avx2`].
    #[inline(always)]
    pub fn any(&self, ray: &Ray, intersect: impl FnMut(&Ray, usize) -> f32) -> Option<u32> {
        self.walk_any::<false>(ray, intersect)
    }

    /// [`Self::any`] with the node tests in AVX2 registers.
    ///
    /// # Safety
    /// The CPU has AVX2.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    #[allow(unsafe_code)]
    pub unsafe fn any_avx2(
        &self,
        ray: &Ray,
        intersect: impl FnMut(&Ray, usize) -> f32,
    ) -> Option<u32> {
        self.walk_any::<true>(ray, intersect)
    }

    /// [`Self::any`]; with `AVX2`, only where the CPU has it.
    #[inline(always)]
    fn walk_any<const AVX2: bool>(
        &self,
        ray: &Ray,
        mut intersect: impl FnMut(&Ray, usize) -> f32,
    ) -> Option<u32> {
        let slabs = Slabs::<AVX2>::new(ray);
        let mut stack = Stack::<(u32, f32)>::new();
        stack.push((0, 0.0));
        while let Some((word, _)) = stack.pop() {
            let node = &self.nodes[word as usize];
            let (mut mask, t_near) = slabs.hits(node, ray.tmax);
            let pushed = stack.len();
            while mask != 0 {
                let j = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let child = node.child[j];
                let count = child >> COUNT_SHIFT;
                if count == 0 {
                    stack.push((child, -t_near[j]));
                    continue;
                }
                let first = child & (MAX_TRIANGLES as u32 - 1);
                for id in first..first + count {
                    if intersect(ray, id as usize) < ray.tmax {
                        return Some(id);
                    }
                }
            }
            stack.sort_nearest_on_top(pushed);
        }
        None
    }

    /// [`Self::closest`] of each of `rays[..n]` through `triangles`, traced together: one walk
    /// whose stack entries carry the lanes (rays) that enter each child. Each ray tests the
    /// nodes it enters as it would alone and its triangles in lanes with the same operations,
    /// so each answer is its single ray's, bit for bit.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,bmi1,bmi2")]
    pub fn closest_packet(
        &self,
        triangles: &[RtTri],
        rays: &[Ray; PACKET],
        n: usize,
    ) -> [Option<(u32, f32)>; PACKET] {
        use std::arch::x86_64::*;
        let lanes = Lanes::new(rays);
        let slabs = rays.each_ref().map(Slabs::<true>::new);
        let mut tmax = lanes.tmax;
        let mut t = rays.map(|r| r.tmax);
        let mut best = _mm256_setzero_si256();
        // The farthest any lane still looks: a child entered beyond it by every lane is skipped.
        let mut reach = t.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b));
        let mut stack = Stack::<(u32, u32, f32)>::new();
        stack.push((0, (1u32 << n) - 1, rays[0].tmin));
        while let Some((word, active, t_entry)) = stack.pop() {
            if t_entry > reach * FAR_SCALE {
                continue;
            }
            let count = word >> COUNT_SHIFT;
            if count != 0 {
                let first = word & (MAX_TRIANGLES as u32 - 1);
                let active = lanes.mask(active);
                for id in first..first + count {
                    let (hit, t_hit) = lanes.triangle_hits(&triangles[id as usize], tmax, active);
                    let id = _mm256_set1_epi32(id as i32);
                    // (t, id) below (tmax, best): t < tmax, or t = tmax and id < best.
                    let closer = _mm256_or_ps(
                        _mm256_cmp_ps::<_CMP_LT_OQ>(t_hit, tmax),
                        _mm256_and_ps(
                            _mm256_cmp_ps::<_CMP_EQ_OQ>(t_hit, tmax),
                            _mm256_castsi256_ps(_mm256_cmpgt_epi32(best, id)),
                        ),
                    );
                    let take = _mm256_and_ps(hit, closer);
                    tmax = _mm256_blendv_ps(tmax, t_hit, take);
                    best = _mm256_blendv_epi8(best, id, _mm256_castps_si256(take));
                }
                // SAFETY: a 32-byte store into a 32-byte array.
                #[allow(unsafe_code)]
                unsafe {
                    _mm256_storeu_ps(t.as_mut_ptr(), tmax)
                };
                reach = t.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b));
                continue;
            }
            let node = &self.nodes[word as usize];
            // Byte j: the lanes that enter child j; `order[j]`: the least distance at which a
            // lane enters it (a bound, and the order children are visited in).
            let mut entered = 0u64;
            let mut order = _mm256_set1_ps(f32::INFINITY);
            let mut r = active;
            while r != 0 {
                let i = r.trailing_zeros() as usize;
                r &= r - 1;
                let (hit, t_near) = slabs[i].hits(node, t[i]);
                // SAFETY: an unaligned 32-byte load from a 32-byte array.
                #[allow(unsafe_code)]
                let t_near = unsafe { _mm256_loadu_ps(t_near.as_ptr()) };
                order = _mm256_min_ps(order, t_near);
                entered |= _pdep_u64(hit as u64, 0x0101_0101_0101_0101) << i;
            }
            let mut t_order = [0f32; 8];
            // SAFETY: a 32-byte store into a 32-byte array.
            #[allow(unsafe_code)]
            unsafe {
                _mm256_storeu_ps(t_order.as_mut_ptr(), order)
            };
            let pushed = stack.len();
            while entered != 0 {
                let j = (entered.trailing_zeros() / 8) as usize;
                let rays_in = (entered >> (8 * j)) as u32 & 0xff;
                entered &= !(0xff << (8 * j));
                stack.push((node.child[j], rays_in, t_order[j]));
            }
            stack.sort_nearest_on_top_by(pushed, |e| e.2);
        }
        let mut id = [0u32; PACKET];
        // SAFETY: a 32-byte store into a 32-byte array.
        #[allow(unsafe_code)]
        unsafe {
            _mm256_storeu_si256(id.as_mut_ptr() as *mut __m256i, best)
        };
        // A lane whose distance never shrank found nothing.
        std::array::from_fn(|i| (i < n && t[i] < rays[i].tmax).then_some((id[i], t[i])))
    }

    /// Whether each of `rays[..n]` meets one of `triangles` below its `tmax` ([`Self::any`]),
    /// traced together (bit `i` of the first number), and the last triangle found to block a
    /// ray. Triangle `guess` (if it is one) is tested on every ray first; a ray leaves the
    /// packet at its first hit.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,bmi1,bmi2")]
    pub fn any_packet(
        &self,
        triangles: &[RtTri],
        rays: &[Ray; PACKET],
        n: usize,
        guess: u32,
    ) -> (u32, Option<u32>) {
        use std::arch::x86_64::*;
        let lanes = Lanes::new(rays);
        let all = (1u32 << n) - 1;
        let mut blocked = 0u32;
        let mut blocker = None;
        let mut block = |id: u32, open: u32, blocked: &mut u32| {
            let (hit, t_hit) =
                lanes.triangle_hits(&triangles[id as usize], lanes.tmax, lanes.mask(open));
            let below = _mm256_and_ps(hit, _mm256_cmp_ps::<_CMP_LT_OQ>(t_hit, lanes.tmax));
            let found = _mm256_movemask_ps(below) as u32 & open;
            if found != 0 {
                *blocked |= found;
                blocker = Some(id);
            }
        };
        if (guess as usize) < triangles.len() {
            block(guess, all, &mut blocked);
            if blocked == all {
                return (all, blocker);
            }
        }
        let slabs = rays.each_ref().map(Slabs::<true>::new);
        let mut stack = Stack::<(u32, u32, f32)>::new();
        stack.push((0, all, 0.0));
        while let Some((word, active, _)) = stack.pop() {
            let active = active & !blocked;
            if active == 0 {
                continue;
            }
            let node = &self.nodes[word as usize];
            // Byte j: the lanes that enter child j. The first lane's distances order them.
            let (mut entered, mut order) = (0u64, [0f32; 8]);
            let mut r = active;
            while r != 0 {
                let i = r.trailing_zeros() as usize;
                let (hit, t_near) = slabs[i].hits(node, rays[i].tmax);
                if r == active {
                    order = t_near;
                }
                r &= r - 1;
                entered |= _pdep_u64(hit as u64, 0x0101_0101_0101_0101) << i;
            }
            let pushed = stack.len();
            while entered != 0 {
                let j = (entered.trailing_zeros() / 8) as usize;
                let rays_in = (entered >> (8 * j)) as u32 & 0xff;
                entered &= !(0xff << (8 * j));
                let child = node.child[j];
                let count = child >> COUNT_SHIFT;
                if count == 0 {
                    // Farthest first, as in `any`.
                    stack.push((child, rays_in, -order[j]));
                    continue;
                }
                let first = child & (MAX_TRIANGLES as u32 - 1);
                for id in first..first + count {
                    let open = rays_in & !blocked;
                    if open == 0 {
                        break;
                    }
                    block(id, open, &mut blocked);
                }
                if blocked & all == all {
                    return (all, blocker);
                }
            }
            stack.sort_nearest_on_top_by(pushed, |e| e.2);
        }
        (blocked & all, blocker)
    }
}

/// Converts CWBVH node `i` into `nodes[i]`, its children first, and returns its box.
fn convert(cwbvh: &CwBvh, triangles: &[Triangle], i: usize, nodes: &mut [Node]) -> Bounds {
    let empty = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
    let Some(source) = cwbvh.nodes.get(i) else {
        return empty;
    };
    let mut node = Node::EMPTY;
    let mut bounds = empty;
    for j in 0..8 {
        if source.is_child_empty(j) {
            continue;
        }
        let (lo, hi, word) = if source.is_leaf(j) {
            let (first, count) = source.child_primitives(j);
            let (mut lo, mut hi) = empty;
            for t in triangles.iter().skip(first as usize).take(count as usize) {
                for v in [t.v0, t.v1, t.v2] {
                    (lo, hi) = (lo.min(v), hi.max(v));
                }
            }
            let (lo, hi) = pad(lo, hi);
            (lo, hi, first | count << COUNT_SHIFT)
        } else {
            let k = source.child_node_index(j);
            let (lo, hi) = convert(cwbvh, triangles, k as usize, nodes);
            (lo, hi, k)
        };
        for axis in 0..3 {
            node.bounds[axis][j] = lo[axis];
            node.bounds[3 + axis][j] = hi[axis];
        }
        node.child[j] = word;
        bounds = (bounds.0.min(lo), bounds.1.max(hi));
    }
    if let Some(slot) = nodes.get_mut(i) {
        *slot = node;
    }
    bounds
}

/// A leaf's box, widened so that it holds every point where the triangle test (with its own
/// rounding) says a ray meets one of its triangles: a ray that grazes a triangle's edge is
/// accepted a few ulps outside the exact triangle, and so outside its exact box. By 1/4096 of
/// the box's extent and 8 ulps of its coordinates, on each side (obvhs's byte-quantised boxes
/// are larger still, up to 1/255 of the parent's extent).
pub(super) fn pad(lo: Vec3A, hi: Vec3A) -> Bounds {
    let margin = (hi - lo) * (1.0 / 4096.0);
    let ulps = 1.0 / (1 << 20) as f32;
    (lo - margin - lo.abs() * ulps, hi + margin + hi.abs() * ulps)
}

/// The most rays traced together: one per lane of an AVX2 register.
pub const PACKET: usize = 8;

/// `_mm256_max_ps` on one lane: `a` if `a > b`, else `b`.
#[inline(always)]
fn max_ps(a: f32, b: f32) -> f32 {
    if a > b { a } else { b }
}

/// `_mm256_min_ps` on one lane: `a` if `a < b`, else `b`.
#[inline(always)]
fn min_ps(a: f32, b: f32) -> f32 {
    if a < b { a } else { b }
}

/// A ray prepared for the slab test of a node's eight children, all eight at once in AVX2
/// registers (`AVX2`) or one by one as scalars, with the same IEEE operations in the same order.
#[derive(Clone, Copy)]
struct Slabs<const AVX2: bool> {
    origin: [f32; 3],
    inv_direction: [f32; 3],
    /// Per axis, the row of `Node::bounds` that is entered first (the lower bound unless the
    /// ray goes toward negative values), and then the one left.
    near: [usize; 3],
    far: [usize; 3],
    tmin: f32,
}

impl<const AVX2: bool> Slabs<AVX2> {
    #[inline(always)]
    fn new(ray: &Ray) -> Self {
        let d = ray.direction.to_array();
        // The exact inverse, infinite for a zero component (obvhs's `safe_inverse` makes it
        // 1/ε, finite: a ray along a box's face would then leave the box at once).
        let inv_direction = d.map(|c| 1.0 / c);
        // The near face by the inverse's sign, which is the direction's sign bit, zeros
        // included: −0.0 has the inverse −∞, so its near face is the upper one (chosen by
        // `d < 0`, it would be the lower, and a ray inside the slab would miss the box). Read
        // from the sign bit, not from the inverse, so that it need not wait for the division.
        let near = [0, 1, 2].map(|k| if d[k].is_sign_negative() { 3 + k } else { k });
        Slabs {
            origin: ray.origin.to_array(),
            inv_direction,
            near,
            far: near.map(|row| (row + 3) % 6),
            tmin: ray.tmin,
        }
    }

    /// Bit `j` set where the ray, within `[tmin, tmax]`, enters the box of child `j`, and the
    /// distances at which it enters each. A ray with a zero direction component that lies on
    /// one of a box's planes along it gets 0·∞ = NaN there: each slab distance is the first
    /// operand of `max`/`min`, which then return the second, so that plane is ignored (the ray
    /// stays within the closed slab).
    #[inline(always)]
    fn hits(&self, node: &Node, tmax: f32) -> (u32, [f32; 8]) {
        #[cfg(target_arch = "x86_64")]
        if AVX2 {
            // SAFETY: `Slabs<true>` is made only by `walk_closest::<true>` and
            // `walk_any::<true>`, reached only through `closest_avx2` and `any_avx2`, whose
            // callers guarantee AVX2.
            #[allow(unsafe_code)]
            return unsafe { self.hits_avx2(node, tmax) };
        }
        let mut mask = 0;
        let mut t_near = [0.0; 8];
        let (o, inv) = (self.origin, self.inv_direction);
        for (j, t) in t_near.iter_mut().enumerate() {
            let slab = |k: usize, row: usize| (node.bounds[row][j] - o[k]) * inv[k];
            let (near, far) = (self.near, self.far);
            let t0 = max_ps(
                slab(2, near[2]),
                max_ps(slab(1, near[1]), max_ps(slab(0, near[0]), self.tmin)),
            );
            let t1 = min_ps(
                slab(2, far[2]),
                min_ps(slab(1, far[1]), min_ps(slab(0, far[0]), tmax)),
            ) * FAR_SCALE;
            *t = t0;
            mask |= u32::from(t0 <= t1) << j;
        }
        (mask, t_near)
    }

    /// [`Self::hits`] for all eight children in AVX2 registers. Not a `target_feature`
    /// function, which the compiler would not always inline: it is inlined into the AVX2
    /// traversals, and its intrinsics with it.
    ///
    /// # Safety
    /// The CPU has AVX2.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    #[allow(unsafe_code)]
    unsafe fn hits_avx2(&self, node: &Node, tmax: f32) -> (u32, [f32; 8]) {
        use std::arch::x86_64::*;
        // SAFETY: the caller's CPU has AVX2; 32-byte loads from rows of eight f32 (a node is
        // 32-byte aligned) and a 32-byte store into a 32-byte array.
        unsafe {
            let slab = |k: usize, r: usize| {
                _mm256_mul_ps(
                    _mm256_sub_ps(
                        _mm256_load_ps(node.bounds[r].as_ptr()),
                        _mm256_set1_ps(self.origin[k]),
                    ),
                    _mm256_set1_ps(self.inv_direction[k]),
                )
            };
            let (near, far) = (self.near, self.far);
            let t0 = _mm256_max_ps(
                slab(2, near[2]),
                _mm256_max_ps(
                    slab(1, near[1]),
                    _mm256_max_ps(slab(0, near[0]), _mm256_set1_ps(self.tmin)),
                ),
            );
            let t1 = _mm256_min_ps(
                slab(2, far[2]),
                _mm256_min_ps(
                    slab(1, far[1]),
                    _mm256_min_ps(slab(0, far[0]), _mm256_set1_ps(tmax)),
                ),
            );
            let t1 = _mm256_mul_ps(t1, _mm256_set1_ps(FAR_SCALE));
            let mask = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t0, t1)) as u32;
            let mut t_near = [0.0; 8];
            _mm256_storeu_ps(t_near.as_mut_ptr(), t0);
            (mask, t_near)
        }
    }
}

/// The rays of a packet, one per lane, as [`RtTri::uvt`] reads them.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Lanes {
    origin: [std::arch::x86_64::__m256; 3],
    direction: [std::arch::x86_64::__m256; 3],
    tmin: std::arch::x86_64::__m256,
    tmax: std::arch::x86_64::__m256,
}

#[cfg(target_arch = "x86_64")]
impl Lanes {
    #[target_feature(enable = "avx2")]
    #[inline]
    fn new(rays: &[Ray; PACKET]) -> Self {
        use std::arch::x86_64::*;
        let lane = |f: fn(&Ray) -> f32| {
            let v = rays.each_ref().map(f);
            _mm256_setr_ps(v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7])
        };
        Lanes {
            origin: [
                lane(|r| r.origin.x),
                lane(|r| r.origin.y),
                lane(|r| r.origin.z),
            ],
            direction: [
                lane(|r| r.direction.x),
                lane(|r| r.direction.y),
                lane(|r| r.direction.z),
            ],
            tmin: lane(|r| r.tmin),
            tmax: lane(|r| r.tmax),
        }
    }

    /// All bits set in the lanes of `bits`.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn mask(&self, bits: u32) -> std::arch::x86_64::__m256 {
        use std::arch::x86_64::*;
        let lane_bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        let r = _mm256_set1_epi32(bits as i32);
        _mm256_castsi256_ps(_mm256_cmpeq_epi32(
            _mm256_and_si256(r, lane_bits),
            lane_bits,
        ))
    }

    /// The lanes of `active` whose rays meet `tri` at a distance in `[tmin, tmax]`, and the
    /// distances: [`RtTri::intersect`] lane by lane, with glam's SSE2 operations for `cross`
    /// and `dot` in their order (`(x + y) + z`; `a.y·b.z - a.z·b.y`), so the same answer bit
    /// for bit.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn triangle_hits(
        &self,
        tri: &RtTri,
        tmax: std::arch::x86_64::__m256,
        active: std::arch::x86_64::__m256,
    ) -> (std::arch::x86_64::__m256, std::arch::x86_64::__m256) {
        use std::arch::x86_64::*;
        let splat = |v: Vec3A| v.to_array().map(|x| _mm256_set1_ps(x));
        let (v0, e1, e2, ng) = (splat(tri.v0), splat(tri.e1), splat(tri.e2), splat(tri.ng));
        let (mul, sub, add) = (_mm256_mul_ps, _mm256_sub_ps, _mm256_add_ps);
        let dot = |a: [__m256; 3], b: [__m256; 3]| {
            add(add(mul(a[0], b[0]), mul(a[1], b[1])), mul(a[2], b[2]))
        };
        let (o, d) = (self.origin, self.direction);
        let c = [sub(v0[0], o[0]), sub(v0[1], o[1]), sub(v0[2], o[2])];
        let r = [
            sub(mul(d[1], c[2]), mul(d[2], c[1])),
            sub(mul(d[2], c[0]), mul(d[0], c[2])),
            sub(mul(d[0], c[1]), mul(d[1], c[0])),
        ];
        let inv_det = _mm256_div_ps(_mm256_set1_ps(1.0), dot(ng, d));
        let u = mul(dot(r, e2), inv_det);
        let v = mul(dot(r, e1), inv_det);
        let t = mul(dot(ng, c), inv_det);
        let zero = _mm256_setzero_ps();
        let inside = _mm256_and_ps(
            _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GE_OQ>(u, zero),
                _mm256_cmp_ps::<_CMP_GE_OQ>(v, zero),
            ),
            _mm256_cmp_ps::<_CMP_LE_OQ>(add(u, v), _mm256_set1_ps(1.0)),
        );
        let within = _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_GE_OQ>(t, self.tmin),
            _mm256_cmp_ps::<_CMP_LE_OQ>(t, tmax),
        );
        (_mm256_and_ps(_mm256_and_ps(inside, within), active), t)
    }
}

/// Deep enough for any tree converted here: at most seven children wait per level, and a tree
/// is at most `MAX_CWBVH_DEPTH` (31) levels deep (the build refuses deeper ones).
const STACK: usize = 256;
const _: () = assert!(7 * (super::MAX_CWBVH_DEPTH as usize) < STACK);

/// A traversal stack that is not zeroed for every ray (2 KB of stores would cost more than
/// a shadow ray's node tests).
struct Stack<T: Copy> {
    entries: [MaybeUninit<T>; STACK],
    len: usize,
}

impl<T: Copy> Stack<T> {
    #[inline(always)]
    fn new() -> Self {
        Stack {
            entries: [const { MaybeUninit::uninit() }; STACK],
            len: 0,
        }
    }

    #[inline(always)]
    fn len(&self) -> usize {
        self.len
    }

    /// Pushes `entry`. A tree the build accepts never fills the stack (`STACK`'s assertion);
    /// were it full, the entry would be dropped rather than written out of bounds, which a
    /// debug build reports.
    #[inline(always)]
    fn push(&mut self, entry: T) {
        debug_assert!(self.len < STACK, "a traversal stack of {STACK} is full");
        if let Some(slot) = self.entries.get_mut(self.len) {
            slot.write(entry);
            self.len += 1;
        }
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<T> {
        self.len = self.len.checked_sub(1)?;
        // SAFETY: entries below `len` were written by `push`.
        #[allow(unsafe_code)]
        Some(unsafe { self.entries[self.len].assume_init() })
    }

    /// Orders the entries pushed since length `from` so that the nearest (least `key`) is
    /// popped first: an insertion sort, as they are at most eight and mostly one or two.
    #[inline(always)]
    fn sort_nearest_on_top_by(&mut self, from: usize, key: impl Fn(&T) -> f32) {
        for i in from + 1..self.len {
            // SAFETY: entries below `len` were written by `push`.
            #[allow(unsafe_code)]
            let entry = unsafe { self.entries[i].assume_init() };
            let mut k = i;
            #[allow(unsafe_code)]
            while k > from && key(unsafe { self.entries[k - 1].assume_init_ref() }) < key(&entry) {
                self.entries[k] = self.entries[k - 1];
                k -= 1;
            }
            self.entries[k].write(entry);
        }
    }
}

impl Stack<(u32, f32)> {
    #[inline(always)]
    fn sort_nearest_on_top(&mut self, from: usize) {
        self.sort_nearest_on_top_by(from, |e| e.1);
    }
}
