use clap::Parser;
use portalview::cli::{Cli, Command, run};

fn main() {
    let cli = Cli::parse();
    let command = cli.command.unwrap_or(Command::View(Default::default()));
    if let Err(e) = run(command) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
