//! The command line as a newcomer meets it (issue 40's papercuts): mistakes are refused before
//! any work is done, with a message that says what to do; piped output ends quietly.

use clap::Parser;
use portalview::cli::{Cli, run};
use std::path::PathBuf;
use std::time::{Duration, Instant};

fn cli(args: &[&str]) -> Result<Cli, clap::Error> {
    Cli::try_parse_from(std::iter::once("portalview").chain(args.iter().copied()))
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("portalview-cli-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A render whose output cannot be written is refused before it renders: an unknown image
/// type, a folder that does not exist, and `--spp 0` (a black image). Each asks for ten
/// minutes of samples, so only a refusal up front returns at once.
#[test]
fn render_refuses_what_it_cannot_write_before_rendering() {
    let dir = temp_dir("render");
    let missing = dir.join("no-such-folder").join("a.exr");
    let cases: [(Vec<String>, &str); 3] = [
        (
            vec!["--out".into(), dir.join("a.jpg").display().to_string()],
            "unknown image type",
        ),
        (
            vec!["--out".into(), missing.display().to_string()],
            "does not exist",
        ),
        (
            vec![
                "--out".into(),
                dir.join("a.exr").display().to_string(),
                "--spp".into(),
                "0".into(),
            ],
            "--spp must be at least 1",
        ),
    ];
    for (extra, expected) in cases {
        let mut args = vec!["render", "--scene", "lampshade", "--width", "8"];
        if !extra.contains(&"--spp".to_owned()) {
            args.extend(["--seconds", "600"]);
        }
        args.extend(extra.iter().map(String::as_str));
        let start = Instant::now();
        let error = run(cli(&args).unwrap().command.unwrap())
            .unwrap_err()
            .to_string();
        assert!(error.contains(expected), "{args:?}: {error}");
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "{args:?} rendered"
        );
    }
    assert!(!dir.join("a.exr").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// `export` writes a binary glTF, so it refuses a `.gltf` name (it wrote GLB bytes there).
#[test]
fn export_refuses_a_gltf_name() {
    let dir = temp_dir("export");
    let out = dir.join("a.gltf");
    let args = [
        "export",
        "--scene",
        "lampshade",
        "--out",
        out.to_str().unwrap(),
    ];
    let error = run(cli(&args).unwrap().command.unwrap())
        .unwrap_err()
        .to_string();
    assert!(error.contains(".glb"), "{error}");
    assert!(!out.exists());
    let glb = dir.join("a.glb");
    let args = [
        "export",
        "--scene",
        "lampshade",
        "--out",
        glb.to_str().unwrap(),
    ];
    run(cli(&args).unwrap().command.unwrap()).unwrap();
    assert!(glb.exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--environment 1,2` is a colour given wrong, and says so (it said the file must be .hdr or
/// .exr).
#[test]
fn a_colour_of_two_numbers_is_named_a_colour() {
    let args = [
        "render",
        "--scene",
        "window",
        "--environment",
        "1,2",
        "--out",
        "/tmp/never.exr",
    ];
    let error = run(cli(&args).unwrap().command.unwrap())
        .unwrap_err()
        .to_string();
    assert!(error.contains("three non-negative numbers"), "{error}");
}

/// `compare` without a scene names both ways to give one; every flag of every command has a
/// description, none cites the specification that is not shipped, and the scene lists name
/// every built-in.
#[test]
fn help_names_what_a_newcomer_needs() {
    let error = cli(&["compare", "--seconds", "1", "--out", "/tmp/x"])
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("--scene") && error.contains("--figure8"),
        "{error}"
    );
    use clap::CommandFactory;
    let command = Cli::command();
    for sub in command.get_subcommands() {
        for arg in sub.get_arguments() {
            let help = arg.get_help().map(|h| h.to_string()).unwrap_or_default();
            assert!(
                !help.is_empty() || arg.get_id() == "help" || arg.get_id() == "version",
                "{} --{}: no description",
                sub.get_name(),
                arg.get_id()
            );
            assert!(
                !help.contains("METHOD.md"),
                "{} --{}",
                sub.get_name(),
                arg.get_id()
            );
            for value in arg.get_possible_values() {
                let help = value.get_help().map(|h| h.to_string()).unwrap_or_default();
                assert!(!help.contains("METHOD.md"), "{}: {help}", sub.get_name());
            }
            // A default shown by clap is not repeated in the text.
            if !arg.get_default_values().is_empty() {
                assert!(
                    !help.contains("(default"),
                    "{} --{}",
                    sub.get_name(),
                    arg.get_id()
                );
            }
            if arg.get_id() == "scene" {
                for name in portalview::asset::builtin::NAMES {
                    assert!(
                        help.contains(name),
                        "{} --scene lacks {name}",
                        sub.get_name()
                    );
                }
            }
        }
    }
}

/// Piped into a reader that stops after a line (`| head -1`), a command ends quietly when the
/// pipe closes instead of panicking on its next print (exit status 101).
#[cfg(unix)]
#[test]
fn a_closed_pipe_ends_a_command_quietly() {
    use std::io::{BufRead, BufReader};
    use std::process::{Command, Stdio};
    let dir = temp_dir("pipe");
    let out = dir.join("found.glb");
    let mut child = Command::new(env!("CARGO_BIN_EXE_portalview"))
        .args([
            "portals",
            "--find",
            "lampshade",
            "--out",
            out.to_str().unwrap(),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    // The reader is dropped: the pipe is closed while the command still has lines to print.
    let status = child.wait().unwrap();
    assert_ne!(status.code(), Some(101), "{status:?} after {line:?}");
    let _ = std::fs::remove_dir_all(&dir);
}
