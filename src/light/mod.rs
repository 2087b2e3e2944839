//! Lights, portals, the antishadow classifier and the sampling strategies (`docs/method.md`).

pub mod antishadow;
pub mod area;
pub mod bounce;
pub mod environment;
pub mod estimator;
pub mod guided;
pub mod hull;
pub mod portal;
pub mod punctual;
pub mod sky;
pub mod tree;
pub mod window;

/// The most portals one shading point can use for one light (and windows for the sky): the
/// size of the mixtures' term lists, which the estimator, the sky and the light tree share.
pub const MAX_TERMS: usize = 8;

use serde::{Deserialize, Serialize};

use antishadow::Region;
use area::AreaLight;
use environment::Environment;
use portal::Portal;
use punctual::Lamp;
use window::Window;

use crate::sampling::ONE_BELOW;

/// A scene's lights and the portals onto them: all that light sampling reads. The scene
/// implements it, so this layer never needs to know what a scene is.
pub trait LightSet {
    fn lights(&self) -> &[AreaLight];
    fn portals(&self) -> &[Portal];
    /// Punctual lamps, picked with the area lights by power (none by default).
    fn lamps(&self) -> &[Lamp] {
        &[]
    }
    /// The environment, picked with the lights by power (none by default).
    fn environment(&self) -> Option<&Environment> {
        None
    }
    /// Window portals onto the environment (none by default).
    fn windows(&self) -> &[Window] {
        &[]
    }
    /// The box where area light `light` lights its enclosure, as measured
    /// (`scene::enclosure`); `None`: not measured (the tree then takes the box around the
    /// light and its portals).
    fn enclosure(&self, _light: usize) -> Option<(glam::Vec3, glam::Vec3)> {
        None
    }
}

/// Picks the light's share (probability `alpha`) or the portals' by `u.x`, and stretches `u.x`
/// back to a uniform number in [0, 1): `(true, u')` for the light's share. Both shares then
/// draw from stratified 2D points: under Sobol' points the count of the light share's draws
/// that reach the light past the occluders is stratified too, where a separate number would
/// give each share a random subset of the points. At `alpha = 1` `u` comes back as it is.
#[inline(always)]
pub(crate) fn split_share(u: glam::Vec2, alpha: f32) -> (bool, glam::Vec2) {
    if u.x < alpha {
        (true, glam::Vec2::new((u.x / alpha).min(ONE_BELOW), u.y))
    } else {
        let x = ((u.x - alpha) / (1.0 - alpha)).min(ONE_BELOW);
        (false, glam::Vec2::new(x, u.y))
    }
}

/// The four strategies of the method: a closed set.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum,
)]
pub enum Strategy {
    /// Uniform on the light's area; portals ignored (the thesis's baseline).
    Light,
    /// Uniform on the portal's area; the ray goes on through it and may miss the light.
    Portal,
    /// The light's projection through the portal, sampled by solid angle.
    Projection,
    /// Per shading point, the technique of its antishadow region.
    #[default]
    Antishadow,
}

impl Strategy {
    pub const ALL: [Strategy; 4] = [
        Strategy::Light,
        Strategy::Portal,
        Strategy::Projection,
        Strategy::Antishadow,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Strategy::Light => "light",
            Strategy::Portal => "portal",
            Strategy::Projection => "projection",
            Strategy::Antishadow => "antishadow",
        }
    }

    /// The technique a portal term uses for a point in `region` (in front of the portal and
    /// not outside its antishadow); `None` for light sampling, which ignores portals.
    pub fn technique(self, region: Region) -> Option<Technique> {
        // Behind the portal or outside its antishadow, no direction through it reaches the
        // light: the portal gets no weight under any strategy.
        if matches!(region, Region::Behind | Region::Outside) {
            return None;
        }
        match self {
            Strategy::Light => None,
            Strategy::Portal => Some(Technique::Portal),
            Strategy::Projection => Some(Technique::Projection),
            Strategy::Antishadow => match region {
                Region::Antiumbra => Some(Technique::Light),
                Region::Antiantumbra => Some(Technique::Portal),
                _ => Some(Technique::Projection),
            },
        }
    }
}

/// How a shading point picks the light it samples (`docs/method.md` §10).
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum,
)]
pub enum Selection {
    /// By a tree of the lights' bounds (position, direction, intensity), portals bounding the
    /// lights behind them: lights that can send the point much light are picked more.
    #[default]
    Tree,
    /// By power alone, the same everywhere.
    Power,
}

impl Selection {
    pub const ALL: [Selection; 2] = [Selection::Tree, Selection::Power];

    pub fn name(self) -> &'static str {
        match self {
            Selection::Tree => "tree",
            Selection::Power => "power",
        }
    }
}

/// How a shading point draws from the mixture of the light technique's share (`alpha` and
/// the terms that use the light technique) and the other techniques' share
/// (`docs/method.md` §5). Both are exactly unbiased with the mixture's pdf.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum,
)]
pub enum Mixture {
    /// Where both shares draw something, one sample from each, weighted by its share
    /// (Veach's multi-sample model, balance heuristic); elsewhere one sample, as `one-sample`.
    EachShare,
    /// One sample per shading point: the share picked by its probability (the thesis's
    /// single-sample estimator; docs/method.md §5).
    #[default]
    OneSample,
}

impl Mixture {
    pub const ALL: [Mixture; 2] = [Mixture::OneSample, Mixture::EachShare];

    pub fn name(self) -> &'static str {
        match self {
            Mixture::EachShare => "each-share",
            Mixture::OneSample => "one-sample",
        }
    }
}

/// How one direction towards a light is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Technique {
    /// Uniform on the light's area.
    Light,
    /// Uniform on the portal's area.
    Portal,
    /// By solid angle of the light's projection clipped to the portal.
    Projection,
}

impl Technique {
    pub const ALL: [Technique; 3] = [Technique::Light, Technique::Portal, Technique::Projection];

    pub fn name(self) -> &'static str {
        match self {
            Technique::Light => "light",
            Technique::Portal => "portal",
            Technique::Projection => "projection",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a stratified grid of `u.x`, the light's share takes exactly the fraction `alpha`
    /// (to one grid step), and each share's stretched numbers are stratified again: one per
    /// interval of their own count, in [0, 1). A stretch that forgot the offset (`u.x / (1 −
    /// alpha)` for the portals' share) fails the second check.
    #[test]
    fn each_share_gets_its_probability_and_stays_stratified() {
        let n = 10_000;
        for alpha in [0.0, 0.1, 0.37, 0.9, 1.0] {
            let mut shares: [Vec<f32>; 2] = [Vec::new(), Vec::new()];
            for i in 0..n {
                let u = glam::Vec2::new((i as f32 + 0.5) / n as f32, 0.25);
                let (light, v) = split_share(u, alpha);
                assert!((0.0..1.0).contains(&v.x) && v.y == 0.25);
                shares[usize::from(light)].push(v.x);
            }
            let light = shares[1].len() as f32 / n as f32;
            assert!(
                (light - alpha).abs() <= 1.0 / n as f32,
                "alpha {alpha}: {light}"
            );
            for share in &mut shares {
                share.sort_by(f32::total_cmp);
                let m = share.len() as f32;
                for (k, x) in share.iter().enumerate() {
                    assert!(
                        (x * m - k as f32).abs() <= 1.01,
                        "alpha {alpha}: {k} at {x}"
                    );
                }
            }
        }
        // Negative case: the portals' share stretched without its offset is not stratified.
        let alpha = 0.37;
        let wrong: Vec<f32> = (0..n)
            .map(|i| (i as f32 + 0.5) / n as f32)
            .filter(|&x| x >= alpha)
            .map(|x| (x / (1.0 - alpha)).min(ONE_BELOW))
            .collect();
        let m = wrong.len() as f32;
        assert!(
            wrong
                .iter()
                .enumerate()
                .any(|(k, x)| (x * m - k as f32).abs() > 1.01)
        );
    }
}
