//! The acceleration structure: obvhs builds a CWBVH over every triangle, the triangles are
//! reordered once into BVH order so traversal reads them sequentially, and the tree is converted
//! once into portalview's own traversal layout (`wide`), which the renderer traces. obvhs's own
//! traversal of its CWBVH stays as the reference.

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

mod wide;
pub use wide::PACKET;
use wide::{MAX_TRIANGLES, WideBvh};

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
/// (`avx2_node_test_agrees_with_obvhs`).
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

/// The closest primitive along `ray` and its distance: obvhs's `CwBvh::ray_traverse` (through
/// its `traverse!` macro, with this module's node test), the reference that portalview's own
/// layout is tested and benchmarked against.
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
/// the first hit; the reference, as [`closest`].
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
    /// The closest hit of `origin + t·dir` with `t` in `[tmin, tmax)`.
    fn closest_hit(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit>;
    /// A primitive on the segment `origin + t·dir`, `t` in `[tmin, tmax)`, if any, in the
    /// tracer's own numbering; `guess` (such a number, or [`NO_OCCLUDER`]) is tested first.
    fn occluder(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32, guess: u32) -> Option<u32>;
    /// Whether anything lies on the segment `origin + t·dir`, `t` in `[tmin, tmax)`.
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
    /// `None` for an empty scene, where every ray misses: obvhs's tree, kept as the reference
    /// traversal.
    cwbvh: Option<CwBvh>,
    /// The same tree in the layout the renderer traverses.
    wide: Option<WideBvh>,
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
    /// More triangles than the traversal layout numbers.
    #[error("{count} triangles with an area: at most {MAX_TRIANGLES} can be traced")]
    TooMany { count: usize },
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
        if tris.len() >= MAX_TRIANGLES {
            return Err(BvhError::TooMany { count: tris.len() });
        }
        if tris.is_empty() {
            return Ok(Bvh {
                cwbvh: None,
                wide: None,
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
        let ordered: Vec<Triangle> = order.iter().map(|&i| tris[i as usize]).collect();
        let triangles = ordered.iter().map(RtTri::new).collect();
        let scene_index = order.iter().map(|&i| kept[i as usize]).collect();
        // After reordering, BVH primitive i is triangle i of `triangles`.
        cwbvh.primitive_indices = (0..order.len() as u32).collect();
        let wide = WideBvh::new(&cwbvh, &ordered);
        Ok(Bvh {
            cwbvh: Some(cwbvh),
            wide: Some(wide),
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

    /// The closest hit of `origin + t·dir` with `t` in `[tmin, tmax)`.
    #[inline(always)]
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        let ray = make_ray(origin, dir, tmin, tmax);
        let (id, t) = self.closest_id(Traversal::Wide, &ray)?;
        Some(self.hit(id, t, &ray))
    }

    /// The closest triangle (BVH order) along `ray` and its distance, by `traversal`.
    #[inline(always)]
    fn closest_id(&self, traversal: Traversal, ray: &Ray) -> Option<(u32, f32)> {
        match &self.cutouts {
            None => self.closest_by(traversal, ray, |r, id| self.triangles[id].intersect(r)),
            Some(c) => self.closest_by(traversal, ray, |r, id| self.intersect_cutout(c, r, id)),
        }
    }

    /// The closest triangle that `intersect` meets along `ray`, by `traversal`.
    #[inline(always)]
    fn closest_by(
        &self,
        traversal: Traversal,
        ray: &Ray,
        intersect: impl FnMut(&Ray, usize) -> f32,
    ) -> Option<(u32, f32)> {
        match traversal {
            Traversal::Wide => self.wide_closest(ray, intersect),
            Traversal::Cwbvh => closest(self.cwbvh.as_ref()?, self.isa, *ray, intersect),
        }
    }

    /// A triangle (BVH order) on `ray` by `traversal`: triangle `guess` if it is one, else the
    /// first the traversal finds.
    #[inline(always)]
    fn any_id(&self, traversal: Traversal, ray: &Ray, guess: u32) -> Option<u32> {
        match &self.cutouts {
            None => self.any_by(traversal, ray, guess, |r, id| {
                self.triangles[id].intersect(r)
            }),
            Some(c) => self.any_by(traversal, ray, guess, |r, id| {
                self.intersect_cutout(c, r, id)
            }),
        }
    }

    /// A triangle that `intersect` puts on `ray`: `guess` if it is one (a number past the
    /// triangles is none), else the first `traversal` finds.
    #[inline(always)]
    fn any_by(
        &self,
        traversal: Traversal,
        ray: &Ray,
        guess: u32,
        intersect: impl Fn(&Ray, usize) -> f32,
    ) -> Option<u32> {
        if (guess as usize) < self.triangles.len() && intersect(ray, guess as usize) < ray.tmax {
            return Some(guess);
        }
        match traversal {
            Traversal::Wide => self.wide_any(ray, intersect),
            Traversal::Cwbvh => any_hit(self.cwbvh.as_ref()?, self.isa, *ray, intersect),
        }
    }

    /// [`WideBvh::closest`] in this CPU's instruction set.
    #[inline(always)]
    fn wide_closest(
        &self,
        ray: &Ray,
        intersect: impl FnMut(&Ray, usize) -> f32,
    ) -> Option<(u32, f32)> {
        let wide = self.wide.as_ref()?;
        match self.isa {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: a BVH's `isa` is `Isa::detect()`, which is `Avx2` only where the CPU has it.
            #[allow(unsafe_code)]
            Isa::Avx2 => unsafe { wide_closest_avx2(wide, ray, intersect) },
            _ => wide.closest(ray, intersect),
        }
    }

    /// [`WideBvh::any`] in this CPU's instruction set.
    #[inline(always)]
    fn wide_any(&self, ray: &Ray, intersect: impl FnMut(&Ray, usize) -> f32) -> Option<u32> {
        let wide = self.wide.as_ref()?;
        match self.isa {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as in `wide_closest`.
            #[allow(unsafe_code)]
            Isa::Avx2 => unsafe { wide_any_avx2(wide, ray, intersect) },
            _ => wide.any(ray, intersect),
        }
    }

    /// The hit on BVH triangle `id` at distance `t` along `ray`.
    #[inline(always)]
    fn hit(&self, id: u32, t: f32, ray: &Ray) -> Hit {
        let (u, v, _) = self.triangles[id as usize].uvt(ray);
        Hit {
            t,
            triangle: self.scene_index[id as usize],
            bary: Vec2::new(u, v),
        }
    }

    /// [`Self::closest_hit`] of each ray `origins[i] + t·dirs[i]` into `hits[i]`. Two to
    /// [`PACKET`] rays are traced together where the CPU has AVX2 and no triangle is cut out
    /// ([`WideBvh::closest_packet`]); others one by one. Same answers, bit for bit.
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
        if let (Isa::Avx2, None, Some(wide), 2..=PACKET) = (self.isa, &self.cutouts, &self.wide, n)
        {
            let rays: [Ray; PACKET] = std::array::from_fn(|i| {
                let i = i.min(n - 1);
                make_ray(origins[i], dirs[i], tmin, tmax)
            });
            // SAFETY: a BVH's `isa` is `Isa::detect()`, which is `Avx2` only where the CPU has
            // AVX2, BMI1 and BMI2.
            #[allow(unsafe_code)]
            let found = unsafe { wide.closest_packet(&self.triangles, &rays, n) };
            for ((hit, found), ray) in hits.iter_mut().zip(found).zip(&rays).take(n) {
                *hit = found.map(|(id, t)| self.hit(id, t, ray));
            }
            return;
        }
        for i in 0..n {
            hits[i] = self.closest_hit(origins[i], dirs[i], tmin, tmax);
        }
    }

    /// Whether anything lies on each open segment `origins[i] + t·dirs[i]`, `t` in
    /// `[tmin, tmaxes[i])`, into `blocked[i]`: [`Self::occluded`] of each, traced together as
    /// for [`Self::closest_hits`].
    #[inline(always)]
    pub fn occluded_each(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        tmin: f32,
        tmaxes: &[f32],
        blocked: &mut [bool],
    ) {
        let n = origins
            .len()
            .min(dirs.len())
            .min(tmaxes.len())
            .min(blocked.len());
        #[cfg(target_arch = "x86_64")]
        if let (Isa::Avx2, None, Some(wide), 2..=PACKET) = (self.isa, &self.cutouts, &self.wide, n)
        {
            let rays: [Ray; PACKET] = std::array::from_fn(|i| {
                let i = i.min(n - 1);
                make_ray(origins[i], dirs[i], tmin, tmaxes[i])
            });
            // SAFETY: as in `closest_hits`.
            #[allow(unsafe_code)]
            let found = unsafe { wide.any_packet(&self.triangles, &rays, n) };
            for (i, b) in blocked.iter_mut().enumerate().take(n) {
                *b = found & (1 << i) != 0;
            }
            return;
        }
        for i in 0..n {
            blocked[i] = self.occluded(origins[i], dirs[i], tmin, tmaxes[i]);
        }
    }

    /// Whether anything lies on the segment `origin + t·dir`, `t` in `[tmin, tmax)`.
    #[inline(always)]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        self.occluder(origin, dir, tmin, tmax, NO_OCCLUDER)
            .is_some()
    }

    /// A triangle (BVH order) on the segment `origin + t·dir`, `t` in `[tmin, tmax)`:
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
        self.any_id(Traversal::Wide, &make_ray(origin, dir, tmin, tmax), guess)
    }

    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Bytes per triangle of what traversal reads: the nodes, the triangles laid out for the
    /// test, and their scene numbers (the CWBVH kept as the reference is not counted).
    pub fn bytes_per_triangle(&self) -> f64 {
        let nodes = self.wide.as_ref().map_or(0, WideBvh::bytes);
        let triangles = self.triangles.len() * (size_of::<RtTri>() + size_of::<u32>());
        (nodes + triangles) as f64 / self.triangles.len().max(1) as f64
    }

    /// The renderer's closest-hit traversal (`traversal`) with no other work, for benchmarks:
    /// the distance alone (no barycentrics, no cut-outs).
    #[inline(always)]
    pub fn raw_closest_t(
        &self,
        traversal: Traversal,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
    ) -> f32 {
        let ray = make_ray(origin, dir, tmin, tmax);
        self.closest_by(traversal, &ray, |r, id| self.triangles[id].intersect(r))
            .map_or(f32::INFINITY, |(_, t)| t)
    }

    /// Whether `traversal` finds a triangle on the segment, for benchmarks (no cut-outs, no
    /// guess).
    #[inline(always)]
    pub fn raw_occluded(
        &self,
        traversal: Traversal,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
    ) -> bool {
        let ray = make_ray(origin, dir, tmin, tmax);
        let tri = |r: &Ray, id: usize| self.triangles[id].intersect(r);
        self.any_by(traversal, &ray, NO_OCCLUDER, tri).is_some()
    }

    /// The closest hit by obvhs's own traversal of its CWBVH (with this module's node test):
    /// the reference that the layout's traversals are tested against.
    pub fn reference_closest_hit(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
    ) -> Option<Hit> {
        let ray = make_ray(origin, dir, tmin, tmax);
        let (id, t) = self.closest_id(Traversal::Cwbvh, &ray)?;
        Some(self.hit(id, t, &ray))
    }

    /// Occlusion by obvhs's own traversal, as [`Self::reference_closest_hit`].
    pub fn reference_occluded(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        let ray = make_ray(origin, dir, tmin, tmax);
        self.any_id(Traversal::Cwbvh, &ray, NO_OCCLUDER).is_some()
    }
}

/// Which tree a benchmark traverses: portalview's layout (what the renderer uses) or obvhs's
/// CWBVH through obvhs's traversal (the reference, and the renderer's before the layout).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Traversal {
    Wide,
    Cwbvh,
}

/// [`WideBvh::closest`] compiled for AVX2, where the closure is inlined into it.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,bmi1,bmi2,lzcnt,popcnt")]
fn wide_closest_avx2(
    wide: &WideBvh,
    ray: &Ray,
    intersect: impl FnMut(&Ray, usize) -> f32,
) -> Option<(u32, f32)> {
    // SAFETY: compiled for AVX2 and called only where the CPU has it (`Isa::Avx2`).
    #[allow(unsafe_code)]
    unsafe {
        wide.closest_avx2(ray, intersect)
    }
}

/// [`WideBvh::any`] compiled for AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,bmi1,bmi2,lzcnt,popcnt")]
fn wide_any_avx2(
    wide: &WideBvh,
    ray: &Ray,
    intersect: impl FnMut(&Ray, usize) -> f32,
) -> Option<u32> {
    // SAFETY: as in `wide_closest_avx2`.
    #[allow(unsafe_code)]
    unsafe {
        wide.any_avx2(ray, intersect)
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
    /// barycentrics; and occlusion, each ray with its own `tmax`): camera rays of up to eight
    /// consecutive jittered pixels in a built-in scene, short ones among them, and rays from
    /// random points in random directions of one octant, or of several. Not vacuous: most
    /// packets are traced together, most of their rays hit something, and both answers to
    /// occlusion are common.
    #[test]
    fn packets_answer_as_single_rays() {
        let scene = crate::scene::Scene::open("lampshade").unwrap();
        let bvh = &scene.geometry.bvh;
        let rays = scene.camera.rays(1.0);
        let mut rng = Rng::new(5, 0);
        let (mut together, mut hits, mut rays_traced, mut occluded) = (0, 0, 0, 0);
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
            together += u32::from(n >= 2);
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
            let tmaxes: [f32; PACKET] = std::array::from_fn(|i| {
                found[i].map_or(f32::INFINITY, |h| h.t * (0.5 + rng.uniform()))
            });
            let mut blocked = [false; PACKET];
            bvh.occluded_each(&origins[..n], &dirs[..n], 0.0, &tmaxes[..n], &mut blocked);
            for i in 0..n {
                let expected = bvh.occluded(origins[i], dirs[i], 0.0, tmaxes[i]);
                assert_eq!(blocked[i], expected, "packet {packet}, shadow ray {i}");
                occluded += u32::from(expected);
            }
        }
        assert!(
            together > 2000
                && hits > rays_traced / 2
                && occluded > rays_traced / 4
                && occluded < rays_traced * 3 / 4,
            "{together}, {hits} and {occluded} of {rays_traced}"
        );
    }

    /// Rays of the kinds a renderer traces and of the kinds that break traversals, in `bvh`'s
    /// scene: from random points in random directions; from points on triangles (as shading
    /// points start, `tmin` 0) in random directions, some stopping short; at triangles' edges
    /// and corners from random points (grazing); along axis-aligned walls (a direction
    /// component exactly 0 along the wall's normal) and exactly along the axes. Each as
    /// (origin, direction, tmax).
    fn probing_rays(bvh: &Bvh, count: usize, seed: u64) -> Vec<(Vec3, Vec3, f32)> {
        let mut rng = Rng::new(seed, 0);
        let tris = &bvh.triangles;
        let corners = |t: &RtTri| {
            let v0 = Vec3::from(t.v0);
            [v0, v0 - Vec3::from(t.e1), v0 + Vec3::from(t.e2)]
        };
        let (lo, hi) = tris
            .iter()
            .flat_map(corners)
            .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), v| {
                (lo.min(v), hi.max(v))
            });
        let (lo, hi) = (lo - (hi - lo) * 0.1, hi + (hi - lo) * 0.1);
        let walls: Vec<usize> = (0..tris.len())
            .filter(|&i| {
                let n = tris[i].ng.to_array();
                n.iter().filter(|&&c| c == 0.0).count() == 2
            })
            .collect();
        let mut rays = Vec::with_capacity(count);
        for k in 0..count {
            let u = Vec3::new(rng.uniform(), rng.uniform(), rng.uniform());
            let random_point = lo + (hi - lo) * u;
            let w = rng.uniform2();
            let random_dir = crate::sampling::sample_uniform_sphere(w);
            let tri = &tris[(rng.uniform() * tris.len() as f32) as usize % tris.len()];
            let [a, b, c] = corners(tri);
            let (s, t) = (rng.uniform(), rng.uniform());
            let on_triangle = if s + t > 1.0 {
                a + (b - a) * (1.0 - s) + (c - a) * (1.0 - t)
            } else {
                a + (b - a) * s + (c - a) * t
            };
            let tmax = if rng.uniform() < 0.3 {
                rng.uniform() * (hi - lo).length()
            } else {
                f32::INFINITY
            };
            let ray = match k % 6 {
                0 => (random_point, random_dir, tmax),
                1 => (on_triangle, random_dir, tmax),
                2 => {
                    // An edge or a corner of the triangle, from a random point.
                    let target = match (rng.uniform() * 4.0) as u32 {
                        0 => a + (b - a) * s,
                        1 => b + (c - b) * s,
                        2 => c + (a - c) * s,
                        _ => [a, b, c][(s * 3.0) as usize % 3],
                    };
                    (
                        random_point,
                        (target - random_point).normalize(),
                        f32::INFINITY,
                    )
                }
                3 if !walls.is_empty() => {
                    // In the plane of an axis-aligned wall, from a point on it.
                    let wall =
                        &tris[walls[(rng.uniform() * walls.len() as f32) as usize % walls.len()]];
                    let [a, b, c] = corners(wall);
                    let start = if s + t > 1.0 {
                        a
                    } else {
                        a + (b - a) * s + (c - a) * t
                    };
                    let normal = Vec3::from(wall.ng).signum().abs();
                    let d = random_dir * (Vec3::ONE - normal);
                    let d = if d == Vec3::ZERO {
                        Vec3::ONE - normal
                    } else {
                        d
                    };
                    (start, d.normalize(), tmax)
                }
                4 => {
                    // Exactly along an axis, from a point on a triangle or anywhere.
                    let axis = [Vec3::X, Vec3::Y, Vec3::Z][(s * 3.0) as usize % 3];
                    let sign = if t < 0.5 { -1.0 } else { 1.0 };
                    let origin = if w.x < 0.5 { on_triangle } else { random_point };
                    (origin, axis * sign, tmax)
                }
                _ => (on_triangle, (random_point - on_triangle).normalize(), tmax),
            };
            if ray.1.is_finite() && ray.1 != Vec3::ZERO {
                rays.push(ray);
            }
        }
        rays
    }

    /// The closest hit by testing every triangle: the least (distance, triangle) pair, in BVH
    /// numbering.
    fn brute_closest(bvh: &Bvh, origin: Vec3, dir: Vec3, tmax: f32) -> Option<(u32, f32)> {
        let ray = make_ray(origin, dir, 0.0, tmax);
        let mut best: Option<(u32, f32)> = None;
        for (id, tri) in bvh.triangles.iter().enumerate() {
            let t = tri.intersect(&ray);
            let closer = match best {
                None => t < tmax,
                Some((b, tb)) => t < tb || (t == tb && (id as u32) < b),
            };
            if closer {
                best = Some((id as u32, t));
            }
        }
        best
    }

    /// Disagreements of the layout with obvhs's traversal on `rays`, each checked against
    /// brute force: the closest-hit and occlusion answers that differed from obvhs's; of
    /// those, how many the brute force contradicts; and of these, how many only where the
    /// triangle test's distance is rounding noise (its hit outside the triangle's box).
    fn compare_with_reference(bvh: &Bvh, rays: &[(Vec3, Vec3, f32)]) -> (u32, u32, u32) {
        let (mut differ, mut wrong, mut noise) = (0, 0, 0);
        for &(origin, dir, tmax) in rays {
            let ray = make_ray(origin, dir, 0.0, tmax);
            let ours = bvh.closest_id(Traversal::Wide, &ray);
            let reference = bvh.closest_id(Traversal::Cwbvh, &ray);
            // A tie (two triangles at one distance) may go either way in obvhs's order.
            let same = match (ours, reference) {
                (Some((a, ta)), Some((b, tb))) => {
                    ta.to_bits() == tb.to_bits()
                        && (a == b || bvh.triangles[a as usize].intersect(&ray) == ta)
                }
                (None, None) => true,
                _ => false,
            };
            if !same {
                differ += 1;
                let brute = brute_closest(bvh, origin, dir, tmax);
                if ours != brute {
                    // Right only if the triangle test put the brute force's hit outside that
                    // triangle's own box (with the layout's margin): a ray grazing a vertex
                    // nearly in the triangle's plane, whose distance is rounding noise.
                    let (id, t) = brute.unwrap_or((0, f32::INFINITY));
                    let tri = &bvh.triangles[id as usize];
                    let corners = [tri.v0, tri.v0 - tri.e1, tri.v0 + tri.e2];
                    let lo = corners.iter().fold(Vec3A::INFINITY, |a, &v| a.min(v));
                    let hi = corners.iter().fold(Vec3A::NEG_INFINITY, |a, &v| a.max(v));
                    let (lo, hi) = wide::pad(lo, hi);
                    let p = Vec3A::from(origin + dir * t);
                    if p.cmplt(lo).any() || p.cmpgt(hi).any() {
                        noise += 1;
                    } else {
                        wrong += 1;
                    }
                }
            }
            let occluded = bvh.occluded(origin, dir, 0.0, tmax);
            if occluded != bvh.reference_occluded(origin, dir, 0.0, tmax) {
                differ += 1;
                let brute = bvh.triangles.iter().any(|t| t.intersect(&ray) < tmax);
                wrong += u32::from(occluded != brute);
            }
        }
        (differ, wrong, noise)
    }

    /// portalview's traversal layout answers as obvhs's traversal of its own tree, hit for hit,
    /// on a million rays per built-in scene (and on the fuzz corpus's scenes that load): random
    /// rays, rays that start on surfaces, rays grazing triangles' edges and corners, rays
    /// along axis-aligned walls and exactly along the axes. Where the two differ, testing every
    /// triangle decides, and the layout must be right; they may differ only there, and rarely
    /// (obvhs's byte-quantised boxes are larger, but its slab test has no margin for rounding).
    /// Not vacuous: hits, misses and occlusion are all common, and the negative case below
    /// shows that these rays probe the boxes' faces.
    #[test]
    fn layout_answers_as_obvhs() {
        let corpus = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz_corpus");
        let mut scenes: Vec<String> = crate::asset::builtin::NAMES.map(String::from).to_vec();
        for entry in std::fs::read_dir(&corpus).unwrap() {
            let path = entry.unwrap().path();
            if path.to_string_lossy().ends_with(".loads.glb") {
                scenes.push(path.to_string_lossy().into_owned());
            }
        }
        for (k, name) in scenes.iter().enumerate() {
            let scene = crate::scene::Scene::open(name).unwrap();
            // Without the scene's cut-outs, which brute force does not know.
            let positions: Vec<[Vec3; 3]> = scene.geometry.triangles.iter().map(|t| t.p).collect();
            let bvh = &Bvh::build(&positions).unwrap();
            let count = if k < crate::asset::builtin::NAMES.len() {
                1_000_000
            } else {
                100_000
            };
            let rays = probing_rays(bvh, count, k as u64);
            let (differ, wrong, noise) = compare_with_reference(bvh, &rays);
            eprintln!("{name}: {differ} differ from obvhs, {wrong} wrong, {noise} on noise");
            assert_eq!(
                wrong, 0,
                "{name}: {wrong} wrong answers ({differ} differ from obvhs)"
            );
            assert!(
                noise * 100_000 <= rays.len() as u32,
                "{name}: {noise} on noise"
            );
            // The baseline instruction set gives the same answers, bit for bit.
            let mut baseline = Bvh::build(&positions).unwrap();
            baseline.isa = Isa::Baseline;
            for &(o, d, tmax) in rays.iter().step_by(7) {
                assert_eq!(
                    baseline.closest_hit(o, d, 0.0, tmax),
                    bvh.closest_hit(o, d, 0.0, tmax)
                );
                assert_eq!(
                    baseline.occluded(o, d, 0.0, tmax),
                    bvh.occluded(o, d, 0.0, tmax)
                );
            }
            let hits = rays
                .iter()
                .filter(|&&(o, d, tmax)| bvh.closest_hit(o, d, 0.0, tmax).is_some())
                .count();
            assert!(
                hits > rays.len() / 5 && hits < rays.len() * 19 / 20,
                "{name}: {hits} hits of {}",
                rays.len()
            );
        }
    }

    /// A ray whose direction has −0.0 components, made directly (`make_ray` turns them into
    /// +0.0, so the renderer's rays never have them): the layout picks each axis's near face by
    /// the inverse's sign (−∞ here), so the ray, within the boxes' x and y slabs, meets the
    /// quad below it; picked by `d < 0` (false for −0.0), the near face was the lower one, its
    /// distance +∞, and the ray missed every box (issue 40).
    #[test]
    fn a_direction_of_negative_zeros_finds_its_hit() {
        let (a, b, c, d) = (
            Vec3::new(-1.0, -1.0, 0.0),
            Vec3::new(1.0, -1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
            Vec3::new(-1.0, 1.0, 0.0),
        );
        let bvh = Bvh::build(&[[a, b, c], [a, c, d]]).unwrap();
        let wide = bvh.wide.as_ref().unwrap();
        let ray = Ray::new(
            Vec3A::new(0.25, 0.5, 2.0),
            Vec3A::new(-0.0, -0.0, -1.0),
            0.0,
            f32::INFINITY,
        );
        let intersect = |r: &Ray, id: usize| bvh.triangles[id].intersect(r);
        let hit = wide.closest(&ray, intersect);
        assert!(hit.is_some_and(|(_, t)| (t - 2.0).abs() < 1e-6), "{hit:?}");
        assert!(wide.any(&ray, intersect).is_some());
        #[cfg(target_arch = "x86_64")]
        if Isa::Avx2.available() {
            // SAFETY: the CPU has AVX2.
            #[allow(unsafe_code)]
            let (closest, any) = unsafe {
                (
                    wide.closest_avx2(&ray, intersect),
                    wide.any_avx2(&ray, intersect),
                )
            };
            assert_eq!(closest, hit);
            assert!(any.is_some());
        }
    }

    /// The negative case of `layout_answers_as_obvhs`: with every box moved inward by a
    /// thousandth of its size (a little more than its margin for the triangle test's rounding), rays that graze the boxes' faces (edges, corners, walls) miss
    /// triangles, and the comparison finds it.
    #[test]
    fn a_layout_with_shrunk_boxes_is_caught() {
        let scene = crate::scene::Scene::open("fig8a").unwrap();
        let mut bvh = Bvh::build(
            &scene
                .geometry
                .triangles
                .iter()
                .map(|t| t.p)
                .collect::<Vec<_>>(),
        )
        .unwrap();
        let rays = probing_rays(&bvh, 20_000, 1);
        assert_eq!(compare_with_reference(&bvh, &rays).1, 0);
        bvh.wide.as_mut().unwrap().shrink(1e-3);
        let (differ, wrong, _) = compare_with_reference(&bvh, &rays);
        assert!(wrong > 20, "{wrong} wrong, {differ} differ");
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
