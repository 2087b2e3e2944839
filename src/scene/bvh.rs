//! The acceleration structure: an obvhs CWBVH over every triangle, with triangles reordered
//! once into BVH order so traversal reads them sequentially.

use glam::{UVec2, Vec2, Vec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    bvh2::{Bvh2, reinsertion::ReinsertionOptimizer},
    cwbvh::{CwBvh, bvh2_to_cwbvh::bvh2_to_cwbvh, node::CwBvhNode},
    ploc::PlocBuilder,
    ray::{Ray, RayHit},
    triangle::Triangle,
};
use std::cell::Cell;
use std::collections::HashMap;

use crate::isa::Isa;
use crate::surface::SurfaceTextures;

/// A triangle laid out for intersection (obvhs's `RtTriangle` layout), with a Möller–Trumbore
/// test whose inside check accepts -0.0: obvhs's sign-bit test rejects it, so a ray exactly on
/// the shared diagonal of a quad would slip between its two triangles.
#[derive(Clone, Copy, Debug)]
struct RtTri {
    v0: Vec3A,
    e1: Vec3A,
    e2: Vec3A,
    ng: Vec3A,
}

impl RtTri {
    fn new(t: &Triangle) -> Self {
        let (e1, e2) = (t.v0 - t.v1, t.v2 - t.v0);
        RtTri {
            v0: t.v0,
            e1,
            e2,
            ng: e1.cross(e2),
        }
    }

    /// (u, v, t) of the hit, the hit point being `(1-u-v)·v0 + u·v1 + v·v2`.
    #[inline(always)]
    fn uvt(&self, ray: &Ray) -> (f32, f32, f32) {
        let c = self.v0 - ray.origin;
        let r = ray.direction.cross(c);
        let inv_det = 1.0 / self.ng.dot(ray.direction);
        (
            r.dot(self.e2) * inv_det,
            r.dot(self.e1) * inv_det,
            self.ng.dot(c) * inv_det,
        )
    }

    /// Distance along the ray, or infinity for a miss.
    #[inline(always)]
    fn intersect(&self, ray: &Ray) -> f32 {
        let (u, v, t) = self.uvt(ray);
        if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t >= ray.tmin && t <= ray.tmax {
            t
        } else {
            f32::INFINITY
        }
    }
}

/// The closest intersection along a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    /// Index of the triangle in the scene's order.
    pub triangle: u32,
    /// Barycentric coordinates of the hit for vertices 1 and 2.
    pub bary: Vec2,
}

/// obvhs 0.4 misses every node when a direction component is -0.0 (its octant and inverse
/// direction disagree), so a ray straight down `-Y` would pass through the floor; adding +0.0
/// turns -0.0 into +0.0 and leaves every other value alone.
#[inline(always)]
fn make_ray(origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Ray {
    Ray::new(origin.into(), (dir + Vec3::ZERO).into(), tmin, tmax)
}

/// obvhs's lower bound on a child's entry distance (`cwbvh::node::EPSILON`, crate-private).
/// Its own node test enters no child nearer than this, absolute: a ray that starts within
/// 1e-4 of a wall and heads into it would pass through. The node tests here bound the entry
/// distance by the ray's own `tmin` instead; they agree with obvhs's for rays whose `tmin` is
/// this (the tests compare them so).
#[cfg(test)]
const NODE_EPSILON: f32 = 0.0001;

/// The children of `node` that `ray` enters, as obvhs's traversal wants them: obvhs's node
/// test (`CwBvhNode::intersect_ray_basic`) with the entry distance bounded by `ray.tmin`
/// rather than obvhs's absolute 1e-4, or, where the CPU has AVX2, [`node_hits_avx2`], which
/// gives the same mask.
#[inline(always)]
#[allow(unsafe_code)]
fn node_hits(isa: Isa, node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
    match isa {
        // SAFETY: a BVH's `isa` is `Isa::detect()`, which is `Avx2` only where the CPU has it.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { node_hits_avx2(node, ray, oct_inv4) },
        _ => node_hits_scalar(node, ray, oct_inv4),
    }
}

/// obvhs's `intersect_ray_basic`, child by child, with the entry distance bounded by
/// `ray.tmin`: the same IEEE operations as [`child_hits_avx2`], so the same mask.
#[inline(always)]
fn node_hits_scalar(node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
    let dir_inv = node.compute_extent() * ray.inv_direction;
    let origin = (Vec3A::from(node.p) - ray.origin) * ray.inv_direction;
    let d = ray.direction;
    let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
    let mut mask = 0;
    for j in 0..8 {
        let lo = Vec3A::new(
            node.child_min_x[j] as f32,
            node.child_min_y[j] as f32,
            node.child_min_z[j] as f32,
        );
        let hi = Vec3A::new(
            node.child_max_x[j] as f32,
            node.child_max_y[j] as f32,
            node.child_max_z[j] as f32,
        );
        let near = Vec3A::select(d.cmplt(Vec3A::ZERO), hi, lo);
        let far = Vec3A::select(d.cmplt(Vec3A::ZERO), lo, hi);
        let t_near = near * dir_inv + origin;
        let t_far = far * dir_inv + origin;
        let tmin = t_near.x.max(t_near.y.max(t_near.z)).max(ray.tmin);
        let tmax = t_far.x.min(t_far.y.min(t_far.z)).min(ray.tmax);
        if tmin <= tmax {
            let shift = j as u32 * 8;
            mask |= ((child_bits8 >> shift) as u32 & 0xff) << ((bit_index8 >> shift) as u32 & 0xff);
        }
    }
    mask
}

/// obvhs's `CwBvhNode::intersect_ray` (its SSE `intersect_ray_simd`) in AVX2: all eight
/// children in one register, their byte-quantised bounds widened by two instructions instead of
/// 48 scalar conversions. The same IEEE operations in the same order (multiply, then add, never
/// fused; `max`/`min` with the same operand order), so the same mask, bit for bit
/// (`avx2_node_test_agrees_with_obvhs`). Node tests were a fifth of a light sample's
/// instructions in fig8b; this form takes 8% of that sample's instructions away.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn node_hits_avx2(node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
    let mut hit = child_hits_avx2(node, ray, ray.tmax);
    let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
    let mut mask = 0;
    while hit != 0 {
        let j = hit.trailing_zeros() * 8;
        hit &= hit - 1;
        mask |= ((child_bits8 >> j) as u32 & 0xff) << ((bit_index8 >> j) as u32 & 0xff);
    }
    mask
}

/// Bit `j` set where `ray`, up to `tmax`, enters the box of child `j` of `node` (the slab test
/// of [`node_hits_avx2`], before it maps children to obvhs's hit mask).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn child_hits_avx2(node: &CwBvhNode, ray: &Ray, tmax: f32) -> u32 {
    use std::arch::x86_64::*;
    let dir_inv = node.compute_extent() * ray.inv_direction;
    let origin = (Vec3A::from(node.p) - ray.origin) * ray.inv_direction;
    // SAFETY: an 8-byte load from an 8-byte array.
    #[allow(unsafe_code)]
    let bytes = |v: &[u8; 8]| unsafe {
        _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_loadl_epi64(
            v.as_ptr() as *const __m128i
        )))
    };
    let slab = |lo: &[u8; 8], hi: &[u8; 8], negative: bool, inv: f32, o: f32| {
        let (lo, hi) = (bytes(lo), bytes(hi));
        let (near, far) = if negative { (hi, lo) } else { (lo, hi) };
        let (inv, o) = (_mm256_set1_ps(inv), _mm256_set1_ps(o));
        (
            _mm256_add_ps(_mm256_mul_ps(near, inv), o),
            _mm256_add_ps(_mm256_mul_ps(far, inv), o),
        )
    };
    let d = ray.direction;
    let (tmin_x, tmax_x) = slab(
        &node.child_min_x,
        &node.child_max_x,
        d.x < 0.0,
        dir_inv.x,
        origin.x,
    );
    let (tmin_y, tmax_y) = slab(
        &node.child_min_y,
        &node.child_max_y,
        d.y < 0.0,
        dir_inv.y,
        origin.y,
    );
    let (tmin_z, tmax_z) = slab(
        &node.child_min_z,
        &node.child_max_z,
        d.z < 0.0,
        dir_inv.z,
        origin.z,
    );
    let tmin = _mm256_max_ps(tmin_x, _mm256_max_ps(tmin_y, tmin_z));
    let tmin = _mm256_max_ps(tmin, _mm256_set1_ps(ray.tmin));
    let tmax = _mm256_min_ps(
        _mm256_min_ps(tmax_x, _mm256_min_ps(tmax_y, tmax_z)),
        _mm256_set1_ps(tmax),
    );
    _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(tmin, tmax)) as u32
}

/// obvhs's `ray_get_octant_inv4` (crate-private): which of the eight orders the traversal
/// visits a node's children in, from the direction's signs.
#[inline(always)]
fn octant_inv4(dir: Vec3A) -> u32 {
    (if dir.x < 0.0 { 0 } else { 0x0404_0404 })
        | (if dir.y < 0.0 { 0 } else { 0x0202_0202 })
        | (if dir.z < 0.0 { 0 } else { 0x0101_0101 })
}

/// Up to how many active rays of a packet a node is tested ray by ray ([`child_hits_avx2`]),
/// not over all lanes at once ([`Lanes::node_hits`]): the lanes' test costs about five
/// single-ray tests for a node of eight children (4 and 5 measured within 0.1%).
const LANES_TESTED_ALONE: u32 = 5;

/// A group of children left to visit in a packet traversal: obvhs's `current_group` (the base
/// index of the children, their priority bits in the top byte, the node's `imask` in the low
/// one) and, in byte `k`, the lanes that enter the child of priority bit `24 + k`.
#[derive(Clone, Copy, Default)]
struct PacketGroup {
    child_base: u32,
    bits: u32,
    lanes: u64,
}

/// The rays of a packet, one per lane, as [`node_hits_avx2`] and [`RtTri::uvt`] read them.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Lanes {
    origin: [std::arch::x86_64::__m256; 3],
    direction: [std::arch::x86_64::__m256; 3],
    inv_direction: [std::arch::x86_64::__m256; 3],
    /// Per axis, whether the rays go toward negative values (the same for all: one octant).
    negative: [bool; 3],
    /// Each ray's `tmin`: no child nearer is entered.
    tmin: std::arch::x86_64::__m256,
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
        let d = rays[0].direction;
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
            inv_direction: [
                lane(|r| r.inv_direction.x),
                lane(|r| r.inv_direction.y),
                lane(|r| r.inv_direction.z),
            ],
            negative: [d.x < 0.0, d.y < 0.0, d.z < 0.0],
            tmin: lane(|r| r.tmin),
        }
    }

    /// In byte `j`: the lanes of `active` whose rays (closest hits so far at `tmax`) enter
    /// child `j` of `node`. Each lane computes [`node_hits_avx2`]'s IEEE operations for that
    /// child, in the same order, so its bit is that test's, bit for bit.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn node_hits(&self, node: &CwBvhNode, tmax: std::arch::x86_64::__m256, active: u32) -> u64 {
        use std::arch::x86_64::*;
        let extent = node.compute_extent();
        let p = Vec3A::from(node.p);
        let axis = |k: usize, e: f32, p: f32| {
            let inv = self.inv_direction[k];
            (
                _mm256_mul_ps(_mm256_set1_ps(e), inv),
                _mm256_mul_ps(_mm256_sub_ps(_mm256_set1_ps(p), self.origin[k]), inv),
            )
        };
        let (inv_x, o_x) = axis(0, extent.x, p.x);
        let (inv_y, o_y) = axis(1, extent.y, p.y);
        let (inv_z, o_z) = axis(2, extent.z, p.z);
        // SAFETY: an 8-byte load from an 8-byte array.
        #[allow(unsafe_code)]
        let bytes = |v: &[u8; 8]| unsafe {
            _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_loadl_epi64(
                v.as_ptr() as *const __m128i
            )))
        };
        // The children's near and far planes, all eight per register.
        let planes = |lo: &[u8; 8], hi: &[u8; 8], negative: bool| {
            let (lo, hi) = (bytes(lo), bytes(hi));
            if negative { (hi, lo) } else { (lo, hi) }
        };
        let (near_x, far_x) = planes(&node.child_min_x, &node.child_max_x, self.negative[0]);
        let (near_y, far_y) = planes(&node.child_min_y, &node.child_max_y, self.negative[1]);
        let (near_z, far_z) = planes(&node.child_min_z, &node.child_max_z, self.negative[2]);
        let mut lanes = 0u64;
        for j in 0..8 {
            if node.child_meta[j] == 0 {
                continue;
            }
            // Child j's plane in every lane, then the slab distance of each lane's ray.
            let child = _mm256_set1_epi32(j as i32);
            let slab = |q: __m256, inv: __m256, o: __m256| {
                let q = _mm256_permutevar8x32_ps(q, child);
                _mm256_add_ps(_mm256_mul_ps(q, inv), o)
            };
            let tmin = _mm256_max_ps(
                slab(near_x, inv_x, o_x),
                _mm256_max_ps(slab(near_y, inv_y, o_y), slab(near_z, inv_z, o_z)),
            );
            let tmax_child = _mm256_min_ps(
                slab(far_x, inv_x, o_x),
                _mm256_min_ps(slab(far_y, inv_y, o_y), slab(far_z, inv_z, o_z)),
            );
            let tmin = _mm256_max_ps(tmin, self.tmin);
            let tmax_child = _mm256_min_ps(tmax_child, tmax);
            let hit = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(tmin, tmax_child)) as u32;
            lanes |= ((hit & active) as u64) << (8 * j);
        }
        lanes
    }

    /// The lanes of `active` whose rays meet `tri` at a distance in `[tmin, tmax)`, and the
    /// distances: [`RtTri::intersect`] followed by the traversal's `t < tmax`, lane by lane,
    /// with glam's SSE2 operations for `cross` and `dot` in their order (`(x + y) + z`;
    /// `a.y·b.z - a.z·b.y`), so the same answer bit for bit.
    #[target_feature(enable = "avx2")]
    #[inline]
    fn triangle_hits(
        &self,
        tri: &RtTri,
        tmin: std::arch::x86_64::__m256,
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
            _mm256_cmp_ps::<_CMP_GE_OQ>(t, tmin),
            _mm256_cmp_ps::<_CMP_LT_OQ>(t, tmax),
        );
        (_mm256_and_ps(_mm256_and_ps(inside, within), active), t)
    }
}

/// The closest primitive along `ray` and its distance: obvhs's `CwBvh::ray_traverse`, through
/// its `traverse!` macro here so that the traversal is compiled into (and inlined by) the
/// renderer's CPU-feature variants (`render::render_tile`) instead of once for baseline x86-64.
#[inline(always)]
fn closest(
    bvh: &CwBvh,
    isa: Isa,
    ray: Ray,
    mut intersect: impl FnMut(&Ray, usize) -> f32,
) -> Option<(u32, f32)> {
    let mut traverse_ray = ray;
    let mut hit = RayHit::none();
    let mut state = bvh.new_traversal(ray.direction);
    let mut node;
    obvhs::traverse!(
        bvh,
        node,
        state,
        node_hits(isa, node, &traverse_ray, state.oct_inv4),
        {
            let t = intersect(&traverse_ray, state.primitive_id as usize);
            if t < traverse_ray.tmax {
                hit.primitive_id = state.primitive_id;
                hit.t = t;
                traverse_ray.tmax = t;
            }
        }
    );
    (hit.t < ray.tmax).then_some((hit.primitive_id, hit.t))
}

/// A primitive that lies along `ray`, if any: obvhs's `CwBvh::ray_traverse_miss`, stopped at
/// the first hit, for the same reason as [`closest`].
#[inline(always)]
fn any_hit(
    bvh: &CwBvh,
    isa: Isa,
    ray: Ray,
    mut intersect: impl FnMut(&Ray, usize) -> f32,
) -> Option<u32> {
    let mut state = bvh.new_traversal(ray.direction);
    let mut node;
    let mut hit = None;
    'outer: {
        obvhs::traverse!(
            bvh,
            node,
            state,
            node_hits(isa, node, &ray, state.oct_inv4),
            {
                if intersect(&ray, state.primitive_id as usize) < ray.tmax {
                    hit = Some(state.primitive_id);
                    break 'outer;
                }
            }
        );
    }
    hit
}

/// The two ray queries a renderer makes. The renderer traces through [`Bvh`]; the benchmark
/// traces through a recorder, to replay exactly the renderer's rays through raw traversal.
pub trait Tracer {
    /// The closest hit of `origin + t·dir` with `t` in `(tmin, tmax)`.
    fn closest_hit(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit>;
    /// A primitive on the open segment `origin + t·dir`, `t` in `(tmin, tmax)`, if any, in the
    /// tracer's own numbering; `guess` (such a number, or [`NO_OCCLUDER`]) is tested first.
    fn occluder(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32, guess: u32) -> Option<u32>;
    /// Whether anything lies on the open segment `origin + t·dir`, `t` in `(tmin, tmax)`.
    #[inline(always)]
    fn occluded(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        self.occluder(origin, dir, tmin, tmax, NO_OCCLUDER)
            .is_some()
    }
    /// [`Self::closest_hit`] of each ray `origins[i] + t·dirs[i]` into `hits[i]` (at most
    /// [`PACKET`] rays): the same answers, bit for bit, though a tracer may trace them together.
    #[inline(always)]
    fn closest_hits(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        tmin: f32,
        tmax: f32,
        hits: &mut [Option<Hit>],
    ) {
        for ((&o, &d), hit) in origins.iter().zip(dirs).zip(hits) {
            *hit = self.closest_hit(o, d, tmin, tmax);
        }
    }
}

/// The most rays [`Tracer::closest_hits`] traces together: one per lane of an AVX2 register.
pub const PACKET: usize = 8;

/// No guess for [`Tracer::occluder`].
pub const NO_OCCLUDER: u32 = u32::MAX;

/// A tracer that tests the primitive which blocked its last shadow ray before traversing
/// (Haines and Greenberg's shadow cache): consecutive shading points of a tile lie close
/// together, and their shadow rays toward a light behind a shade are mostly blocked by the
/// same triangle, so one triangle test often replaces a traversal. Occlusion is a yes/no
/// answer whichever blocker is found, so every image stays the same, bit for bit. One per
/// thread (the last occluder is a `Cell`).
pub struct ShadowCache<'t, T: Tracer> {
    tracer: &'t T,
    last: Cell<u32>,
}

impl<'t, T: Tracer> ShadowCache<'t, T> {
    #[inline(always)]
    pub fn new(tracer: &'t T) -> Self {
        ShadowCache {
            tracer,
            last: Cell::new(NO_OCCLUDER),
        }
    }
}

impl<T: Tracer> Tracer for ShadowCache<'_, T> {
    #[inline(always)]
    fn closest_hit(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        self.tracer.closest_hit(origin, dir, tmin, tmax)
    }

    #[inline(always)]
    fn closest_hits(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        tmin: f32,
        tmax: f32,
        hits: &mut [Option<Hit>],
    ) {
        self.tracer.closest_hits(origins, dirs, tmin, tmax, hits);
    }

    /// The guess is always the last blocker (the renderer never has one of its own).
    #[inline(always)]
    fn occluder(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32, _: u32) -> Option<u32> {
        let found = self
            .tracer
            .occluder(origin, dir, tmin, tmax, self.last.get());
        if let Some(id) = found {
            self.last.set(id);
        }
        found
    }
}

impl Tracer for Bvh {
    #[inline(always)]
    fn closest_hit(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        Bvh::closest_hit(self, origin, dir, tmin, tmax)
    }

    #[inline(always)]
    fn closest_hits(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        tmin: f32,
        tmax: f32,
        hits: &mut [Option<Hit>],
    ) {
        Bvh::closest_hits(self, origins, dirs, tmin, tmax, hits);
    }

    #[inline(always)]
    fn occluder(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32, guess: u32) -> Option<u32> {
        Bvh::occluder(self, origin, dir, tmin, tmax, guess)
    }
}

pub struct Bvh {
    /// `None` for an empty scene, where every ray misses.
    cwbvh: Option<CwBvh>,
    /// Triangles in BVH order.
    triangles: Vec<RtTri>,
    /// Scene index of each triangle in BVH order.
    scene_index: Vec<u32>,
    /// Alpha-tested triangles, if the scene has any: rays pass through their cut-out parts.
    cutouts: Option<Cutouts>,
    /// The instruction set of the node test, `Isa::detect()`.
    isa: Isa,
}

/// A triangle whose material is alpha-tested: its corners' `TEXCOORD_0/1` and its surface.
#[derive(Clone, Copy, Debug)]
pub struct CutoutTriangle {
    pub uvs: [[Vec2; 3]; 2],
    /// Index into the surfaces given to [`Bvh::set_cutouts`].
    pub surface: u32,
}

/// The any-hit test of alpha-tested triangles (glTF MASK and BLEND materials).
struct Cutouts {
    /// Per triangle in BVH order: index into `triangles`, or `u32::MAX`.
    slot: Vec<u32>,
    triangles: Vec<CutoutTriangle>,
    surfaces: Vec<SurfaceTextures>,
}

impl Cutouts {
    /// Whether the ray meets BVH triangle `id` at barycentrics (u, v).
    #[inline]
    fn present(&self, id: usize, u: f32, v: f32, ray: &Ray) -> bool {
        let Some(t) = self
            .slot
            .get(id)
            .and_then(|&k| self.triangles.get(k as usize))
        else {
            return true;
        };
        let Some(surface) = self.surfaces.get(t.surface as usize) else {
            return true;
        };
        let w = 1.0 - u - v;
        let uvs = t.uvs.map(|c| w * c[0] + u * c[1] + v * c[2]);
        surface.is_present(&uvs, || coverage_uniform(ray, id))
    }
}

/// A uniform number in [0, 1) hashed from the ray and the triangle, for BLEND coverage: the
/// same ray always makes the same choice (the closest-hit traversal may test a triangle more
/// than once), and rays of different samples decide independently.
fn coverage_uniform(ray: &Ray, id: usize) -> f32 {
    let words = [
        ray.origin.x.to_bits(),
        ray.origin.y.to_bits(),
        ray.origin.z.to_bits(),
        ray.direction.x.to_bits(),
        ray.direction.y.to_bits(),
        ray.direction.z.to_bits(),
        id as u32,
    ];
    // FNV-1a over the words, then a 64-bit finaliser (splitmix64's).
    let mut h = words.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, &w| {
        (h ^ w as u64).wrapping_mul(0x0000_0100_0000_01b3)
    });
    h = (h ^ (h >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    h ^= h >> 31;
    (h >> 40) as f32 / (1u64 << 24) as f32
}

/// Why triangles cannot be put in a BVH that obvhs builds in reasonable time and traverses
/// correctly.
#[derive(Debug, thiserror::Error)]
pub enum BvhError {
    /// Triangles with one bounding box make obvhs's PLOC build quadratic in time and its tree a
    /// chain (a thousand copies of one triangle give a tree 999 levels deep).
    #[error(
        "{count} triangles share one bounding box (at most {MAX_SHARED_BOUNDS} may): duplicated \
         geometry that the BVH cannot be built over"
    )]
    SharedBounds { count: usize },
    /// The tree is deeper than obvhs's fixed traversal stack, which would silently skip nodes.
    #[error(
        "the geometry is too degenerate for the BVH: its tree is {depth} levels deep (at most \
         {limit})"
    )]
    TooDeep { depth: u32, limit: u32 },
}

/// The most triangles that may share one bounding box (two coincident faces of opposite
/// winding, or a few duplicated objects, share theirs).
pub const MAX_SHARED_BOUNDS: usize = 64;
/// The deepest binary tree converted to a CWBVH (the conversion recurses once per level).
const MAX_BVH2_DEPTH: u32 = 256;
/// obvhs's CWBVH traversal stack holds 32 entries; a tree as deep would overflow it.
const MAX_CWBVH_DEPTH: u32 = 31;

/// Levels below the root of a binary tree's deepest node.
fn bvh2_depth(bvh2: &Bvh2) -> u32 {
    let mut deepest = 0;
    let mut stack = vec![(0usize, 0u32)];
    while let Some((i, depth)) = stack.pop() {
        deepest = deepest.max(depth);
        if let Some(node) = bvh2.nodes.get(i).filter(|n| !n.is_leaf()) {
            let first = node.first_index as usize;
            stack.extend([(first, depth + 1), (first + 1, depth + 1)]);
        }
    }
    deepest
}

/// Levels below the root of a CWBVH's deepest interior node.
fn cwbvh_depth(cwbvh: &CwBvh) -> u32 {
    let mut deepest = 0;
    let mut stack = vec![(0usize, 0u32)];
    while let Some((i, depth)) = stack.pop() {
        deepest = deepest.max(depth);
        let Some(node) = cwbvh.nodes.get(i) else {
            continue;
        };
        for child in 0..8 {
            if !node.is_child_empty(child) && !node.is_leaf(child) {
                stack.push((node.child_node_index(child) as usize, depth + 1));
            }
        }
    }
    deepest
}

impl Bvh {
    /// A BVH over the triangles that have an area (the others can never be hit); triangle
    /// numbers in hits are indices into `triangles`.
    ///
    /// The steps are obvhs's `build_cwbvh_from_tris` with the medium preset, without its debug
    /// validation (which panics on a deep tree), and with the depth checked before the
    /// recursive conversion and after it.
    pub fn build(triangles: &[[Vec3; 3]]) -> Result<Self, BvhError> {
        let (tris, kept): (Vec<Triangle>, Vec<u32>) = triangles
            .iter()
            .enumerate()
            .filter(|(_, [a, b, c])| (*b - *a).cross(*c - *a) != Vec3::ZERO)
            .map(|(i, t)| {
                let triangle = Triangle {
                    v0: t[0].into(),
                    v1: t[1].into(),
                    v2: t[2].into(),
                };
                (triangle, i as u32)
            })
            .unzip();
        if tris.is_empty() {
            return Ok(Bvh {
                cwbvh: None,
                triangles: Vec::new(),
                scene_index: Vec::new(),
                cutouts: None,
                isa: Isa::detect(),
            });
        }
        let mut sharing: HashMap<[u32; 6], usize> = HashMap::new();
        for t in &tris {
            let bounds = t.aabb();
            let (lo, hi) = (Vec3::from(bounds.min), Vec3::from(bounds.max));
            let key = [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z].map(f32::to_bits);
            let count = sharing.entry(key).or_default();
            *count += 1;
            if *count > MAX_SHARED_BOUNDS {
                return Err(BvhError::SharedBounds { count: *count });
            }
        }
        let params = BvhBuildParams::medium_build();
        let mut bvh2 = PlocBuilder::with_capacity(tris.len()).build(
            params.ploc_search_distance,
            &tris,
            (0..tris.len() as u32).collect(),
            params.sort_precision,
            params.search_depth_threshold,
        );
        ReinsertionOptimizer::default().run(&mut bvh2, params.reinsertion_batch_ratio, None);
        let depth = bvh2_depth(&bvh2);
        if depth > MAX_BVH2_DEPTH {
            return Err(BvhError::TooDeep {
                depth,
                limit: MAX_BVH2_DEPTH,
            });
        }
        let mut cwbvh = bvh2_to_cwbvh(&bvh2, params.max_prims_per_leaf.clamp(1, 3), true, false);
        let depth = cwbvh_depth(&cwbvh);
        if depth > MAX_CWBVH_DEPTH {
            return Err(BvhError::TooDeep {
                depth,
                limit: MAX_CWBVH_DEPTH,
            });
        }
        let order = std::mem::take(&mut cwbvh.primitive_indices);
        let triangles = order
            .iter()
            .map(|&i| RtTri::new(&tris[i as usize]))
            .collect();
        let scene_index = order.iter().map(|&i| kept[i as usize]).collect();
        // After reordering, BVH primitive i is triangle i of `triangles`.
        cwbvh.primitive_indices = (0..order.len() as u32).collect();
        Ok(Bvh {
            cwbvh: Some(cwbvh),
            triangles,
            scene_index,
            cutouts: None,
            isa: Isa::detect(),
        })
    }

    /// Makes the triangles that `cutout` gives (by scene index) alpha-tested against
    /// `surfaces`: rays pass through where they are absent.
    pub fn set_cutouts(
        &mut self,
        cutout: impl Fn(u32) -> Option<CutoutTriangle>,
        surfaces: Vec<SurfaceTextures>,
    ) {
        let mut triangles = Vec::new();
        let slot = self
            .scene_index
            .iter()
            .map(|&i| match cutout(i) {
                Some(t) => {
                    triangles.push(t);
                    triangles.len() as u32 - 1
                }
                None => u32::MAX,
            })
            .collect();
        self.cutouts = (!triangles.is_empty()).then_some(Cutouts {
            slot,
            triangles,
            surfaces,
        });
    }

    /// Distance to BVH triangle `id` along the ray, or infinity: a miss, or a cut-out point.
    #[inline(always)]
    fn intersect_cutout(&self, cutouts: &Cutouts, ray: &Ray, id: usize) -> f32 {
        let tri = &self.triangles[id];
        let (u, v, t) = tri.uvt(ray);
        if u >= 0.0
            && v >= 0.0
            && u + v <= 1.0
            && t >= ray.tmin
            && t <= ray.tmax
            && cutouts.present(id, u, v, ray)
        {
            t
        } else {
            f32::INFINITY
        }
    }

    /// The closest hit of `origin + t·dir` with `t` in `(tmin, tmax)`.
    #[inline(always)]
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        let bvh = self.cwbvh.as_ref()?;
        let ray = make_ray(origin, dir, tmin, tmax);
        let (id, t) = match &self.cutouts {
            None => closest(bvh, self.isa, ray, |r, id| self.triangles[id].intersect(r)),
            Some(c) => closest(bvh, self.isa, ray, |r, id| self.intersect_cutout(c, r, id)),
        }?;
        let (u, v, _) = self.triangles[id as usize].uvt(&ray);
        Some(Hit {
            t,
            triangle: self.scene_index[id as usize],
            bary: Vec2::new(u, v),
        })
    }

    /// [`Self::closest_hit`] of each ray `origins[i] + t·dirs[i]` into `hits[i]`. Two to
    /// [`PACKET`] rays of one direction octant are traced together where the CPU has AVX2 and
    /// no triangle is cut out (`closest_packet`); others one by one. Same answers.
    #[inline(always)]
    pub fn closest_hits(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        tmin: f32,
        tmax: f32,
        hits: &mut [Option<Hit>],
    ) {
        let n = origins.len().min(dirs.len()).min(hits.len());
        #[cfg(target_arch = "x86_64")]
        if let (Isa::Avx2, None, Some(bvh), 2..=PACKET) = (self.isa, &self.cutouts, &self.cwbvh, n)
        {
            let rays: [Ray; PACKET] = std::array::from_fn(|i| {
                let i = i.min(n - 1);
                make_ray(origins[i], dirs[i], tmin, tmax)
            });
            let octant = octant_inv4(rays[0].direction);
            if rays.iter().all(|r| octant_inv4(r.direction) == octant) {
                // SAFETY: a BVH's `isa` is `Isa::detect()`, which is `Avx2` only where the CPU
                // has AVX2 and BMI2.
                #[allow(unsafe_code)]
                let found = unsafe { self.closest_packet(bvh, &rays, n) };
                for ((hit, found), ray) in hits.iter_mut().zip(found).zip(&rays).take(n) {
                    *hit = found.map(|(id, t)| {
                        let (u, v, _) = self.triangles[id as usize].uvt(ray);
                        Hit {
                            t,
                            triangle: self.scene_index[id as usize],
                            bary: Vec2::new(u, v),
                        }
                    });
                }
                return;
            }
        }
        for i in 0..n {
            hits[i] = self.closest_hit(origins[i], dirs[i], tmin, tmax);
        }
    }

    /// The closest triangle (BVH order) and distance along each of `rays[..n]`, traced
    /// together: one traversal whose stack entries carry, per child, the lanes that enter it.
    /// Each ray meets the nodes and triangles it would alone (its masks are [`node_hits_avx2`]'s,
    /// lane by lane), in the same order (the rays share their octant, so the children's order),
    /// with the same `tmax` at each test: so the same answer, bit for bit
    /// (`packets_answer_as_single_rays`).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,bmi2")]
    fn closest_packet(
        &self,
        bvh: &CwBvh,
        rays: &[Ray; PACKET],
        n: usize,
    ) -> [Option<(u32, f32)>; PACKET] {
        use std::arch::x86_64::*;
        let lanes = Lanes::new(rays);
        let tmin = _mm256_set1_ps(rays[0].tmin);
        let tmax0 = _mm256_set1_ps(rays[0].tmax);
        // Per lane: the closest hit so far (the traversal's `tmax`) and its triangle.
        let (mut tmax, mut found) = (tmax0, _mm256_setzero_si256());
        let lane_bits = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        let oct_inv4 = octant_inv4(rays[0].direction);
        // obvhs's traversal (`traverse!`) with one group (children left, by priority bit)
        // per level on the stack, and their lanes beside them.
        let mut stack = [PacketGroup::default(); MAX_CWBVH_DEPTH as usize + 1];
        let mut depth = 0usize;
        let mut group = PacketGroup {
            child_base: 0,
            bits: 0x8000_0000,
            lanes: (((1u32 << n) - 1) as u64) << 56,
        };
        let mut lanes_of_primitive = [0u8; 24];
        loop {
            if group.bits & 0xff00_0000 == 0 {
                let Some(top) = depth.checked_sub(1) else {
                    break;
                };
                depth = top;
                group = stack[depth];
                continue;
            }
            let offset = 31 - group.bits.leading_zeros();
            let slot = (offset - 24) ^ (oct_inv4 & 0xff);
            let child = group.child_base + (group.bits & !(u32::MAX << slot)).count_ones();
            let active = (group.lanes >> ((offset - 24) * 8)) as u32 & 0xff;
            group.bits &= !(1 << offset);
            if group.bits & 0xff00_0000 != 0 {
                stack[depth] = group;
                depth += 1;
            }
            let node = &bvh.nodes[child as usize];
            let lanes_of_child = if active.count_ones() > LANES_TESTED_ALONE {
                lanes.node_hits(node, tmax, active)
            } else {
                // Few rays: the single-ray test of each costs less than one over all lanes.
                let mut t = [0f32; PACKET];
                // SAFETY: a 32-byte store into a 32-byte array.
                #[allow(unsafe_code)]
                unsafe {
                    _mm256_storeu_ps(t.as_mut_ptr(), tmax)
                };
                let (mut lanes_of_child, mut r) = (0u64, active);
                while r != 0 {
                    let i = r.trailing_zeros();
                    r &= r - 1;
                    let hit = child_hits_avx2(node, &rays[i as usize], t[i as usize]);
                    lanes_of_child |= _pdep_u64(hit as u64, 0x0101_0101_0101_0101) << i;
                }
                lanes_of_child
            };
            // The children's lanes into the node's hit mask, as `node_hits_avx2` builds it.
            let (child_bits8, bit_index8) = node.get_child_and_index_bits(oct_inv4);
            let (mut hits, mut lanes_of_slot) = (0u32, 0u64);
            let mut entered = lanes_of_child;
            while entered != 0 {
                let j = entered.trailing_zeros() & !7;
                let r = (entered >> j) as u8;
                entered &= !(0xff << j);
                let c = ((child_bits8 >> j) as u32 & 0xff) << ((bit_index8 >> j) as u32 & 0xff);
                hits |= c;
                if c >= 1 << 24 {
                    lanes_of_slot |= (r as u64) << ((c.trailing_zeros() - 24) * 8);
                } else {
                    let mut bits = c;
                    while bits != 0 {
                        lanes_of_primitive[bits.trailing_zeros() as usize] = r;
                        bits &= bits - 1;
                    }
                }
            }
            let mut primitives = hits & 0x00ff_ffff;
            while primitives != 0 {
                let k = 31 - primitives.leading_zeros();
                primitives &= !(1 << k);
                let id = node.primitive_base_idx + k;
                let r = _mm256_set1_epi32(lanes_of_primitive[k as usize] as i32);
                let active = _mm256_castsi256_ps(_mm256_cmpeq_epi32(
                    _mm256_and_si256(r, lane_bits),
                    lane_bits,
                ));
                let (hit, t) =
                    lanes.triangle_hits(&self.triangles[id as usize], tmin, tmax, active);
                tmax = _mm256_blendv_ps(tmax, t, hit);
                found = _mm256_blendv_epi8(
                    found,
                    _mm256_set1_epi32(id as i32),
                    _mm256_castps_si256(hit),
                );
            }
            group = PacketGroup {
                child_base: node.child_base_idx,
                bits: (hits & 0xff00_0000) | node.imask as u32,
                lanes: lanes_of_slot,
            };
        }
        let (mut t, mut id) = ([0f32; PACKET], [0u32; PACKET]);
        // SAFETY: 32-byte stores into 32-byte arrays.
        #[allow(unsafe_code)]
        unsafe {
            _mm256_storeu_ps(t.as_mut_ptr(), tmax);
            _mm256_storeu_si256(id.as_mut_ptr() as *mut __m256i, found);
        }
        // A lane whose `tmax` never shrank found nothing.
        std::array::from_fn(|i| (i < n && t[i] < rays[i].tmax).then_some((id[i], t[i])))
    }

    /// Whether anything lies on the open segment `origin + t·dir`, `t` in `(tmin, tmax)`.
    #[inline(always)]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        self.occluder(origin, dir, tmin, tmax, NO_OCCLUDER)
            .is_some()
    }

    /// A triangle (BVH order) on the open segment `origin + t·dir`, `t` in `(tmin, tmax)`:
    /// triangle `guess` if it is one, else the first the traversal finds.
    #[inline(always)]
    pub fn occluder(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
        guess: u32,
    ) -> Option<u32> {
        let bvh = self.cwbvh.as_ref()?;
        let ray = make_ray(origin, dir, tmin, tmax);
        match &self.cutouts {
            None => {
                self.guess_then_traverse(bvh, ray, guess, |r, id| self.triangles[id].intersect(r))
            }
            Some(c) => {
                self.guess_then_traverse(bvh, ray, guess, |r, id| self.intersect_cutout(c, r, id))
            }
        }
    }

    #[inline(always)]
    fn guess_then_traverse(
        &self,
        bvh: &CwBvh,
        ray: Ray,
        guess: u32,
        intersect: impl Fn(&Ray, usize) -> f32,
    ) -> Option<u32> {
        if (guess as usize) < self.triangles.len() && intersect(&ray, guess as usize) < ray.tmax {
            return Some(guess);
        }
        any_hit(bvh, self.isa, ray, intersect)
    }

    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The renderer's closest-hit traversal with no other work, for benchmarks: the distance
    /// alone (no barycentrics, no cut-outs).
    #[inline(always)]
    pub fn raw_closest_t(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> f32 {
        let Some(bvh) = self.cwbvh.as_ref() else {
            return f32::INFINITY;
        };
        let ray = make_ray(origin, dir, tmin, tmax);
        closest(bvh, self.isa, ray, |r, id| self.triangles[id].intersect(r))
            .map_or(f32::INFINITY, |(_, t)| t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;

    /// The shadow cache answers every occlusion query as the BVH does: rays from points close
    /// together toward a plate with holes, some blocked by the triangle that blocked the last
    /// ray, some by another, some not at all, some stopping short of the plate. Not vacuous:
    /// the guess answers a share of the queries, and traversal the rest.
    #[test]
    fn shadow_cache_answers_as_the_bvh() {
        let mut rng = Rng::new(11, 0);
        // A 6 × 6 grid of unit squares at y = 1, every third one left out.
        let mut triangles = Vec::new();
        for i in 0..36 {
            if i % 3 == 0 {
                continue;
            }
            let (x, z) = ((i % 6) as f32 - 3.0, (i / 6) as f32 - 3.0);
            let [a, b, c, d] = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
                .map(|(dx, dz)| Vec3::new(x + dx, 1.0, z + dz));
            triangles.extend([[a, b, c], [a, c, d]]);
        }
        let bvh = Bvh::build(&triangles).unwrap();
        let cache = ShadowCache::new(&bvh);
        let (mut blocked, mut guessed) = (0, 0);
        for i in 0..4000 {
            let u = rng.uniform2();
            let origin = Vec3::new(u.x - 0.5, 0.0, u.y - 0.5);
            let target = Vec3::new(rng.uniform() * 2.0 - 1.0, 2.0, rng.uniform() * 2.0 - 1.0);
            let dir = (target - origin).normalize();
            let tmax = if i % 4 == 0 { 0.9 } else { 3.0 };
            let last = cache.last.get();
            let expected = bvh.occluded(origin, dir, 0.0, tmax);
            assert_eq!(cache.occluded(origin, dir, 0.0, tmax), expected, "ray {i}");
            blocked += expected as u32;
            guessed += (expected && cache.last.get() == last) as u32;
        }
        // 537 of 1498 (the rays that stop short of the plate are never blocked).
        assert!(
            blocked > 1200 && guessed > 300 && guessed < blocked - 500,
            "{guessed} of {blocked}"
        );
    }

    /// Packets answer as their rays traced one by one, bit for bit (distance, triangle,
    /// barycentrics): camera rays of up to eight consecutive jittered pixels in a built-in
    /// scene, short ones among them, and rays from random points in random directions of one
    /// octant, or of several (which are traced one by one). Not vacuous: most packets are
    /// traced together, and most of their rays hit something.
    #[test]
    fn packets_answer_as_single_rays() {
        let scene = crate::scene::Scene::open("lampshade").unwrap();
        let bvh = &scene.geometry.bvh;
        let rays = scene.camera.rays(1.0);
        let mut rng = Rng::new(5, 0);
        let (mut together, mut hits, mut rays_traced) = (0, 0, 0);
        for packet in 0..3000 {
            let n = if packet % 7 == 0 {
                1 + packet % PACKET
            } else {
                PACKET
            };
            let (mut origins, mut dirs) = ([Vec3::ZERO; PACKET], [Vec3::ZERO; PACKET]);
            if packet % 2 == 0 {
                // Consecutive pixels of a row, at a random resolution.
                let size = 16.0 + rng.uniform() * 1000.0;
                let start = rng.uniform2() * size;
                for i in 0..n {
                    let pixel = start + Vec2::new(i as f32, 0.0) + rng.uniform2();
                    (origins[i], dirs[i]) = rays.ray(pixel / size);
                }
            } else {
                let signs = Vec3::new(rng.uniform(), rng.uniform(), rng.uniform());
                let mixed = packet % 6 == 1;
                for i in 0..n {
                    let u = Vec3::new(rng.uniform(), rng.uniform(), rng.uniform());
                    origins[i] = (u * 2.0 - 1.0) * 2.0;
                    let w = Vec3::new(rng.uniform(), rng.uniform(), rng.uniform());
                    let mut d = w + 0.01;
                    let s = if mixed {
                        Vec3::new(w.y, w.z, w.x)
                    } else {
                        signs
                    };
                    d *= Vec3::select(s.cmplt(Vec3::splat(0.5)), -Vec3::ONE, Vec3::ONE);
                    if packet % 10 == 3 {
                        d.y = 0.0;
                    }
                    dirs[i] = d.normalize();
                }
            }
            let tmax = if packet % 5 == 0 { 0.7 } else { f32::INFINITY };
            let mut found = [None; PACKET];
            bvh.closest_hits(&origins[..n], &dirs[..n], 0.0, tmax, &mut found);
            let octant = octant_inv4((dirs[0] + Vec3::ZERO).into());
            together += dirs[..n]
                .iter()
                .all(|&d| octant_inv4((d + Vec3::ZERO).into()) == octant)
                as u32;
            for i in 0..n {
                let expected = bvh.closest_hit(origins[i], dirs[i], 0.0, tmax);
                assert_eq!(found[i], expected, "packet {packet}, ray {i}");
                if let (Some(a), Some(b)) = (found[i], expected) {
                    assert_eq!(a.t.to_bits(), b.t.to_bits());
                    assert_eq!(
                        a.bary.to_array().map(f32::to_bits),
                        b.bary.to_array().map(f32::to_bits)
                    );
                }
                hits += expected.is_some() as u32;
                rays_traced += 1;
            }
            assert!(found[n..].iter().all(Option::is_none));
        }
        assert!(
            together > 2000 && hits > rays_traced / 2,
            "{together}, {hits} of {rays_traced}"
        );
    }

    /// The AVX2 and scalar node tests give obvhs's mask for every node of a tree and rays in every octant,
    /// axis-parallel ones too (+0.0 components: which slab plane is near is decided by the
    /// direction's sign, and obvhs's safe inverse makes them huge but finite), short ones, and
    /// ones starting inside the boxes. Reading +0.0 as negative there fails it.
    #[cfg(target_arch = "x86_64")]
    #[test]
    #[allow(unsafe_code)]
    fn avx2_node_test_agrees_with_obvhs() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut rng = Rng::new(7, 0);
        let mut point = |scale: f32| {
            let u = rng.uniform2();
            let w = rng.uniform();
            (Vec3::new(u.x, u.y, w) * 2.0 - 1.0) * scale
        };
        let triangles: Vec<[Vec3; 3]> = (0..2000)
            .map(|_| {
                let c = point(4.0);
                [c + point(0.3), c + point(0.3), c + point(0.3)]
            })
            .collect();
        let bvh = Bvh::build(&triangles).unwrap();
        let cwbvh = bvh.cwbvh.as_ref().unwrap();
        let (mut compared, mut hits) = (0, 0);
        for i in 0..3000 {
            let mut dir = point(1.0);
            match i % 5 {
                0 => dir.x = 0.0,
                1 => dir = Vec3::new(0.0, dir.y, 0.0),
                _ => {}
            }
            if dir == Vec3::ZERO {
                continue;
            }
            let tmax = if i % 3 == 0 { 0.5 } else { f32::INFINITY };
            // obvhs bounds entry distances by NODE_EPSILON, these tests by the ray's tmin.
            let ray = make_ray(point(6.0), dir.normalize(), NODE_EPSILON, tmax);
            let oct_inv4 = cwbvh.new_traversal(ray.direction).oct_inv4;
            for node in &cwbvh.nodes {
                let sse = node.intersect_ray(&ray, oct_inv4);
                // SAFETY: AVX2 was detected above.
                let avx2 = unsafe { node_hits_avx2(node, &ray, oct_inv4) };
                assert_eq!(sse, avx2, "ray {i}: {ray:?}, node {node:?}");
                let scalar = node_hits_scalar(node, &ray, oct_inv4);
                assert_eq!(sse, scalar, "ray {i}: {ray:?}, node {node:?}");
                compared += 1;
                hits += (sse != 0) as u32;
            }
        }
        // Not vacuous: the rays enter children of 2.5 nodes each on average (7581 masks of
        // 717,000 are not empty), and miss every child of most.
        assert!(hits > 5000 && hits < compared / 20, "{hits} of {compared}");
    }

    /// A ray that starts closer to a wall than obvhs's absolute node bound (1e-4) and heads
    /// into it meets it, in every instruction set, alone and in packets; obvhs's own
    /// traversal (the reference, which is right for rays that start farther away) misses it.
    #[test]
    fn rays_starting_near_a_wall_meet_it() {
        // A wall in the plane x = 0 among other geometry, so that it lies in a deep node.
        let mut triangles: Vec<[Vec3; 3]> = vec![
            [
                Vec3::new(0.0, -1.0, -1.0),
                Vec3::new(0.0, 1.0, -1.0),
                Vec3::new(0.0, 1.0, 1.0),
            ],
            [
                Vec3::new(0.0, -1.0, -1.0),
                Vec3::new(0.0, 1.0, 1.0),
                Vec3::new(0.0, -1.0, 1.0),
            ],
        ];
        let mut rng = Rng::new(3, 0);
        for _ in 0..500 {
            let (u, w) = (rng.uniform2(), rng.uniform());
            let c = Vec3::new(2.0 + u.x, u.y - 0.5, w - 0.5) * 2.0;
            triangles.push([c, c + Vec3::X * 0.1, c + Vec3::Y * 0.1]);
        }
        let mut bvh = Bvh::build(&triangles).unwrap();
        let cwbvh = bvh.cwbvh.clone().unwrap();
        let mut missed_by_obvhs = 0;
        for isa in [Isa::Baseline, Isa::detect()] {
            bvh.isa = isa;
            for k in 0..200 {
                let gap = 1e-6 * (1.0 + k as f32 * 0.4);
                let u = rng.uniform2() * 1.6 - 0.8;
                let origin = Vec3::new(gap, u.x, u.y);
                let dir = Vec3::new(-1.0, 0.3 * (k % 5) as f32 - 0.6, 0.2).normalize();
                let hit = bvh.closest_hit(origin, dir, 0.0, f32::INFINITY);
                assert!(
                    hit.is_some_and(|h| h.triangle < 2),
                    "ray {k} ({isa:?}) missed the wall"
                );
                assert!(
                    bvh.occluded(origin, dir, 0.0, 1.0),
                    "shadow ray {k} ({isa:?})"
                );
                let mut hits = [None; PACKET];
                bvh.closest_hits(
                    &[origin; PACKET],
                    &[dir; PACKET],
                    0.0,
                    f32::INFINITY,
                    &mut hits,
                );
                assert!(
                    hits.iter().all(|h| h.is_some_and(|h| h.triangle < 2)),
                    "packet {k}"
                );
                let ray = make_ray(origin, dir, 0.0, f32::INFINITY);
                let hit = cwbvh.ray_traverse(ray, &mut RayHit::none(), |r, id| {
                    bvh.triangles[id].intersect(r)
                });
                missed_by_obvhs += u32::from(!hit);
            }
        }
        // The reference's leak is real: the negative case these rays are made for.
        assert!(
            missed_by_obvhs > 300,
            "obvhs missed {missed_by_obvhs} of 400"
        );
    }
}
