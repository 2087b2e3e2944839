//! The command line: parses arguments, translates them into the library's parameter types and
//! runs one subcommand. Nothing imports this module.

mod bench;
mod compare;
mod export;
mod portals;
mod render;
mod view;

use anyhow::Result;
use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;

pub use bench::BenchArgs;
pub use compare::CompareArgs;
pub use portals::{PortalsArgs, check_report};
pub use render::RenderArgs;
pub use view::ViewArgs;

use crate::asset::environment::{EnvironmentOverrides, Interpolation};
use crate::light::Mixture;
use crate::sampling::SamplerKind;
use crate::scene::Scene;

#[derive(Parser, Debug)]
#[command(
    name = "portalview",
    version,
    about = "Light portals for area lights: a viewer and a renderer"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Open the viewer (the default) on a built-in scene or a .gltf/.glb file.
    View(ViewArgs),
    /// Render an image headless.
    Render(RenderArgs),
    /// Write a built-in scene as .glb, with the portal conventions.
    Export {
        /// The built-in scene to write (lampshade, fig8a, fig8b, fig8c, window, windows2,
        /// desklamp, livingroom, panes, pendant).
        #[arg(long)]
        scene: String,
        /// Where to write it: a .glb file (its environment image, if any, beside it).
        #[arg(long)]
        out: PathBuf,
    },
    /// Measure raw BVH traversal and renderer throughput on the built-in scenes.
    Bench(BenchArgs),
    /// Render strategies for equal time and measure their error against a converged reference.
    Compare(CompareArgs),
    /// Find a scene's portals (--find SCENE --out OUT.glb), or check the ones it has
    /// (--check SCENE).
    Portals(PortalsArgs),
}

pub fn run(command: Command) -> Result<()> {
    match command {
        Command::View(args) => crate::app::run_viewer(args.into()),
        Command::Render(args) => render::run(&args),
        Command::Export { scene, out } => export::run(&scene, &out),
        Command::Bench(args) if args.ui => bench::run_ui(&args),
        Command::Bench(args) => bench::run(&args),
        Command::Compare(args) => compare::run(&args),
        Command::Portals(args) => portals::run(&args),
    }
}

/// Opens a built-in scene or a glTF file with the command line's environment, printing on
/// stderr what the file holds that is not read.
fn open_scene(name: &str, environment: &EnvironmentArgs) -> Result<Scene> {
    let scene = Scene::open_with_environment(name, &environment.into())?;
    for warning in &scene.desc.warnings {
        eprintln!("warning: {warning}");
    }
    Ok(scene)
}

/// The environment: what rays leaving the scene see, lighting it through window portals.
#[derive(Args, Debug, Clone, Default)]
pub struct EnvironmentArgs {
    /// An equirectangular .hdr or .exr image, or a constant colour R,G,B (replaces the
    /// scene's `environment`).
    #[arg(long, value_name = "FILE|R,G,B")]
    pub environment: Option<String>,
    /// Multiplies the environment's radiance (default: the scene's, else 1).
    #[arg(long, value_name = "S")]
    pub environment_strength: Option<f32>,
    /// Turns the environment about +Y, in degrees, as Blender's Mapping node's Z rotation
    /// (default: the scene's, else 0).
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    pub environment_rotation: Option<f32>,
    /// How the image is read between pixels, as Blender's Environment Texture node's
    /// Interpolation (default: the scene's `environment_interpolation`, else linear).
    #[arg(long, value_enum, value_name = "MODE")]
    pub environment_interpolation: Option<Interpolation>,
}

impl From<&EnvironmentArgs> for EnvironmentOverrides {
    fn from(a: &EnvironmentArgs) -> Self {
        EnvironmentOverrides {
            source: a.environment.clone(),
            strength: a.environment_strength,
            rotation_degrees: a.environment_rotation,
            interpolation: a.environment_interpolation,
        }
    }
}

/// Image options shared by `render` and `compare` (their widths differ in default).
#[derive(Args, Debug, Clone)]
pub struct ImageArgs {
    /// Image height (default: from the width and the camera's aspect ratio).
    #[arg(long)]
    pub height: Option<u32>,
    /// Seed of the random numbers: the same seed, scene and settings give the same image.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Path vertices after the camera (1 = direct light only, as in the thesis).
    #[arg(long, default_value_t = 1)]
    pub max_depth: u32,
    /// Random numbers: Owen-scrambled Sobol' points in Z-order (stratified per pixel), or
    /// independent ones.
    #[arg(long, value_enum, default_value_t = SamplerKind::default())]
    pub sampler: SamplerKind,
    /// Where a shading point's light mixture has both a light share and a portal share: one
    /// sample of the mixture (the thesis's), or one sample from each, weighted by its share.
    #[arg(long, value_enum, default_value_t = Mixture::default())]
    pub mixture: Mixture,
    #[command(flatten)]
    pub environment: EnvironmentArgs,
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    /// Doc comments are the help text: rustdoc's link syntax must not leak into it.
    #[test]
    fn help_text_has_no_rustdoc_links() {
        let mut cli = Cli::command();
        cli.build();
        let mut helps = vec![cli.render_long_help().to_string()];
        for sub in cli.get_subcommands_mut() {
            helps.push(sub.render_long_help().to_string());
        }
        assert!(helps.iter().any(|h| h.contains("stratified per pixel")));
        for help in helps {
            for line in help.lines() {
                assert!(!line.contains("[`"), "rustdoc link in the help: {line}");
            }
        }
    }
}
