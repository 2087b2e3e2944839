//! obvhs's own traversal of its CWBVH, with portalview's node test: the reference that the
//! traversal layout (`wide`) is tested and benchmarked against.

use super::*;

/// obvhs's lower bound on a child's entry distance (`cwbvh::node::EPSILON`, crate-private).
/// Its own node test enters no child nearer than this, absolute: a ray that starts within
/// 1e-4 of a wall and heads into it would pass through. The node tests here bound the entry
/// distance by the ray's own `tmin` instead; they agree with obvhs's for rays whose `tmin` is
/// this (the tests compare them so).
#[cfg(test)]
pub(super) const NODE_EPSILON: f32 = 0.0001;

/// The children of `node` that `ray` enters, as obvhs's traversal wants them: obvhs's node
/// test (`CwBvhNode::intersect_ray_basic`) with the entry distance bounded by `ray.tmin`
/// rather than obvhs's absolute 1e-4, or, where the CPU has AVX2, [`node_hits_avx2`], which
/// gives the same mask.
#[inline(always)]
#[allow(unsafe_code)]
pub(super) fn node_hits(isa: Isa, node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
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
pub(super) fn node_hits_scalar(node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
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
pub(super) fn node_hits_avx2(node: &CwBvhNode, ray: &Ray, oct_inv4: u32) -> u32 {
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
pub(super) fn child_hits_avx2(node: &CwBvhNode, ray: &Ray, tmax: f32) -> u32 {
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
pub(super) fn closest(
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
pub(super) fn any_hit(
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
