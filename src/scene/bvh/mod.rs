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

mod cwbvh;
#[cfg(test)]
mod tests;
mod wide;
use cwbvh::{any_hit, closest};
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
    /// What stops the segment `origin + t·dir`, `t` in `[tmin, tmax)`, in the tracer's own
    /// numbering, where each surface met is first offered to `pass` (in no particular order,
    /// each triangle once) and the segment goes on past those it lets through: one traversal
    /// that crosses panes, gathering their transmittance in `pass`, and stops at anything
    /// else. `guess` (or [`NO_OCCLUDER`]) is offered first.
    fn blocker_past(
        &self,
        origin: Vec3,
        dir: Vec3,
        segment: (f32, f32),
        guess: u32,
        pass: &mut dyn FnMut(&Hit) -> bool,
    ) -> Option<u32>;
    /// Whether [`Self::blocker_past`] finds a blocker, without a guess.
    #[inline(always)]
    fn occluded_past(
        &self,
        origin: Vec3,
        dir: Vec3,
        tmin: f32,
        tmax: f32,
        pass: &mut dyn FnMut(&Hit) -> bool,
    ) -> bool {
        self.blocker_past(origin, dir, (tmin, tmax), NO_OCCLUDER, pass)
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

    /// Whether anything lies on each open segment `origins[i] + t·dirs[i]`, `t` in
    /// `[tmin, tmaxes[i])`, into `blocked[i]` (at most [`PACKET`] rays), `guess` tested first
    /// as in [`Self::occluder`], and a primitive found to block one of them: the same answers
    /// as [`Self::occluded`], though a tracer may trace them together.
    #[inline(always)]
    fn occluders_each(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        tmin: f32,
        tmaxes: &[f32],
        guess: u32,
        blocked: &mut [bool],
    ) -> Option<u32> {
        let mut blocker = None;
        for (((&o, &d), &tmax), b) in origins.iter().zip(dirs).zip(tmaxes).zip(blocked) {
            let found = self.occluder(o, d, tmin, tmax, guess);
            *b = found.is_some();
            blocker = found.or(blocker);
        }
        blocker
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

    /// Keeps the blocker `found`, if any, as the next query's guess.
    #[inline(always)]
    fn remember(&self, found: Option<u32>) -> Option<u32> {
        if let Some(id) = found {
            self.last.set(id);
        }
        found
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

    /// The guess is the last blocker, as for [`Self::occluder`], tested on the whole packet
    /// first: a tile's shadow rays toward a shaded light mostly stop at the same triangle.
    #[inline(always)]
    fn occluders_each(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        tmin: f32,
        tmaxes: &[f32],
        _: u32,
        blocked: &mut [bool],
    ) -> Option<u32> {
        let guess = self.last.get();
        self.remember(
            self.tracer
                .occluders_each(origins, dirs, tmin, tmaxes, guess, blocked),
        )
    }

    /// The guess is the last blocker, as for [`Self::occluder`]: offered first, and never
    /// offered twice (a guess let through is skipped by the traversal).
    #[inline(always)]
    fn blocker_past(
        &self,
        origin: Vec3,
        dir: Vec3,
        segment: (f32, f32),
        _: u32,
        pass: &mut dyn FnMut(&Hit) -> bool,
    ) -> Option<u32> {
        self.remember(
            self.tracer
                .blocker_past(origin, dir, segment, self.last.get(), pass),
        )
    }

    /// The guess is always the last blocker (the renderer never has one of its own).
    #[inline(always)]
    fn occluder(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32, _: u32) -> Option<u32> {
        self.remember(
            self.tracer
                .occluder(origin, dir, tmin, tmax, self.last.get()),
        )
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
    fn occluders_each(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        tmin: f32,
        tmaxes: &[f32],
        guess: u32,
        blocked: &mut [bool],
    ) -> Option<u32> {
        Bvh::occluders_each(self, origins, dirs, tmin, tmaxes, guess, blocked)
    }

    #[inline(always)]
    fn blocker_past(
        &self,
        origin: Vec3,
        dir: Vec3,
        segment: (f32, f32),
        guess: u32,
        pass: &mut dyn FnMut(&Hit) -> bool,
    ) -> Option<u32> {
        Bvh::blocker_past(self, origin, dir, segment, guess, pass)
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
        self.occluders_each(origins, dirs, tmin, tmaxes, NO_OCCLUDER, blocked);
    }

    /// [`Self::occluded_each`] with triangle `guess` (BVH order, or [`NO_OCCLUDER`]) tested
    /// on every ray first, and a triangle found to block one of them, if any.
    #[inline(always)]
    pub fn occluders_each(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        tmin: f32,
        tmaxes: &[f32],
        guess: u32,
        blocked: &mut [bool],
    ) -> Option<u32> {
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
            let (found, blocker) = unsafe { wide.any_packet(&self.triangles, &rays, n, guess) };
            for (i, b) in blocked.iter_mut().enumerate().take(n) {
                *b = found & (1 << i) != 0;
            }
            return blocker;
        }
        let mut blocker = None;
        for i in 0..n {
            let found = self.occluder(origins[i], dirs[i], tmin, tmaxes[i], guess);
            blocked[i] = found.is_some();
            blocker = found.or(blocker);
        }
        blocker
    }

    /// Whether anything lies on the segment `origin + t·dir`, `t` in `[tmin, tmax)`.
    #[inline(always)]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> bool {
        self.occluder(origin, dir, tmin, tmax, NO_OCCLUDER)
            .is_some()
    }

    /// [`Tracer::blocker_past`]: `guess` (BVH order) first, then one any-hit traversal whose
    /// triangle test offers each hit on the segment to `pass` and answers "no hit" for those
    /// it lets through. The BVH holds each triangle once (no spatial splits), and a guess
    /// already offered is skipped, so each is offered once.
    pub fn blocker_past(
        &self,
        origin: Vec3,
        dir: Vec3,
        (tmin, tmax): (f32, f32),
        guess: u32,
        pass: &mut dyn FnMut(&Hit) -> bool,
    ) -> Option<u32> {
        let ray = make_ray(origin, dir, tmin, tmax);
        let distance = |r: &Ray, id: usize| match &self.cutouts {
            None => self.triangles[id].intersect(r),
            Some(c) => self.intersect_cutout(c, r, id),
        };
        let mut offered = NO_OCCLUDER;
        if (guess as usize) < self.triangles.len() {
            let t = distance(&ray, guess as usize);
            if t < tmax {
                if !pass(&self.hit(guess, t, &ray)) {
                    return Some(guess);
                }
                offered = guess;
            }
        }
        self.wide_any(&ray, |r, id| {
            let t = distance(r, id);
            if t < r.tmax && id as u32 != offered && !pass(&self.hit(id as u32, t, r)) {
                t
            } else {
                f32::INFINITY
            }
        })
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
