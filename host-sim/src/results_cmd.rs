//! `host-sim results`: the steps of `docs/results/manifest.toml` for `scripts/regenerate.sh`,
//! and which rows of a results file moved when it was measured again.

use std::path::PathBuf;

use anyhow::{Result, anyhow};
use clap::{Args, Subcommand};
use host_sim::manifest::Manifest;
use host_sim::moved;

use crate::tables_cmd::{find_root, read_results};

#[derive(Args)]
pub struct ResultsArgs {
    #[command(subcommand)]
    action: Action,
}

#[derive(Subcommand)]
enum Action {
    /// Print the manifest's steps in order, one a line, the fields separated by tabs and `-`
    /// where there is none: name, cost, needs (comma-separated), rebuild (1 or 0), the
    /// output if the command prints it, the output, prepare, run, about.
    Steps {
        /// The repository's root (default: the nearest directory at or above the current one
        /// that holds a Cargo.toml and docs/results/).
        #[arg(long)]
        root: Option<PathBuf>,
    },
    /// Compare two versions of a results file: per row, the figures now outside their
    /// earlier 95% intervals, the rows that changed within them, the rows new and gone.
    Moved {
        /// The earlier version.
        old: PathBuf,
        /// The new one.
        new: PathBuf,
        /// The file's name in the report [default: NEW].
        #[arg(long)]
        name: Option<String>,
    },
}

pub fn run(a: &ResultsArgs) -> Result<()> {
    match &a.action {
        Action::Steps { root } => {
            let root = match root {
                Some(r) => r.clone(),
                None => find_root(&std::env::current_dir()?)?,
            };
            let m = Manifest::load(&root)?;
            let or = |o: Option<&str>| o.unwrap_or("-").to_string();
            for s in &m.steps {
                let printed = s.stdout.then_some(s.output.as_deref()).flatten();
                let needs = if s.needs.is_empty() {
                    "-".to_string()
                } else {
                    s.needs.join(",")
                };
                let fields = [
                    s.name.clone(),
                    // Shortest: `{}` writes 1e300 out in 301 digits.
                    format!("{:?}", s.cost),
                    needs,
                    u8::from(s.rebuild).to_string(),
                    or(printed),
                    or(s.output.as_deref()),
                    or(s.prepare.as_deref()),
                    s.run.clone(),
                    s.about.clone(),
                ];
                host_common::outln!("{}", fields.join("\t"));
            }
        }
        Action::Moved { old, new, name } => {
            let json = |p: &PathBuf| -> Result<serde_json::Value> {
                let text = read_results(p)?;
                weights::json::value(&text).map_err(|e| {
                    anyhow!("{}: expected a results file's JSON, {e}", weights::shown(p))
                })
            };
            let (was, now) = (json(old)?, json(new)?);
            for (doc, path) in [(&was, old), (&now, new)] {
                moved::check(doc).map_err(|e| anyhow!("{}: {e}", weights::shown(path)))?;
            }
            let name = name
                .as_deref()
                .map_or_else(|| weights::shown(new), weights::excerpt);
            host_common::out!("{}", moved::report(&name, &moved::compare(&was, &now)));
        }
    }
    Ok(())
}
