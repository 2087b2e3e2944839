//! The equal-time comparison: metrics on known images, the scheduler's fairness, the reference
//! cache, and the files `portalview compare` writes. Run in release
//! (`cargo test --release --test compare`); a few seconds in all.

use clap::Parser;
use glam::Vec3;
use indicatif::ProgressBar;
use portalview::cli::{Cli, run};
use portalview::compare::{
    EqualTime, ImageSpec, RELMSE_EPSILON, ReferenceBudget, ReferenceOrigin, cache_key,
    cached_reference, error_at_spp, mse, relmse, render_reference, time_to_error,
};
use portalview::light::Strategy;
use portalview::render::integrator::RenderSettings;
use portalview::scene::Scene;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::AtomicBool;

/// The tests that time renders run one at a time, so that they do not share the cores.
static SERIAL: Mutex<()> = Mutex::new(());

fn serial() -> std::sync::MutexGuard<'static, ()> {
    SERIAL.lock().unwrap_or_else(|e| e.into_inner())
}

/// A fresh, empty folder under the system's temporary folder.
fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("portalview-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs `portalview compare` as a user would type it: a short fig8b comparison of every
/// strategy writing into `out`, with references cached in `cache`; `overrides` replace or add
/// flags (a flag with an empty value is a switch and drops `--scene`).
fn run_compare(out: &Path, cache: &Path, overrides: &[(&str, &str)]) {
    let (out, cache) = (out.display().to_string(), cache.display().to_string());
    let mut flags: Vec<(&str, &str)> = vec![
        ("--scene", "fig8b"),
        ("--seconds", "0.2"),
        ("--out", &out),
        ("--width", "24"),
        ("--height", "18"),
        ("--seed", "3"),
        ("--max-depth", "1"),
        ("--reference-spp", "64"),
        ("--cache-dir", &cache),
    ];
    for &(flag, value) in overrides {
        if value.is_empty() {
            flags.retain(|(f, _)| *f != "--scene");
        }
        flags.retain(|(f, _)| *f != flag);
        flags.push((flag, value));
    }
    let mut args = vec!["portalview", "compare"];
    for (flag, value) in flags {
        args.push(flag);
        if !value.is_empty() {
            args.push(value);
        }
    }
    let cli = Cli::try_parse_from(args).unwrap();
    run(cli.command.unwrap()).unwrap();
}

/// Parses a CSV without quoted fields: the header and the rows.
fn read_csv(path: &Path) -> (String, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().to_owned();
    let rows = lines
        .map(|l| l.split(',').map(str::to_owned).collect())
        .collect();
    (header, rows)
}

fn assert_svg(path: &Path, strategies: usize) {
    let svg = std::fs::read_to_string(path).unwrap();
    let start = svg.trim_start();
    assert!(
        start.starts_with("<svg") || start.starts_with("<?xml"),
        "{}",
        &svg[..80.min(svg.len())]
    );
    assert!(svg.trim_end().ends_with("</svg>"));
    // One line per strategy, and as many legend entries.
    let lines = svg.matches("<polyline").count() + svg.matches("<path").count();
    assert!(
        lines >= strategies,
        "{lines} polylines for {strategies} strategies"
    );
    for s in Strategy::ALL {
        assert!(svg.contains(s.name()), "no legend for {}", s.name());
    }
}

#[test]
fn metrics_match_hand_computed_values() {
    let reference = [Vec3::new(1.0, 1.0, 1.0), Vec3::new(0.0, 0.0, 0.0)];
    let image = [Vec3::new(2.0, 1.0, 1.0), Vec3::new(0.0, 0.0, 0.1)];
    // Squared errors 1, 0, 0 and 0, 0, 0.01 over six channels.
    assert!((mse(&image, &reference) - 1.01 / 6.0).abs() < 1e-7);
    // 1 / (1 + ε) in the first pixel, 0.01 / (0 + ε) = 1 in the second (ε = 0.01).
    assert_eq!(RELMSE_EPSILON, 1e-2);
    let expected = (1.0 / 1.01 + 1.0) / 6.0;
    assert!(
        (relmse(&image, &reference) - expected).abs() < 1e-6,
        "{}",
        relmse(&image, &reference)
    );
    assert_eq!(mse(&reference, &reference), 0.0);
    assert_eq!(relmse(&reference, &reference), 0.0);
    // Symmetric in its arguments for MSE only.
    assert_eq!(mse(&image, &reference), mse(&reference, &image));
    assert_eq!(mse(&[], &[]), 0.0);
}

#[test]
fn short_compare_writes_csv_svg_and_summary() {
    let _serial = serial();
    let root = temp_dir("compare");
    let (out, cache) = (root.join("out"), root.join("cache"));
    run_compare(&out, &cache, &[]);

    let (header, rows) = read_csv(&out.join("convergence.csv"));
    assert_eq!(header, "scene,strategy,seconds,spp,mse,relmse");
    assert!(!rows.is_empty());
    for s in Strategy::ALL {
        let mine: Vec<&Vec<String>> = rows.iter().filter(|r| r[1] == s.name()).collect();
        assert!(!mine.is_empty(), "no rows for {}", s.name());
        let mut last = (0.0f64, 0u32);
        for r in mine {
            assert_eq!(r.len(), 6, "{r:?}");
            assert_eq!(r[0], "fig8b");
            let seconds: f64 = r[2].parse().unwrap();
            let spp: u32 = r[3].parse().unwrap();
            let (m, rel): (f64, f64) = (r[4].parse().unwrap(), r[5].parse().unwrap());
            assert!(
                seconds > last.0 && spp > last.1,
                "{} not increasing: {r:?}",
                s.name()
            );
            assert!(
                m.is_finite() && m >= 0.0 && rel.is_finite() && rel >= 0.0,
                "{r:?}"
            );
            last = (seconds, spp);
        }
        // Each strategy ran for its time, overshooting by one short pass at most.
        assert!(last.0 >= 0.2 && last.0 < 0.4, "{}: {} s", s.name(), last.0);
    }
    assert_svg(&out.join("convergence.svg"), Strategy::ALL.len());
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    for s in Strategy::ALL {
        assert!(summary.contains(&format!("| {} |", s.name())), "{summary}");
    }
    assert!(summary.contains("relative standard error"), "{summary}");
    // The reference was rendered and cached: one EXR and its sidecar.
    let cached: Vec<String> = std::fs::read_dir(&cache)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        cached.iter().filter(|n| n.ends_with(".exr")).count(),
        1,
        "{cached:?}"
    );
    assert_eq!(
        cached.iter().filter(|n| n.ends_with(".json")).count(),
        1,
        "{cached:?}"
    );
    let _ = std::fs::remove_dir_all(&root);
}

/// `--runs 3` compares three times against one reference, with seeds 3, 4 and 5: a folder of
/// files per run whose summary names its seed, and `runs.csv` / `runs.md` over all three.
/// Negative case: `--runs 0` is an error, not an empty report.
#[test]
fn compare_runs_write_each_seed_and_the_mean() {
    let _serial = serial();
    let root = temp_dir("runs");
    let (out, cache) = (root.join("out"), root.join("cache"));
    run_compare(
        &out,
        &cache,
        &[
            ("--runs", "3"),
            ("--strategies", "light,antishadow"),
            ("--seconds", "0.1"),
        ],
    );
    for seed in 3..6 {
        let summary = std::fs::read_to_string(out.join(format!("seed-{seed}/summary.md"))).unwrap();
        assert!(summary.contains(&format!("seed {seed},")), "{summary}");
    }
    let (header, rows) = read_csv(&out.join("runs.csv"));
    assert_eq!(
        header,
        "seed,strategy,spp,seconds,mse,mse_above_floor,efficiency_vs_light,\
         efficiency_vs_light_above_floor"
    );
    let seeds: Vec<(&str, &str)> = rows
        .iter()
        .map(|r| (r[0].as_str(), r[1].as_str()))
        .collect();
    assert_eq!(
        seeds,
        [
            ("3", "light"),
            ("3", "antishadow"),
            ("4", "light"),
            ("4", "antishadow"),
            ("5", "light"),
            ("5", "antishadow")
        ]
    );
    for r in &rows {
        let efficiency: f64 = r[6].parse().unwrap();
        assert!(efficiency.is_finite() && efficiency > 0.0, "{r:?}");
    }
    let md = std::fs::read_to_string(out.join("runs.md")).unwrap();
    assert!(md.contains("over 3 runs: fig8b"), "{md}");
    assert!(md.contains("seeds 3, 4, 5"), "{md}");
    assert!(
        md.contains("| antishadow | 3 |") && md.contains(" ± "),
        "{md}"
    );
    let cached = std::fs::read_dir(&cache)
        .unwrap()
        .filter(|e| {
            e.as_ref()
                .unwrap()
                .path()
                .extension()
                .is_some_and(|x| x == "exr")
        })
        .count();
    assert_eq!(cached, 1, "one reference for all runs");

    let cli = Cli::try_parse_from([
        "portalview",
        "compare",
        "--scene",
        "fig8b",
        "--seconds",
        "0.1",
        "--runs",
        "0",
        "--out",
        &out.display().to_string(),
    ])
    .unwrap();
    let err = run(cli.command.unwrap()).unwrap_err();
    assert!(err.to_string().contains("--runs"), "{err}");
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn figure8_writes_its_table_for_every_scene() {
    let _serial = serial();
    let root = temp_dir("figure8");
    let (out, cache) = (root.join("out"), root.join("cache"));
    let overrides = [
        ("--figure8", ""),
        ("--seconds", "0.05"),
        ("--width", "16"),
        ("--height", "12"),
        ("--reference-spp", "16"),
    ];
    run_compare(&out, &cache, &overrides);
    let (header, rows) = read_csv(&out.join("figure8.csv"));
    assert_eq!(header, "scene,strategy,seconds,mse,efficiency_vs_light");
    assert_eq!(rows.len(), 3 * Strategy::ALL.len());
    for scene in ["fig8a", "fig8b", "fig8c"] {
        for s in Strategy::ALL {
            let row = rows
                .iter()
                .find(|r| r[0] == scene && r[1] == s.name())
                .unwrap_or_else(|| panic!("no row for {scene} {}", s.name()));
            assert!(row[2].parse::<f64>().unwrap() >= 0.05);
            assert!(row[3].parse::<f64>().unwrap() >= 0.0);
            let efficiency: f64 = row[4].parse().unwrap();
            if s == Strategy::Light {
                assert!((efficiency - 1.0).abs() < 1e-9);
            }
        }
        assert!(out.join(scene).join("convergence.csv").exists());
        assert!(out.join(scene).join("summary.md").exists());
    }
    assert_svg(&out.join("figure8.svg"), Strategy::ALL.len());
    let md = std::fs::read_to_string(out.join("figure8.md")).unwrap();
    assert!(md.contains("| fig8c | antishadow |"), "{md}");
    let _ = std::fs::remove_dir_all(&root);
}

/// `--light-selection power,tree` renders every strategy with each selection against one
/// reference, side by side: each selection's runs in its own folder, every run given the same
/// pass time. Negative case: a selection listed twice is an error.
#[test]
fn compare_renders_two_light_selections_side_by_side() {
    let _serial = serial();
    let root = temp_dir("selections");
    let (out, cache) = (root.join("out"), root.join("cache"));
    run_compare(
        &out,
        &cache,
        &[
            ("--scene", "desklamp"),
            ("--runs", "2"),
            ("--strategies", "light,antishadow"),
            ("--light-selection", "power,tree"),
            ("--seconds", "0.1"),
        ],
    );
    for selection in ["power", "tree"] {
        let md = std::fs::read_to_string(out.join(selection).join("runs.md")).unwrap();
        assert!(md.contains("over 2 runs: desklamp"), "{selection}: {md}");
        let (_, rows) = read_csv(&out.join(selection).join("runs.csv"));
        assert_eq!(rows.len(), 4, "{selection}: {rows:?}");
        for r in &rows {
            let seconds: f64 = r[3].parse().unwrap();
            // Each run stops at the first pass past 0.1 s. How far past depends on the
            // machine's load, not on the code (issue 40: this asked for under 0.2 s).
            assert!(seconds >= 0.1, "{selection}: {r:?}");
        }
    }
    let cli = Cli::try_parse_from([
        "portalview",
        "compare",
        "--scene",
        "desklamp",
        "--seconds",
        "0.1",
        "--light-selection",
        "tree,tree",
        "--out",
        &out.display().to_string(),
    ])
    .unwrap();
    let err = run(cli.command.unwrap()).unwrap_err();
    assert!(err.to_string().contains("twice"), "{err}");
    let _ = std::fs::remove_dir_all(&root);
}

/// `--glass-shadows pass,stop` renders every strategy both ways against one reference, each in
/// its own folder, and prints the efficiency of stopping over passing. Negative case: both
/// lists with two entries is an error that names them.
#[test]
fn compare_renders_glass_passing_and_stopping_side_by_side() {
    let _serial = serial();
    let root = temp_dir("glass");
    let (out, cache) = (root.join("out"), root.join("cache"));
    run_compare(
        &out,
        &cache,
        &[
            ("--scene", "panes"),
            ("--strategies", "antishadow"),
            ("--glass-shadows", "pass,stop"),
            ("--seconds", "0.1"),
        ],
    );
    for glass in ["glass-pass", "glass-stop"] {
        let (_, rows) = read_csv(&out.join(glass).join("convergence.csv"));
        assert!(!rows.is_empty(), "{glass}");
        assert!(
            rows.iter().all(|r| r[1] == "antishadow"),
            "{glass}: {rows:?}"
        );
    }
    let cli = Cli::try_parse_from([
        "portalview",
        "compare",
        "--scene",
        "panes",
        "--seconds",
        "0.1",
        "--light-selection",
        "power,tree",
        "--glass-shadows",
        "pass,stop",
        "--out",
        &out.display().to_string(),
    ])
    .unwrap();
    let err = run(cli.command.unwrap()).unwrap_err();
    assert!(err.to_string().contains("--glass-shadows"), "{err}");
    let _ = std::fs::remove_dir_all(&root);
}

/// This checks the scheduling, not the strategies' speed: whatever each pass costs, every
/// strategy's accumulated pass time must end within one pass of the others'. The bound is the
/// longest step measured here (a pass and its bookkeeping), not a share of the clock, so a
/// loaded machine's stall widens it rather than failing the test (issue 40: it asked for 10%
/// of the mean).
#[test]
fn equal_time_scheduler_shares_time_evenly() {
    let _serial = serial();
    let scene = Scene::open("fig8c").unwrap();
    let mut schedule = EqualTime::new(scene, &Strategy::ALL, 32, 24, RenderSettings::default());
    // Ties go by order: the first four steps render each strategy once, in order.
    let never = AtomicBool::new(false);
    let mut longest_step = 0.0f64;
    for i in 0..4 {
        let start = std::time::Instant::now();
        assert_eq!(schedule.step(&never).unwrap(), Some(i));
        longest_step = longest_step.max(start.elapsed().as_secs_f64());
    }
    while schedule.runs().iter().map(|r| r.seconds).sum::<f64>() < 1.0 {
        let start = std::time::Instant::now();
        schedule.step(&never).unwrap();
        longest_step = longest_step.max(start.elapsed().as_secs_f64());
    }
    let seconds: Vec<f64> = schedule.runs().iter().map(|r| r.seconds).collect();
    let (least, most) = seconds
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &s| (a.min(s), b.max(s)));
    assert!(
        most - least <= longest_step,
        "{seconds:?}: more than the longest step ({longest_step} s) apart"
    );
    for run in schedule.runs() {
        assert!(run.film.spp > 1 && run.stats.samples == run.film.spp as u64);
    }
    // A cancelled pass changes nothing.
    let before: Vec<u32> = schedule.runs().iter().map(|r| r.film.spp).collect();
    assert!(schedule.step(&AtomicBool::new(true)).is_err());
    let after: Vec<u32> = schedule.runs().iter().map(|r| r.film.spp).collect();
    assert_eq!(before, after);
    // Without strategies there is nothing to step.
    let empty = Scene::open("fig8c").unwrap();
    let mut none = EqualTime::new(empty, &[], 8, 8, RenderSettings::default());
    assert_eq!(none.step(&never).unwrap(), None);
}

#[test]
fn reference_cache_hits_on_second_request() {
    let _serial = serial();
    let cache = temp_dir("cache");
    let scene = Scene::open("fig8b").unwrap();
    let image = ImageSpec {
        width: 20,
        height: 15,
        max_depth: 1,
    };
    let hidden = ProgressBar::hidden();
    let budget = ReferenceBudget::Spp(8);
    let first = cached_reference(&cache, &scene, image, 0, budget, &hidden).unwrap();
    let key = cache_key(&scene, image);
    let exr = cache.join(format!("{key}.exr"));
    assert_eq!(first.origin, ReferenceOrigin::Rendered(Some(exr.clone())));
    assert!(exr.exists() && cache.join(format!("{key}.json")).exists());
    let info = first.info.clone().unwrap();
    assert_eq!((info.spp, info.width, info.height), (8, 20, 15));
    assert!(
        info.convergence.mse_floor > 0.0 && info.convergence.mean_relative_standard_error > 0.0
    );

    // Same key: loaded, identical pixels and information.
    let second = cached_reference(&cache, &scene, image, 0, budget, &hidden).unwrap();
    assert_eq!(second.origin, ReferenceOrigin::Cached(exr.clone()));
    assert_eq!(second.pixels, first.pixels);
    // JSON keeps the information, floats to their last bit but one (serde_json's default
    // parser may round the final digit of a 17-digit decimal).
    let (a, b) = (first.info.clone().unwrap(), second.info.clone().unwrap());
    assert!((a.seconds - b.seconds).abs() <= 1e-12 * a.seconds.abs().max(1.0));
    let close = |x: f64, y: f64| (x - y).abs() <= 1e-12 * x.abs().max(1e-300);
    assert!(close(a.convergence.mse_floor, b.convergence.mse_floor));
    assert!(close(
        a.convergence.mean_relative_standard_error,
        b.convergence.mean_relative_standard_error
    ));
    assert_eq!(
        (a.key, a.spp, a.width, a.height, a.seed),
        (b.key, b.spp, b.width, b.height, b.seed)
    );
    // A smaller budget is covered by the cached one; a larger one renders again.
    let smaller =
        cached_reference(&cache, &scene, image, 0, ReferenceBudget::Spp(4), &hidden).unwrap();
    assert_eq!(smaller.origin, ReferenceOrigin::Cached(exr.clone()));
    let larger =
        cached_reference(&cache, &scene, image, 0, ReferenceBudget::Spp(12), &hidden).unwrap();
    assert_eq!(larger.origin, ReferenceOrigin::Rendered(Some(exr.clone())));
    assert_eq!(larger.info.unwrap().spp, 12);

    // A damaged entry is a miss, rendered again and replaced.
    std::fs::write(cache.join(format!("{key}.json")), "{ not json").unwrap();
    let repaired = cached_reference(&cache, &scene, image, 0, budget, &hidden).unwrap();
    assert_eq!(
        repaired.origin,
        ReferenceOrigin::Rendered(Some(exr.clone()))
    );
    let again = cached_reference(&cache, &scene, image, 0, budget, &hidden).unwrap();
    assert_eq!(again.origin, ReferenceOrigin::Cached(exr.clone()));

    // The key is stable and depends on the scene's content, camera and image settings.
    assert_eq!(cache_key(&Scene::open("fig8b").unwrap(), image), key);
    assert_ne!(cache_key(&Scene::open("fig8c").unwrap(), image), key);
    assert_ne!(cache_key(&scene, ImageSpec { width: 21, ..image }), key);
    assert_ne!(
        cache_key(
            &scene,
            ImageSpec {
                max_depth: 2,
                ..image
            }
        ),
        key
    );
    let mut moved = scene.clone();
    moved.camera.eye.x += 0.01;
    assert_ne!(cache_key(&moved, image), key);
    let _ = std::fs::remove_dir_all(&cache);
}

/// Time to an equal error stops at the first pass whose relMSE is at most the target, and a run
/// stopped by the cap is extrapolated as relMSE ∝ 1/time; the error at a given spp is that of a
/// render of exactly that many passes.
#[test]
fn time_to_error_stops_at_the_target_or_the_cap() {
    let scene = Scene::open("fig8c").unwrap();
    let image = ImageSpec {
        width: 16,
        height: 12,
        max_depth: 1,
    };
    let never = AtomicBool::new(false);
    let reference = render_reference(
        &scene,
        image,
        0,
        ReferenceBudget::Spp(32),
        &never,
        &ProgressBar::hidden(),
    )
    .unwrap();
    let settings = RenderSettings::default();
    let easy = time_to_error(&scene, settings, &reference, 1e9, 60.0);
    assert!(easy.reached);
    assert_eq!(easy.spp, 1);
    assert_eq!(easy.estimated_seconds(1e9), easy.seconds);
    // A target no render reaches: the cap (zero: one pass) stops it, and the time needed is
    // extrapolated from the error reached.
    let hard = time_to_error(&scene, settings, &reference, 1e-30, 0.0);
    assert!(!hard.reached);
    assert_eq!(hard.spp, 1);
    assert!(hard.relmse > 1e-30);
    let extrapolated = hard.estimated_seconds(1e-30);
    assert!((extrapolated / (hard.seconds * hard.relmse / 1e-30) - 1.0).abs() < 1e-12);
    // The error at one spp is the error of the one-pass render above (same seed and sampler).
    let (mse, relmse) = error_at_spp(&scene, settings, &reference, 1);
    assert_eq!((mse, relmse), (hard.mse, hard.relmse));
}
