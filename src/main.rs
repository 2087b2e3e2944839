use clap::Parser;
use portalview::cli::{Cli, Command, run};

fn main() {
    // Rust ignores SIGPIPE, so printing to a pipe that was closed (`portalview … | head`)
    // panics; a command-line tool ends quietly there instead.
    #[cfg(unix)]
    // SAFETY: at start-up, before any other thread exists; restores the default action.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    let command = cli.command.unwrap_or(Command::View(Default::default()));
    if let Err(e) = run(command) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
