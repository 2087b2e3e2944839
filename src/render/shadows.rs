//! Where a path's shadow rays go: traced at once ([`TraceNow`], one path at a time), or queued
//! with the contribution they carry ([`ShadowQueue`]) so that a packet's paths trace theirs
//! together, [`PACKET`] at a time (the staged tile renderer, `render::tile_samples`).
//!
//! A shadow ray of a glass-free scene answers "blocked" or not, and its contribution is the
//! same product either way, times 1 or 0. So a path computes the contribution as if nothing
//! were in the way, queues the ray with it, and the queue adds it to the path's pixel once the
//! packet says the segment is clear: the same numbers as tracing first, added in the same
//! order (`tests/core.rs`, `staged_schedule_renders_the_reference_pixels`).

use glam::Vec3;

use crate::scene::bvh::{NO_OCCLUDER, PACKET, Tracer};

/// A sink for shadow rays and for the radiance a path gathers, chosen at compile time: the
/// one-path copy of the integrator has no queueing code at all.
pub trait Shadows {
    /// Whether shadow rays go to [`Self::queue`] (else the caller traces them).
    const QUEUES: bool;
    /// Takes the shadow ray `o + t·d`, `t` in `(0, tmax)`, whose contribution if nothing stands
    /// there is `c`. Called only where [`Self::QUEUES`].
    fn queue(&mut self, o: Vec3, d: Vec3, tmax: f32, c: Vec3);
    /// Where the next contributions queued will begin (how many are queued), for [`Self::close`].
    fn mark(&self) -> usize;
    /// Adds `value`, found without a shadow ray, to the path's radiance `l`.
    fn add(&mut self, l: &mut Vec3, value: Vec3);
    /// Adds `beta · (rest + the clear contributions queued from the `from`-th on)` to the
    /// path's radiance `l`: a vertex's light samples, `rest` those it traced itself.
    fn close(&mut self, l: &mut Vec3, from: usize, beta: Vec3, rest: Vec3);
}

/// Shadow rays traced where they are made.
pub struct TraceNow;

impl Shadows for TraceNow {
    const QUEUES: bool = false;

    #[inline(always)]
    fn queue(&mut self, _: Vec3, _: Vec3, _: f32, _: Vec3) {}

    #[inline(always)]
    fn mark(&self) -> usize {
        0
    }

    #[inline(always)]
    fn add(&mut self, l: &mut Vec3, value: Vec3) {
        *l += value;
    }

    #[inline(always)]
    fn close(&mut self, l: &mut Vec3, _: usize, beta: Vec3, rest: Vec3) {
        *l += beta * rest;
    }
}

/// No shadow ray: a contribution that counts as clear.
const NO_RAY: u32 = u32::MAX;

/// A queued contribution: what it adds to its lane's pixel if its shadow ray (if any) is clear.
#[derive(Clone, Copy, Debug)]
struct Queued {
    c: Vec3,
    lane: u8,
    /// Its index in [`ShadowQueue::rays`], or [`NO_RAY`].
    ray: u32,
    /// Set on the last of a vertex's contributions ([`Shadows::close`]): the path's throughput
    /// there, which multiplies their sum.
    beta: Option<Vec3>,
}

/// The shadow rays of one packet's paths and the contributions they carry, in the order the
/// paths made them: a lane's are summed in that order, as the one-path integrator adds them,
/// so both give the same pixels, bit for bit.
#[derive(Debug, Default)]
pub struct ShadowQueue {
    lane: u8,
    queued: Vec<Queued>,
    rays: Vec<(Vec3, Vec3, f32)>,
    clear: Vec<bool>,
}

impl ShadowQueue {
    pub fn new() -> Self {
        Self::default()
    }

    /// The lane whose path queues the next contributions.
    #[inline(always)]
    pub fn set_lane(&mut self, lane: usize) {
        self.lane = lane as u8;
    }

    #[inline(always)]
    fn push(&mut self, c: Vec3, ray: u32, beta: Option<Vec3>) {
        let lane = self.lane;
        self.queued.push(Queued { c, lane, ray, beta });
    }

    /// Traces the queued rays, [`PACKET`] at a time, adds each lane's contributions whose rays
    /// are clear to its `radiance` (vertex by vertex, in the order queued), and empties the
    /// queue.
    #[inline(always)]
    pub fn resolve<T: Tracer>(&mut self, tracer: &T, radiance: &mut [Vec3]) {
        self.clear.clear();
        for rays in self.rays.chunks(PACKET) {
            let mut origins = [Vec3::ZERO; PACKET];
            let mut dirs = [Vec3::ZERO; PACKET];
            let mut tmaxes = [0.0; PACKET];
            for (i, &(o, d, tmax)) in rays.iter().enumerate() {
                (origins[i], dirs[i], tmaxes[i]) = (o, d, tmax);
            }
            let n = rays.len();
            let mut blocked = [false; PACKET];
            let (o, d, tmax) = (&origins[..n], &dirs[..n], &tmaxes[..n]);
            tracer.occluders_each(o, d, 0.0, tmax, NO_OCCLUDER, &mut blocked[..n]);
            self.clear.extend(blocked[..n].iter().map(|&b| !b));
        }
        let mut sum = Vec3::ZERO;
        for q in &self.queued {
            if q.ray == NO_RAY || self.clear.get(q.ray as usize) == Some(&true) {
                sum += q.c;
            }
            if let Some(beta) = q.beta {
                if let Some(l) = radiance.get_mut(q.lane as usize) {
                    *l += beta * sum;
                }
                sum = Vec3::ZERO;
            }
        }
        self.queued.clear();
        self.rays.clear();
    }
}

impl Shadows for ShadowQueue {
    const QUEUES: bool = true;

    #[inline(always)]
    fn queue(&mut self, o: Vec3, d: Vec3, tmax: f32, c: Vec3) {
        let ray = self.rays.len() as u32;
        self.rays.push((o, d, tmax));
        self.push(c, ray, None);
    }

    #[inline(always)]
    fn mark(&self) -> usize {
        self.queued.len()
    }

    #[inline(always)]
    fn add(&mut self, _: &mut Vec3, value: Vec3) {
        self.push(value, NO_RAY, Some(Vec3::ONE));
    }

    #[inline(always)]
    fn close(&mut self, _: &mut Vec3, from: usize, beta: Vec3, rest: Vec3) {
        // What the vertex gathered itself: nothing, as this queue takes every shadow ray, but
        // kept in the sum should a path add some.
        if rest != Vec3::ZERO {
            self.push(rest, NO_RAY, None);
        }
        if self.queued.len() > from
            && let Some(last) = self.queued.last_mut()
        {
            last.beta = Some(beta);
        }
    }
}
