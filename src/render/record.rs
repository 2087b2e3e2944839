//! Recording the rays a render traces, so that a benchmark can replay exactly those rays
//! through the bare traversal, and a test can count them.

use glam::Vec3;
use std::cell::RefCell;

use super::integrator::Integrator;
use super::stats::Stats;
use super::{Tiles, render_tile};
use crate::scene::bvh::{Bvh, Hit, Tracer};

/// One ray the renderer traced, kept to be replayed through the raw traversal.
#[derive(Clone, Copy, Debug)]
pub struct RecordedRay {
    pub origin: Vec3,
    pub dir: Vec3,
    pub tmin: f32,
    pub tmax: f32,
    /// A closest-hit query (else an occlusion query).
    pub closest: bool,
}

/// Traces through the scene's BVH, keeping every ray.
pub struct Recorder<'a> {
    bvh: &'a Bvh,
    rays: RefCell<Vec<RecordedRay>>,
}

impl<'a> Recorder<'a> {
    pub fn new(bvh: &'a Bvh) -> Self {
        Recorder {
            bvh,
            rays: RefCell::new(Vec::new()),
        }
    }

    /// The rays traced so far, in order.
    pub fn into_rays(self) -> Vec<RecordedRay> {
        self.rays.into_inner()
    }

    fn keep(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32, closest: bool) {
        self.rays.borrow_mut().push(RecordedRay {
            origin,
            dir,
            tmin,
            tmax,
            closest,
        });
    }
}

impl Tracer for Recorder<'_> {
    fn closest_hit(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Option<Hit> {
        self.keep(origin, dir, tmin, tmax, true);
        self.bvh.closest_hit(origin, dir, tmin, tmax)
    }

    /// Kept as an occlusion query (a replay stops at the first pane; scenes without glass,
    /// which the benchmarks replay, make none).
    fn blocker_past(
        &self,
        origin: Vec3,
        dir: Vec3,
        (tmin, tmax): (f32, f32),
        guess: u32,
        pass: &mut dyn FnMut(&Hit) -> bool,
    ) -> Option<u32> {
        self.keep(origin, dir, tmin, tmax, false);
        self.bvh
            .blocker_past(origin, dir, (tmin, tmax), guess, pass)
    }

    fn occluder(&self, origin: Vec3, dir: Vec3, tmin: f32, tmax: f32, guess: u32) -> Option<u32> {
        self.keep(origin, dir, tmin, tmax, false);
        self.bvh.occluder(origin, dir, tmin, tmax, guess)
    }
}

/// The rays of one pass of the renderer, one list per tile in the renderer's order, and the
/// rays the renderer's statistics counted for that pass.
pub fn record_pass(integrator: &Integrator, size: u32) -> (Vec<Vec<RecordedRay>>, u64) {
    let tiles = Tiles::new(size, size);
    let rays = integrator.scene().camera.rays(1.0);
    let mut stats = Stats::default();
    let recorded = (0..tiles.count())
        .map(|tile| {
            let recorder = Recorder::new(&integrator.scene().geometry.bvh);
            render_tile(integrator, &recorder, &rays, tiles, tile, 0, &mut stats);
            recorder.into_rays()
        })
        .collect();
    (recorded, stats.rays())
}
