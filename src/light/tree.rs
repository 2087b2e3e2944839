//! Which light a shading point samples (`docs/method.md` §10): a tree of bounds over the lights
//! (Conty Estevez & Kulla 2018; pbrt-v4's `BVHLightSampler`) whose bounds know the portals.
//!
//! Each light is a leaf holding one or more *parts*, each a box, a cone of emission directions
//! and an intensity. A light without portals (or under the light strategy, which ignores
//! them) has one part: itself. A light behind portals has one part per portal, the portal's
//! polygon emitting into its front with the light's flux through it (its `1 − alpha` share),
//! one for its enclosure (the light's `1 − alpha` share, at points behind all its portals,
//! where the estimator samples the light itself, inside the box where its rays first meet the
//! enclosure's walls), and one part for itself with its `alpha` share: any point the light can
//! reach keeps a
//! positive probability, through a portal's part or through the light's own, so a misplaced
//! portal costs variance, never bias. The environment behind windows is a leaf of its
//! windows in the same way; its `alpha` share, and directional lamps, stand beside the tree,
//! and so do the enclosures' parts, each evaluated exactly where it counts.
//!
//! A node's importance at a point `x` with normal `n` is pbrt-v4's `LightBounds::Importance`:
//! intensity × the cosine of the angle by which the point lies outside the emission cone,
//! × the cosine of the angle between `n` and the box, over the squared distance (clamped to
//! the box's radius). It is zero only where no point of the box can send light to `x` along
//! a direction in the cone, above the surface: the picks are exact and conservative.

use arrayvec::ArrayVec;
use glam::{Quat, Vec2, Vec3};

use super::LightSet;
use super::area::{AreaLight, luminance};
use super::environment::Environment;
use crate::asset::desc::LampKind;
use crate::sampling::ONE_BELOW;
use crate::sampling::polygon::{ConvexPolygon, Plane};

/// What a pick chose: an area light or a lamp, by index in its own list, or the environment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PickedLight {
    Area(usize),
    Lamp(usize),
    Environment,
}

/// Where light may come from: a box, the cone of directions it leaves in, and its intensity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightBounds {
    pub lo: Vec3,
    pub hi: Vec3,
    /// The axis of the cone holding the emitting surfaces' normals (a spot's axis).
    pub axis: Vec3,
    /// `cos θ_o`: every normal lies within `θ_o` of the axis (−1: any direction).
    pub cos_o: f32,
    /// `cos θ_e`: light leaves within `θ_e` of a normal (0 for a surface, a spot's outer cone).
    pub cos_e: f32,
    /// Luminance intensity on the axis, W/sr: `L · A` for a surface, `Φ / π` for the flux
    /// `Φ` through a portal.
    pub intensity: f32,
    /// Emits on both sides of its normals.
    pub two_sided: bool,
    /// Reaches only points inside this box (a light's own enclosure, [`enclosure_bounds`]).
    pub within: Option<(Vec3, Vec3)>,
}

/// `√max(0, x)`.
fn safe_sqrt(x: f32) -> f32 {
    x.max(0.0).sqrt()
}

/// `cos(max(0, θ_a − θ_b))` from the sines and cosines of `θ_a, θ_b` in [0, π].
#[inline(always)]
fn cos_sub_clamped((sin_a, cos_a): (f32, f32), (sin_b, cos_b): (f32, f32)) -> f32 {
    if cos_a > cos_b {
        1.0
    } else {
        cos_a * cos_b + sin_a * sin_b
    }
}

/// `sin(max(0, θ_a − θ_b))`, as [`cos_sub_clamped`].
#[inline(always)]
fn sin_sub_clamped((sin_a, cos_a): (f32, f32), (sin_b, cos_b): (f32, f32)) -> f32 {
    if cos_a > cos_b {
        0.0
    } else {
        sin_a * cos_b - cos_a * sin_b
    }
}

impl LightBounds {
    /// The importance of these bounds at `x` for a surface with unit normal `n` facing the
    /// side light is gathered from (`Vec3::ZERO`: no surface). Zero only where no direction
    /// from the box within the emission cone reaches `x` from above the surface.
    #[inline(always)]
    pub fn importance(&self, x: Vec3, n: Vec3) -> f32 {
        if self.intensity <= 0.0 {
            return 0.0;
        }
        if let Some((lo, hi)) = self.within
            && !(x.cmpge(lo).all() && x.cmple(hi).all())
        {
            return 0.0;
        }
        let centre = 0.5 * (self.lo + self.hi);
        let r2 = (0.5 * (self.hi - self.lo)).length_squared();
        let to_x = x - centre;
        let d2 = to_x.length_squared();
        // The directions from the box to x lie within θ_b of the direction from its centre.
        let (sin_b, cos_b) = if d2 <= r2 {
            (0.0, -1.0)
        } else {
            let sin2 = r2 / d2;
            (sin2.sqrt(), safe_sqrt(1.0 - sin2))
        };
        let wi = if d2 > 0.0 {
            to_x / d2.sqrt()
        } else {
            Vec3::ZERO
        };
        let mut cos_w = self.axis.dot(wi);
        if self.two_sided {
            cos_w = cos_w.abs();
        }
        let w = (safe_sqrt(1.0 - cos_w * cos_w), cos_w);
        let o = (safe_sqrt(1.0 - self.cos_o * self.cos_o), self.cos_o);
        // The angle from the cone to x, less the box's spread.
        let x_angle = (sin_sub_clamped(w, o), cos_sub_clamped(w, o));
        let cos_p = cos_sub_clamped(x_angle, (sin_b, cos_b));
        if cos_p <= self.cos_e {
            return 0.0;
        }
        let mut importance = self.intensity * cos_p / d2.max(r2);
        if n != Vec3::ZERO {
            let cos_i = -wi.dot(n);
            let cos_pi = cos_sub_clamped((safe_sqrt(1.0 - cos_i * cos_i), cos_i), (sin_b, cos_b));
            importance *= cos_pi.max(0.0);
        }
        if importance.is_finite() {
            importance.clamp(0.0, 1e30)
        } else {
            // An overflow (a point at a point lamp) is not a reason to drop a light; kept far
            // below f32::MAX so that sums of a few stay finite.
            1e30
        }
    }

    /// Bounds holding both, the intensities summed.
    pub fn union(&self, other: &LightBounds) -> LightBounds {
        let (axis, cos_o) = cone_union((self.axis, self.cos_o), (other.axis, other.cos_o));
        LightBounds {
            lo: self.lo.min(other.lo),
            hi: self.hi.max(other.hi),
            axis,
            cos_o,
            cos_e: self.cos_e.min(other.cos_e),
            intensity: self.intensity + other.intensity,
            two_sided: self.two_sided || other.two_sided,
            within: self
                .within
                .zip(other.within)
                .map(|((a, b), (c, d))| (a.min(c), b.max(d))),
        }
    }

    fn centroid(&self) -> Vec3 {
        0.5 * (self.lo + self.hi)
    }
}

/// The smallest cone (axis, `cos θ`) holding two cones (pbrt-v4's `Union(DirectionCone)`).
fn cone_union((wa, cos_a): (Vec3, f32), (wb, cos_b): (Vec3, f32)) -> (Vec3, f32) {
    let (theta_a, theta_b) = (cos_a.clamp(-1.0, 1.0).acos(), cos_b.clamp(-1.0, 1.0).acos());
    let theta_d = wa.angle_between(wb);
    if (theta_d + theta_b).min(std::f32::consts::PI) <= theta_a {
        return (wa, cos_a);
    }
    if (theta_d + theta_a).min(std::f32::consts::PI) <= theta_b {
        return (wb, cos_b);
    }
    let theta_o = 0.5 * (theta_a + theta_d + theta_b);
    let whole = (wa, -1.0);
    if theta_o >= std::f32::consts::PI {
        return whole;
    }
    let axis = wa.cross(wb);
    if axis.length_squared() == 0.0 {
        return whole;
    }
    let w = Quat::from_axis_angle(axis.normalize(), theta_o - theta_a) * wa;
    (w.normalize(), theta_o.cos())
}

/// The `i`-th of `n` points of a Hammersley set in the unit square.
fn hammersley(i: u32, n: u32) -> Vec2 {
    Vec2::new(
        (i as f32 + 0.5) / n as f32,
        (i.reverse_bits() as f64 / 4_294_967_296.0) as f32,
    )
}

/// A light's own bounds: its triangles' box, the cone of their front normals, `L · A`.
pub fn area_light_bounds(light: &AreaLight, share: f32) -> LightBounds {
    let (mut lo, mut hi) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    let mut cone: Option<(Vec3, f32)> = None;
    for [a, b, c] in light.triangles() {
        lo = lo.min(a).min(b).min(c);
        hi = hi.max(a).max(b).max(c);
        let n = (b - a).cross(c - a).normalize_or_zero();
        if n != Vec3::ZERO {
            cone = Some(cone.map_or((n, 1.0), |k| cone_union(k, (n, 1.0))));
        }
    }
    let (axis, cos_o) = cone.unwrap_or((Vec3::Y, -1.0));
    LightBounds {
        lo,
        hi,
        axis,
        cos_o,
        cos_e: 0.0,
        intensity: share * luminance(light.radiance) * light.area(),
        two_sided: light.double_sided,
        within: None,
    }
}

/// How much an enclosure's box is grown on each side, as a share of its diagonal.
const ENCLOSURE_PAD: f32 = 1e-3;

/// A light behind portals as it lights its own enclosure (a lampshade's inside, a can's
/// walls): the light's own bounds with its `1 − alpha` share, reaching only points in
/// `measured` (the box where the light's rays meet its enclosure, `scene::enclosure`), else
/// in the box around the light and its portals. There the estimator samples the light
/// itself, past the portals, and the portals' parts are 0 (the points are behind them). The
/// importance is the light's own, not that of the larger box: a shade's outside lies in the
/// box too, and there the light is behind the surface, which only its own box can tell.
pub fn enclosure_bounds(
    light: &AreaLight,
    portals: &[&ConvexPolygon],
    share: f32,
    measured: Option<(Vec3, Vec3)>,
) -> LightBounds {
    let own = area_light_bounds(light, share);
    let (lo, hi) = portals
        .iter()
        .flat_map(|p| p.vertices())
        .fold((own.lo, own.hi), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    let (lo, hi) = measured.map_or((lo, hi), |(a, b)| (lo.min(a), hi.max(b)));
    // Grown a little: the enclosure's walls often lie on the box's faces (a can's sides
    // under its portal's edges), and their points fall either side of them by rounding.
    let pad = Vec3::splat(ENCLOSURE_PAD * (hi - lo).length());
    LightBounds {
        within: Some((lo - pad, hi + pad)),
        ..own
    }
}

/// The luminance flux from `light` through `portal` from its back to its front, occluders
/// ignored: `L ∫∫ cos θ_l cos θ_p / r² dA_p dA_l`, by a fixed quadrature (1024 pairs of
/// points), never more than the light emits.
pub fn flux_through(light: &AreaLight, portal: &ConvexPolygon) -> f32 {
    const N: u32 = 32;
    let n_p = portal.normal();
    let mut sum = 0.0f64;
    for i in 0..N {
        let Some(y) = light.sample_point(hammersley(i, N)) else {
            continue;
        };
        for j in 0..N {
            let z = portal.sample_uniform(hammersley(j, N));
            let v = z - y.p;
            let r2 = v.length_squared();
            if r2 <= 0.0 {
                continue;
            }
            let w = v / r2.sqrt();
            let cos_l = if light.double_sided {
                y.n.dot(w).abs()
            } else {
                y.n.dot(w).max(0.0)
            };
            sum += f64::from(cos_l * n_p.dot(w).max(0.0) / r2);
        }
    }
    let mean = (sum / f64::from(N * N)) as f32;
    let flux = luminance(light.radiance) * light.area() * portal.area() * mean;
    let sides = if light.double_sided { 2.0 } else { 1.0 };
    flux.min(std::f32::consts::PI * luminance(light.radiance) * light.area() * sides)
}

/// `∫ Y(L(ω)) max(0, ω·m) dω` over the sphere (`m = 0`: no cosine), by 4096 of the
/// environment's own samples, which find its sun.
fn environment_integral(environment: &Environment, m: Option<Vec3>) -> f32 {
    const N: u32 = 4096;
    let mut sum = 0.0f64;
    for i in 0..N {
        let Some((w, pdf)) = environment.sample(hammersley(i, N)) else {
            continue;
        };
        if pdf <= 0.0 {
            continue;
        }
        let cos = m.map_or(1.0, |m| w.dot(m).max(0.0));
        sum += f64::from(luminance(environment.radiance(w)) * cos / pdf);
    }
    (sum / f64::from(N)) as f32
}

/// An emitter beside the tree: its importance does not fall off with distance.
#[derive(Clone, Copy, Debug)]
enum Infinite {
    /// The environment's share not bounded by windows: a constant irradiance.
    Environment { irradiance: f32 },
    /// A directional lamp: its irradiance on a surface facing it, `E⊥ · cos`.
    Directional {
        lamp: usize,
        irradiance: f32,
        wi: Vec3,
    },
}

impl Infinite {
    fn light(&self) -> PickedLight {
        match *self {
            Infinite::Environment { .. } => PickedLight::Environment,
            Infinite::Directional { lamp, .. } => PickedLight::Lamp(lamp),
        }
    }

    #[inline(always)]
    fn importance(&self, n: Vec3) -> f32 {
        match *self {
            Infinite::Environment { irradiance } => irradiance,
            Infinite::Directional { irradiance, wi, .. } => {
                if n == Vec3::ZERO {
                    irradiance
                } else {
                    irradiance * n.dot(wi).max(0.0)
                }
            }
        }
    }
}

/// A node of the tree, in depth-first order: an interior node's first child follows it.
#[derive(Clone, Copy, Debug)]
struct Node {
    /// The union of every part below.
    bounds: LightBounds,
    kind: NodeKind,
}

#[derive(Clone, Copy, Debug)]
enum NodeKind {
    /// An index into `LightTree::leaves`.
    Leaf(u32),
    /// The index of the second child.
    Interior(u32),
}

/// A light in the tree: its parts, and the path from the root to it.
#[derive(Clone, Debug)]
struct Leaf {
    light: PickedLight,
    parts: std::ops::Range<usize>,
    /// Bit `k` set: the second child at depth `k`.
    trail: u64,
    depth: u32,
}

/// What a light contributes to the tree: its parts (a light with none is never picked there).
pub struct TreeLight {
    pub light: PickedLight,
    pub parts: Vec<LightBounds>,
    /// Its portals' planes (positive in front): its enclosure's parts count only behind all.
    pub behind: ArrayVec<Plane, { super::MAX_TERMS }>,
}

/// A light's enclosure part (`within` a box) beside the tree, with its portals' planes.
#[derive(Clone, Debug)]
struct Enclosure {
    light: PickedLight,
    bounds: LightBounds,
    behind: ArrayVec<Plane, { super::MAX_TERMS }>,
}

impl Enclosure {
    /// The part's importance where `x` is behind all the portals, as the estimator's
    /// `Region::Behind` (not strictly in front of the portal's plane); 0 elsewhere.
    #[inline(always)]
    fn importance(&self, x: Vec3, n: Vec3) -> f32 {
        let w = self.bounds.importance(x, n);
        if w > 0.0 && self.behind.iter().any(|p| p.signed_distance(x) > 0.0) {
            0.0
        } else {
            w
        }
    }
}

/// The lights under their bounds, and the emitters beside them.
#[derive(Clone, Debug, Default)]
pub struct LightTree {
    nodes: Vec<Node>,
    leaves: Vec<Leaf>,
    parts: Vec<LightBounds>,
    /// The leaf of each area light, lamp, and of the environment, if in the tree.
    area_leaf: Vec<Option<u32>>,
    lamp_leaf: Vec<Option<u32>>,
    environment_leaf: Option<u32>,
    /// The enclosures' parts (`within` a box), beside the tree: each is evaluated exactly at
    /// the point, not through the union bounds of the subtrees above a leaf, which are as
    /// loose as the room around it where the enclosure's light is the brightest by far.
    enclosures: Vec<Enclosure>,
    infinite: Vec<Infinite>,
    /// The scene's only emitter, when it has one: picked with probability 1.
    only: Option<PickedLight>,
}

/// How each light's parts are made.
pub struct TreeInputs<'a> {
    /// Whether portals and windows bound their lights (not under the light strategy).
    pub portal_aware: bool,
    /// The portals each area light's estimator uses, and its alpha.
    pub portals_of: &'a [ArrayVec<usize, { super::MAX_TERMS }>],
    pub alpha_of: &'a [f32],
    /// The environment's alpha through its windows.
    pub environment_alpha: f32,
}

impl LightTree {
    /// The tree over `scene`'s lights.
    pub fn new(scene: &impl LightSet, inputs: &TreeInputs) -> Self {
        // One emitter: nothing to bound (a renderer builds this per pass; the flux and sky
        // integrals below would cost a window scene a millisecond each time).
        let emitters = scene.lights().len() + scene.lamps().len();
        let only = match (emitters, scene.environment()) {
            (1, None) if scene.lamps().is_empty() => Some(PickedLight::Area(0)),
            (1, None) => Some(PickedLight::Lamp(0)),
            (0, Some(_)) => Some(PickedLight::Environment),
            _ => None,
        };
        if only.is_some() {
            return LightTree {
                only,
                ..LightTree::default()
            };
        }
        let mut lights: Vec<TreeLight> = Vec::new();
        let mut infinite = Vec::new();
        for (i, light) in scene.lights().iter().enumerate() {
            let portals = inputs.portals_of.get(i).map_or(&[][..], |p| &p[..]);
            let alpha = inputs.alpha_of.get(i).copied().unwrap_or(1.0);
            let mut parts = Vec::new();
            if inputs.portal_aware && !portals.is_empty() {
                if alpha < 1.0 {
                    let polygons: Vec<&ConvexPolygon> = portals
                        .iter()
                        .map(|&j| &scene.portals()[j].polygon)
                        .collect();
                    for polygon in &polygons {
                        let flux = (1.0 - alpha) * flux_through(light, polygon);
                        parts.push(portal_bounds(light, polygon, flux / std::f32::consts::PI));
                    }
                    parts.push(enclosure_bounds(
                        light,
                        &polygons,
                        1.0 - alpha,
                        scene.enclosure(i),
                    ));
                }
                if alpha > 0.0 {
                    parts.push(area_light_bounds(light, alpha));
                }
            } else {
                parts.push(area_light_bounds(light, 1.0));
            }
            lights.push(TreeLight {
                light: PickedLight::Area(i),
                parts,
                behind: portals
                    .iter()
                    .map(|&j| scene.portals()[j].planes.portal_plane())
                    .collect(),
            });
        }
        for (k, lamp) in scene.lamps().iter().enumerate() {
            let intensity = luminance(lamp.scale);
            let point = |axis, cos_o, cos_e| LightBounds {
                lo: lamp.position,
                hi: lamp.position,
                axis,
                cos_o,
                cos_e,
                intensity,
                two_sided: false,
                within: None,
            };
            let part = match lamp.kind {
                LampKind::Point => point(Vec3::Y, -1.0, 0.0),
                LampKind::Spot { .. } => point(lamp.direction, 1.0, lamp.cos_outer()),
                LampKind::Directional => {
                    infinite.push(Infinite::Directional {
                        lamp: k,
                        irradiance: intensity,
                        wi: -lamp.direction,
                    });
                    continue;
                }
            };
            lights.push(TreeLight {
                light: PickedLight::Lamp(k),
                parts: vec![part],
                behind: ArrayVec::new(),
            });
        }
        if let Some(environment) = scene.environment() {
            let windows = scene.windows();
            let alpha = if inputs.portal_aware && !windows.is_empty() {
                inputs.environment_alpha
            } else {
                1.0
            };
            if alpha < 1.0 {
                let parts = windows
                    .iter()
                    .map(|w| {
                        // The flux through the window from the sky beyond it, over π.
                        let e = environment_integral(environment, Some(-w.polygon.normal()));
                        let intensity = (1.0 - alpha) * w.polygon.area() * e / std::f32::consts::PI;
                        polygon_bounds(&w.polygon, intensity)
                    })
                    .collect();
                lights.push(TreeLight {
                    light: PickedLight::Environment,
                    parts,
                    behind: ArrayVec::new(),
                });
            }
            if alpha > 0.0 {
                // A uniform sky of radiance L gives πL, a quarter of ∫ L dω, on a surface.
                let irradiance = alpha * 0.25 * environment_integral(environment, None);
                infinite.push(Infinite::Environment { irradiance });
            }
        }
        Self::from_lights(lights, infinite, scene.lights().len(), scene.lamps().len())
    }

    /// A tree over `lights` given with their parts, nothing beside it: tests build trees with
    /// deliberately wrong bounds to show that the renderer's images detect them.
    pub fn from_parts(lights: Vec<TreeLight>, area_lights: usize, lamps: usize) -> Self {
        Self::from_lights(lights, Vec::new(), area_lights, lamps)
    }

    /// The tree over `lights`, with `infinite` beside it.
    fn from_lights(
        lights: Vec<TreeLight>,
        infinite: Vec<Infinite>,
        area_lights: usize,
        lamps: usize,
    ) -> Self {
        let mut tree = LightTree {
            area_leaf: vec![None; area_lights],
            lamp_leaf: vec![None; lamps],
            infinite,
            ..LightTree::default()
        };
        let mut entries: Vec<(PickedLight, std::ops::Range<usize>, LightBounds)> = Vec::new();
        let mut with_parts: Vec<PickedLight> = Vec::new();
        for light in lights {
            if !light.parts.is_empty() {
                with_parts.push(light.light);
            }
            let (enclosures, parts): (Vec<LightBounds>, Vec<LightBounds>) =
                light.parts.into_iter().partition(|p| p.within.is_some());
            tree.enclosures
                .extend(enclosures.into_iter().map(|bounds| Enclosure {
                    light: light.light,
                    bounds,
                    behind: light.behind.clone(),
                }));
            let Some(first) = parts.first() else {
                continue;
            };
            let union = parts[1..].iter().fold(*first, |u, p| u.union(p));
            let start = tree.parts.len();
            tree.parts.extend(parts);
            entries.push((light.light, start..tree.parts.len(), union));
        }
        let mut emitters: Vec<PickedLight> = Vec::new();
        for light in with_parts
            .into_iter()
            .chain(tree.infinite.iter().map(Infinite::light))
        {
            if !emitters.contains(&light) {
                emitters.push(light);
            }
        }
        if let [only] = emitters[..] {
            tree.only = Some(only);
        }
        if !entries.is_empty() {
            let mut order: Vec<usize> = (0..entries.len()).collect();
            tree.build(&entries, &mut order, 0, 0);
        }
        for (k, leaf) in tree.leaves.iter().enumerate() {
            let slot = match leaf.light {
                PickedLight::Area(i) => tree.area_leaf.get_mut(i),
                PickedLight::Lamp(i) => tree.lamp_leaf.get_mut(i),
                PickedLight::Environment => Some(&mut tree.environment_leaf),
            };
            if let Some(slot) = slot {
                *slot = Some(k as u32);
            }
        }
        tree
    }

    /// Appends the subtree over `order`'s entries, split where [`saoh_split`] finds it cheapest
    /// (in halves by index where their centres coincide), and returns its root's index.
    fn build(
        &mut self,
        entries: &[(PickedLight, std::ops::Range<usize>, LightBounds)],
        order: &mut [usize],
        trail: u64,
        depth: u32,
    ) -> usize {
        let bounds = order[1..]
            .iter()
            .fold(entries[order[0]].2, |u, &i| u.union(&entries[i].2));
        let index = self.nodes.len();
        if let [only] = order {
            let (light, parts, _) = &entries[*only];
            self.nodes.push(Node {
                bounds,
                kind: NodeKind::Leaf(self.leaves.len() as u32),
            });
            self.leaves.push(Leaf {
                light: *light,
                parts: parts.clone(),
                trail,
                depth,
            });
            return index;
        }
        // A leaf's path is the bits of `trail`: where the tree would grow deeper than they
        // hold (collinear lamps tie every SAOH cost and peel off one bucket a level), the rest
        // is split in halves, which keeps every leaf within `MAX_DEPTH` levels.
        let balanced = depth + order.len().next_power_of_two().trailing_zeros() >= MAX_DEPTH;
        let mid = match saoh_split(entries, order, &bounds).filter(|_| !balanced) {
            Some(mid) => mid,
            // Every centre the same, or too deep: halves by index.
            None => {
                order.sort_unstable();
                order.len() / 2
            }
        };
        self.nodes.push(Node {
            bounds,
            kind: NodeKind::Interior(0),
        });
        let (first, second) = order.split_at_mut(mid);
        self.build(entries, first, trail, depth + 1);
        let second_index = self.build(entries, second, trail | (1 << depth), depth + 1);
        self.nodes[index].kind = NodeKind::Interior(second_index as u32);
        index
    }

    /// The importance of node `i` at `x`: a leaf's is the sum of its parts'.
    #[inline(always)]
    fn node_importance(&self, i: usize, x: Vec3, n: Vec3) -> f32 {
        let node = &self.nodes[i];
        match node.kind {
            NodeKind::Leaf(leaf) => self.leaves[leaf as usize]
                .parts
                .clone()
                .map(|k| self.parts[k].importance(x, n))
                .sum(),
            NodeKind::Interior(_) => node.bounds.importance(x, n),
        }
    }

    /// The tree's weight and the sum of every weight at the top level (the tree, the
    /// enclosures and the emitters beside it).
    #[inline(always)]
    fn top_weights(&self, x: Vec3, n: Vec3) -> (f32, f32) {
        let tree = if self.nodes.is_empty() {
            0.0
        } else {
            self.node_importance(0, x, n)
        };
        let total = tree + self.beside(x, n).map(|(_, w)| w).sum::<f32>();
        (tree, total)
    }

    /// The weights beside the tree at `x`: each enclosure's and each emitter's, with its light.
    #[inline(always)]
    fn beside(&self, x: Vec3, n: Vec3) -> impl Iterator<Item = (PickedLight, f32)> + '_ {
        let enclosures = self
            .enclosures
            .iter()
            .map(move |e| (e.light, e.importance(x, n)));
        enclosures.chain(
            self.infinite
                .iter()
                .map(move |e| (e.light(), e.importance(n))),
        )
    }

    /// The probability of picking `light` beside the tree: through its enclosures and as an
    /// emitter beside it, of `total` (`top_weights`'s).
    #[inline(always)]
    fn beside_probability(&self, light: PickedLight, x: Vec3, n: Vec3, total: f32) -> f32 {
        let mut p = 0.0;
        for e in &self.enclosures {
            if e.light == light {
                p += e.importance(x, n) / total;
            }
        }
        for e in &self.infinite {
            if e.light() == light {
                p += e.importance(n) / total;
            }
        }
        p
    }

    /// Picks a light for a point `x` with normal `n` (facing the side light is gathered from),
    /// by `u`: which, and the probability of picking it. `None` where no light can reach.
    #[inline(always)]
    pub fn pick(&self, u: f32, x: Vec3, n: Vec3) -> Option<(PickedLight, f32)> {
        if let Some(only) = self.only {
            return Some((only, 1.0));
        }
        let (tree, total) = self.top_weights(x, n);
        if total.is_nan() || total <= 0.0 {
            return None;
        }
        let mut u = u * total;
        if u >= tree && total > tree {
            // Beside the tree: the last with a weight takes what rounding leaves over.
            u -= tree;
            let mut picked = None;
            for (light, w) in self.beside(x, n) {
                if w > 0.0 {
                    picked = Some(light);
                    if u < w {
                        break;
                    }
                }
                u -= w;
            }
            let light = picked?;
            return Some((light, self.probability_of_weights(light, x, n, tree, total)));
        }
        // Down the tree, each child by its share of the two, `u` stretched back to [0, 1); the
        // product formed as `trail_probability` forms it, so that the two agree exactly.
        let mut u = (u / tree).min(ONE_BELOW);
        let mut p = 1.0;
        let mut i = 0;
        loop {
            match self.nodes[i].kind {
                NodeKind::Leaf(leaf) => {
                    // Its share beside the tree counts too, added as `probability` adds it.
                    let light = self.leaves[leaf as usize].light;
                    let mut p_light = 0.0;
                    p_light += tree / total * p;
                    p_light += self.beside_probability(light, x, n, total);
                    return (p_light > 0.0).then_some((light, p_light));
                }
                NodeKind::Interior(second) => {
                    let (a, b) = (i + 1, second as usize);
                    let (pa, pb) = self.split(a, b, x, n);
                    if u < pa {
                        u = (u / pa).min(ONE_BELOW);
                        p *= pa;
                        i = a;
                    } else {
                        u = ((u - pa) / pb).min(ONE_BELOW);
                        p *= pb;
                        i = b;
                    }
                }
            }
        }
    }

    /// The shares of children `a` and `b` of a node at `x`: by importance, or halves where
    /// both are 0. A node's bounds hold its children's, so it may be important at a point
    /// where neither child is (a lamp's portals facing up and down, seen from beside the
    /// shade); halves keep every pick reaching a leaf, so the probabilities sum to 1. The
    /// light it reaches there sends no light (its bounds are conservative) and adds 0.
    #[inline(always)]
    fn split(&self, a: usize, b: usize, x: Vec3, n: Vec3) -> (f32, f32) {
        let (ia, ib) = (self.node_importance(a, x, n), self.node_importance(b, x, n));
        let sum = ia + ib;
        if sum > 0.0 {
            (ia / sum, ib / sum)
        } else {
            (0.5, 0.5)
        }
    }

    /// The probability that [`Self::pick`] picks `light` at `x` with normal `n`.
    #[inline(always)]
    pub fn probability(&self, light: PickedLight, x: Vec3, n: Vec3) -> f32 {
        if let Some(only) = self.only {
            return if only == light { 1.0 } else { 0.0 };
        }
        let (tree, total) = self.top_weights(x, n);
        if total.is_nan() || total <= 0.0 {
            return 0.0;
        }
        self.probability_of_weights(light, x, n, tree, total)
    }

    /// [`Self::probability`] with `top_weights`'s `(tree, total)` at `x` already known (a pick
    /// beside the tree has them).
    #[inline(always)]
    fn probability_of_weights(
        &self,
        light: PickedLight,
        x: Vec3,
        n: Vec3,
        tree: f32,
        total: f32,
    ) -> f32 {
        let leaf = match light {
            PickedLight::Area(i) => self.area_leaf.get(i).copied().flatten(),
            PickedLight::Lamp(i) => self.lamp_leaf.get(i).copied().flatten(),
            PickedLight::Environment => self.environment_leaf,
        };
        let mut p = 0.0;
        if let Some(leaf) = leaf {
            p += tree / total * self.trail_probability(leaf as usize, x, n);
        }
        p + self.beside_probability(light, x, n, total)
    }

    /// The probability of reaching leaf `leaf` from the root.
    #[inline(always)]
    fn trail_probability(&self, leaf: usize, x: Vec3, n: Vec3) -> f32 {
        let Leaf { trail, depth, .. } = self.leaves[leaf];
        let mut p = 1.0;
        let mut i = 0;
        for level in 0..depth {
            let NodeKind::Interior(second) = self.nodes[i].kind else {
                return 0.0;
            };
            let (a, b) = (i + 1, second as usize);
            let (pa, pb) = self.split(a, b, x, n);
            if trail & (1 << level) == 0 {
                p *= pa;
                i = a;
            } else {
                p *= pb;
                i = b;
            }
        }
        p
    }

    /// The probability of every light the tree or the emitters beside it can pick, at `x`
    /// with normal `n`: [`Self::probability`] for each, in one walk over the tree (each node's
    /// split computed once, where the lights' trails would compute it once per light).
    pub fn probabilities(&self, x: Vec3, n: Vec3) -> Vec<(PickedLight, f32)> {
        let mut out: Vec<(PickedLight, f32)> = Vec::new();
        if let Some(only) = self.only {
            out.push((only, 1.0));
            return out;
        }
        let (tree, total) = self.top_weights(x, n);
        if total.is_nan() || total <= 0.0 {
            return out;
        }
        // Depth first, each node with the probability of reaching it.
        let mut stack: Vec<(usize, f32)> = Vec::new();
        if !self.nodes.is_empty() {
            stack.push((0, 1.0));
        }
        while let Some((i, p)) = stack.pop() {
            match self.nodes[i].kind {
                NodeKind::Leaf(leaf) => {
                    out.push((self.leaves[leaf as usize].light, tree / total * p));
                }
                NodeKind::Interior(second) => {
                    let (a, b) = (i + 1, second as usize);
                    let (pa, pb) = self.split(a, b, x, n);
                    stack.push((b, p * pb));
                    stack.push((a, p * pa));
                }
            }
        }
        for (light, w) in self.beside(x, n) {
            let p = w / total;
            match out.iter_mut().find(|(l, _)| *l == light) {
                Some((_, q)) => *q += p,
                None => out.push((light, p)),
            }
        }
        out
    }

    /// How many lights the tree holds (leaves) and how deep it is.
    pub fn shape(&self) -> (usize, u32) {
        (
            self.leaves.len(),
            self.leaves.iter().map(|l| l.depth).max().unwrap_or(0),
        )
    }
}

/// The deepest a leaf may lie: its path from the root is `trail`'s bits `0..depth`.
const MAX_DEPTH: u32 = u64::BITS - 1;

/// Buckets per axis of [`saoh_split`] (pbrt-v4's).
const SAOH_BUCKETS: usize = 12;

/// The surface area orientation heuristic's split of `order`'s entries (Conty Estevez &
/// Kulla 2018, as pbrt-v4's `BVHLightSampler` builds it): over 12 buckets of the centres along
/// each axis, the split that minimises each side's intensity × the solid angle its cones can
/// light (`M_Ω`) × its box's surface area, stretched by how thin `bounds` is along the axis.
/// Sorts `order` so that the first `k` entries form one side and returns `k`; `None` where no
/// axis separates the centres (along one that does, the extreme centres fall in the first and
/// last buckets, so some split has entries on both sides).
fn saoh_split(
    entries: &[(PickedLight, std::ops::Range<usize>, LightBounds)],
    order: &mut [usize],
    bounds: &LightBounds,
) -> Option<usize> {
    let (lo, hi) = order
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &i| {
            let c = entries[i].2.centroid();
            (lo.min(c), hi.max(c))
        });
    let extent = bounds.hi - bounds.lo;
    let bucket = |i: usize, axis: usize| -> usize {
        let t = (entries[i].2.centroid()[axis] - lo[axis]) / (hi[axis] - lo[axis]);
        ((t * SAOH_BUCKETS as f32) as usize).min(SAOH_BUCKETS - 1)
    };
    let mut best: Option<(f32, usize, usize)> = None;
    for axis in 0..3 {
        if hi[axis] - lo[axis] <= 0.0 {
            continue;
        }
        let mut buckets: [Option<LightBounds>; SAOH_BUCKETS] = [None; SAOH_BUCKETS];
        for &i in order.iter() {
            let b = &mut buckets[bucket(i, axis)];
            *b = Some(b.map_or(entries[i].2, |u| u.union(&entries[i].2)));
        }
        // Kr: a split across a thin box's short side costs more.
        let kr = extent.max_element() / extent[axis].max(1e-6 * extent.max_element());
        let union = |range: &[Option<LightBounds>]| {
            range
                .iter()
                .flatten()
                .fold(None, |u: Option<LightBounds>, b| {
                    Some(u.map_or(*b, |u| u.union(b)))
                })
        };
        for split in 0..SAOH_BUCKETS - 1 {
            let (Some(below), Some(above)) =
                (union(&buckets[..=split]), union(&buckets[split + 1..]))
            else {
                continue;
            };
            let cost = kr * (saoh_cost(&below) + saoh_cost(&above));
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, split));
            }
        }
    }
    let (_, axis, split) = best?;
    // Stable: entries of one bucket keep their order, whatever rounding did to their centres.
    order.sort_by_key(|&i| (bucket(i, axis) > split, i));
    let k = order.iter().filter(|&&i| bucket(i, axis) <= split).count();
    (0 < k && k < order.len()).then_some(k)
}

/// One side's cost in [`saoh_split`]: intensity × `M_Ω` × the box's surface area, `M_Ω` the
/// cosine-weighted solid angle the cone (`θ_o`, widened by `θ_e`) can send light into.
fn saoh_cost(b: &LightBounds) -> f32 {
    use std::f32::consts::PI;
    let theta_o = if b.two_sided {
        PI
    } else {
        b.cos_o.clamp(-1.0, 1.0).acos()
    };
    let theta_e = b.cos_e.clamp(-1.0, 1.0).acos();
    let theta_w = (theta_o + theta_e).min(PI);
    let (sin_o, cos_o) = theta_o.sin_cos();
    let m_omega = 2.0 * PI * (1.0 - cos_o)
        + PI / 2.0
            * (2.0 * theta_w * sin_o - (theta_o - 2.0 * theta_w).cos() - 2.0 * theta_o * sin_o
                + cos_o);
    let d = b.hi - b.lo;
    let area = 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
    b.intensity * m_omega * area
}

/// A portal as its light's light leaves it: from the portal's box, along the directions from
/// the light to the portal, like a spot. Those directions `z − y` (`y` on the light, `z` on
/// the portal) form a convex set, the difference of two convex hulls, whose directions are
/// spanned by the differences of their vertices: the cone holding those holds them all.
/// A point in front of the portal that cannot see the light through it (outside its
/// antishadow, where the estimator draws nothing but its `alpha` share) gets 0 from it.
fn portal_bounds(light: &AreaLight, polygon: &ConvexPolygon, intensity: f32) -> LightBounds {
    let mut cone: Option<(Vec3, f32)> = None;
    for y in light.corners() {
        for &z in polygon.vertices() {
            let w = (z - y).normalize_or_zero();
            if w != Vec3::ZERO {
                cone = Some(cone.map_or((w, 1.0), |k| cone_union(k, (w, 1.0))));
            }
        }
    }
    let hemisphere = polygon_bounds(polygon, intensity);
    match cone {
        // A spot at the portal: axis only, the light within the cone.
        Some((axis, cos_cone)) if cos_cone > 0.0 => LightBounds {
            axis,
            cos_o: 1.0,
            cos_e: cos_cone,
            ..hemisphere
        },
        _ => hemisphere,
    }
}

/// A portal or window as an emitter into its front: its box, its normal, a hemisphere.
fn polygon_bounds(polygon: &ConvexPolygon, intensity: f32) -> LightBounds {
    let (lo, hi) = polygon
        .vertices()
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    LightBounds {
        lo,
        hi,
        axis: polygon.normal(),
        cos_o: 1.0,
        cos_e: 0.0,
        intensity,
        two_sided: false,
        within: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{Rng, sample_uniform_sphere};

    fn unit(rng: &mut Rng) -> Vec3 {
        sample_uniform_sphere(rng.uniform2())
    }

    /// The union of two cones holds every direction of both (directions on each cone's rim),
    /// and is the smallest cone that does: its half-angle is the larger one's where one holds
    /// the other, else `(θa + θd + θb)/2` (at most π), computed here in f64 from the angles
    /// (issue 40: the whole sphere held both and passed). So most unions are not the sphere.
    #[test]
    fn cone_union_holds_both_cones() {
        let mut rng = Rng::new(1, 2);
        let mut spheres = 0;
        for _ in 0..2000 {
            let cones = [0, 1].map(|_| (unit(&mut rng), 1.0 - 2.0 * rng.uniform()));
            let (axis, cos_o) = cone_union(cones[0], cones[1]);
            let [ta, tb] = cones.map(|(_, c)| f64::from(c).clamp(-1.0, 1.0).acos());
            let td = f64::from(cones[0].0.dot(cones[1].0))
                .clamp(-1.0, 1.0)
                .acos();
            let smallest = if td + tb <= ta {
                ta
            } else if td + ta <= tb {
                tb
            } else {
                (0.5 * (ta + td + tb)).min(std::f64::consts::PI)
            };
            assert!(
                (f64::from(cos_o) - smallest.cos()).abs() < 1e-3,
                "{cones:?}: cos {cos_o}, the smallest {}",
                smallest.cos()
            );
            spheres += usize::from(cos_o <= -1.0);
            for (w, cos) in cones {
                // A direction on the cone's rim.
                let t = w.any_orthonormal_vector();
                let sin = (1.0 - cos * cos).max(0.0).sqrt();
                let (s, c) = (std::f32::consts::TAU * rng.uniform()).sin_cos();
                let d = cos * w + sin * (c * t + s * w.cross(t));
                assert!(axis.dot(d) >= cos_o - 1e-4, "{cones:?} → {axis}, {cos_o}");
            }
        }
        assert!(spheres < 2000 / 4, "{spheres} unions are the whole sphere");
    }

    /// The importance is positive wherever some point of the box sends light along a direction
    /// of the emission cone to `x` from above its surface (a brute-force search over points of
    /// the box and normals of the cone). The negative case: the same bound without the box's
    /// spread (`θ_b` = 0) misses some of them.
    #[test]
    fn importance_is_zero_only_where_nothing_can_arrive() {
        let mut rng = Rng::new(3, 4);
        let mut checked = 0;
        let mut missed_without_spread = 0;
        for _ in 0..3000 {
            let c = 2.0 * unit(&mut rng);
            let half = Vec3::new(rng.uniform(), rng.uniform(), rng.uniform()) * 0.5;
            let bounds = LightBounds {
                lo: c - half,
                hi: c + half,
                axis: unit(&mut rng),
                cos_o: 1.0 - 2.0 * rng.uniform() * rng.uniform(),
                cos_e: rng.uniform() * 0.9,
                intensity: 1.0,
                two_sided: false,
                within: None,
            };
            let x = 3.0 * unit(&mut rng);
            let n = unit(&mut rng);
            // Brute force: a point of the box and a normal within θ_o of the axis from which
            // the direction to x is within θ_e, above x's surface.
            let arrives = (0..400).any(|_| {
                let y = bounds.lo
                    + (bounds.hi - bounds.lo)
                        * Vec3::new(rng.uniform(), rng.uniform(), rng.uniform());
                let w = (x - y).normalize();
                // The normal of the cone closest to w.
                let cos_w = bounds.axis.dot(w);
                let theta = cos_w.clamp(-1.0, 1.0).acos() - bounds.cos_o.clamp(-1.0, 1.0).acos();
                theta.max(0.0).cos() > bounds.cos_e && n.dot(-w) > 0.0
            });
            if arrives {
                checked += 1;
                assert!(bounds.importance(x, n) > 0.0, "{bounds:?} at {x}, {n}");
                let point = LightBounds {
                    lo: c,
                    hi: c,
                    ..bounds
                };
                if point.importance(x, n) == 0.0 {
                    missed_without_spread += 1;
                }
            }
        }
        assert!(checked > 300, "{checked}");
        assert!(missed_without_spread > 0);
    }
}
