//! `photonlab` command-line interface.

use clap::Parser;
use photonlab::cli::{Cli, expand_param_flags, run};

fn main() {
    let cli = Cli::parse_from(expand_param_flags(std::env::args().collect()));
    if let Err(e) = run(cli) {
        // One line: the chain of contexts joined, outermost first.
        let msg: Vec<String> = e.chain().map(|c| c.to_string()).collect();
        eprintln!("error: {}", msg.join(": "));
        std::process::exit(1);
    }
}
