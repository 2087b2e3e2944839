//! `portalview portals`: find a scene's portals, or check the ones it has.

use anyhow::{Context, Result, bail};
use clap::Args;
use std::path::{Path, PathBuf};
use std::time::Instant;

use super::{EnvironmentArgs, open_scene};
use crate::asset::desc::{PortalDesc, SceneDesc};
use crate::asset::gltf;
use crate::scene::Scene;
use crate::scene::portals::{self, Found, Source, SourceCheck};

#[derive(Args, Debug)]
#[command(group(clap::ArgGroup::new("what").required(true).args(["find", "check"])))]
pub struct PortalsArgs {
    /// Find the openings of every light and of the sky, and fit a portal to each (alpha
    /// `auto`); the portals replace the scene's.
    #[arg(long, value_name = "SCENE")]
    pub find: Option<String>,
    /// Where `--find` writes the scene with its found portals (a `.glb`; a glTF file keeps
    /// every other byte, as the viewer's Save portals does).
    #[arg(long, value_name = "OUT", requires = "find")]
    pub out: Option<PathBuf>,
    /// Check the scene's portals: per light and for the sky, the share of the light that
    /// leaves through them, the share that leaks past them, and the portals no light passes.
    /// Exits with an error when something is wrong.
    #[arg(long, value_name = "SCENE")]
    pub check: Option<String>,
    /// Seed of the check's rays.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    #[command(flatten)]
    pub environment: EnvironmentArgs,
}

pub fn run(args: &PortalsArgs) -> Result<()> {
    if let Some(name) = &args.find {
        let out = args
            .out
            .as_deref()
            .context("--find needs --out OUT.glb: where to write the scene with its portals")?;
        return find(name, out, args);
    }
    if let Some(name) = &args.check {
        let scene = open_scene(name, &args.environment)?;
        let start = Instant::now();
        let checks = portals::check(&scene, args.seed);
        let seconds = start.elapsed().as_secs_f64();
        let (report, problems) = check_report(&scene, &checks);
        print!("{report}");
        println!("checked in {seconds:.2} s");
        if problems > 0 {
            bail!("{name}: {problems} problem(s) with its portals");
        }
    }
    Ok(())
}

fn find(name: &str, out: &Path, args: &PortalsArgs) -> Result<()> {
    let scene = open_scene(name, &args.environment)?;
    let start = Instant::now();
    let found = portals::find(&scene);
    let seconds = start.elapsed().as_secs_f64();
    print_found(&scene, &found);
    println!("found in {seconds:.2} s");
    if !scene.desc.portals.is_empty() {
        println!(
            "the {} portal(s) of {name} are replaced by the found ones",
            scene.desc.portals.len()
        );
    }
    // Only portals that make a valid scene are written; the others are said and left out.
    // (Deferred: only the validation, without measuring the auto alphas twice.)
    let (_, errors) = scene.with_portals_deferred(found.portals.clone(), None);
    let kept: Vec<PortalDesc> = found
        .portals
        .iter()
        .enumerate()
        .filter(|(i, _)| !errors.iter().any(|(e, _)| e == i))
        .map(|(_, p)| p.clone())
        .collect();
    for (_, error) in &errors {
        println!("left out: {error}");
    }
    let with_found = scene
        .with_portals(kept.clone())
        .with_context(|| format!("{name}: the found portals"))?;
    write(&scene, &with_found.desc, &kept, out)?;
    println!("wrote {}", out.display());
    let checks = portals::check(&with_found, args.seed);
    println!("\ncheck of the found portals:");
    print!("{}", check_report(&with_found, &checks).0);
    Ok(())
}

/// Writes the scene with the found portals: into a copy of its glTF file (every other byte
/// kept), or, for a built-in or another format, as a new `.glb`.
fn write(scene: &Scene, desc: &SceneDesc, portals: &[PortalDesc], out: &Path) -> Result<()> {
    let same_format = |source: &Path| {
        source.extension().map(|e| e.to_ascii_lowercase())
            == out.extension().map(|e| e.to_ascii_lowercase())
    };
    match &scene.source {
        Some(source) if same_format(source) => {
            let beside = |p: &Path| {
                let folder = p.parent().filter(|d| !d.as_os_str().is_empty());
                folder.unwrap_or(Path::new(".")).canonicalize().ok()
            };
            if out
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("gltf"))
                && beside(source) != beside(out)
            {
                bail!(
                    "{}: a .gltf's buffers and images are relative to it, so its copy with the \
                     found portals must go in the same folder (or write a .glb: the whole scene)",
                    out.display()
                );
            }
            // A temporary copy beside the target, renamed over it once written.
            let mut temporary = out.as_os_str().to_owned();
            temporary.push(".portals-tmp");
            let temporary = PathBuf::from(temporary);
            std::fs::copy(source, &temporary).with_context(|| {
                format!("copying {} to {}", source.display(), temporary.display())
            })?;
            let written = gltf::save_portals(&temporary, portals)
                .map_err(anyhow::Error::from)
                .and_then(|()| {
                    std::fs::rename(&temporary, out)
                        .with_context(|| format!("renaming {}", temporary.display()))
                });
            if written.is_err() {
                let _ = std::fs::remove_file(&temporary);
            }
            written
        }
        _ if out
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("glb")) =>
        {
            Ok(gltf::export_glb(desc, out)?)
        }
        _ => bail!(
            "{}: the scene with its found portals is written as a .glb (or, for a .gltf file, as a \
             .gltf beside it)",
            out.display()
        ),
    }
}

fn source_label(scene: &Scene, source: Source) -> String {
    match source {
        Source::Light(i) => format!("light '{}'", scene.geometry.lights[i].name),
        Source::Environment => "the sky".to_owned(),
    }
}

fn print_found(scene: &Scene, found: &Found) {
    for source in &found.sources {
        let label = source_label(scene, source.source);
        match source.source {
            Source::Light(_) => println!(
                "{label}: {:.0}% of its light stopped around it, {} opening(s)",
                100.0 * source.stopped,
                source.openings.len()
            ),
            Source::Environment => println!("{label}: {} window(s)", source.openings.len()),
        }
        for opening in &source.openings {
            let area = crate::sampling::polygon::polygon_area(&opening.corners);
            println!(
                "  {}-gon of {:.4} m² facing ({:.2}, {:.2}, {:.2}), {:.1}% of the light",
                opening.corners.len(),
                area,
                opening.normal.x,
                opening.normal.y,
                opening.normal.z,
                100.0 * opening.share
            );
        }
        for note in &source.notes {
            println!("  note: {note}");
        }
    }
}

/// The checks as `portals --check` prints them, and how many problems they found.
pub fn check_report(scene: &Scene, checks: &[SourceCheck]) -> (String, usize) {
    use std::fmt::Write;
    let mut out = String::new();
    if checks.is_empty() {
        out.push_str("no portals to check\n");
    }
    let mut problems = 0;
    for check in checks {
        let _ = writeln!(
            out,
            "{}: {:.1}% of its light leaves through its portals, {:.1}% ± {:.1}% past them",
            source_label(scene, check.source),
            100.0 * check.through,
            100.0 * check.leak,
            100.0 * check.leak_error
        );
        for p in &check.portals {
            let _ = writeln!(
                out,
                "  {}: {:.1}%{}",
                p.name,
                100.0 * p.share,
                if p.wrong_way > 0.0 {
                    format!(" ({:.1}% the wrong way)", 100.0 * p.wrong_way)
                } else {
                    String::new()
                }
            );
        }
        for note in &check.notes {
            let _ = writeln!(out, "  note: {note}");
        }
        for problem in check.problems() {
            let _ = writeln!(out, "  PROBLEM: {problem}");
            problems += 1;
        }
        // The alpha rendering uses: an `auto` one is measured with the renderer's own rays,
        // not this check's (`--seed`), so it is read from the scene, not recomputed here.
        let _ = match scene.alpha_of(check.source) {
            Some((alpha, true)) => writeln!(out, "  alpha (auto, as rendered): {alpha:.3}"),
            Some((alpha, false)) => writeln!(
                out,
                "  alpha (set): {alpha:.3}; auto would measure about {:.3}",
                check.auto_alpha()
            ),
            None => writeln!(out, "  alpha with auto: about {:.3}", check.auto_alpha()),
        };
        let _ = writeln!(
            out,
            "  {} rays drawn; {:.1}% of the light gets out of what surrounds it (the rest is \
             stopped there)",
            check.rays,
            100.0 * check.reach
        );
    }
    (out, problems)
}
