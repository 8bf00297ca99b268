//! Where a results file came from: the command that wrote it (to run it again), when, from
//! which revision, on what machine. Every writer of `docs/results/` and of a reproduction's
//! `results.json` puts one beside its rows as `provenance`; `host-sim tables` shows it on
//! the file's page. Readers take files without it (written before it existed).
//!
//! Nothing here enters a figure: the date is the one wall-clock field of a results file, and
//! comparisons of results (tests, `host-sim moved`) look at rows only.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{SystemTime, UNIX_EPOCH};

use serde::{Deserialize, Serialize};

/// What is not known is said so, never guessed.
pub const UNKNOWN: &str = "unknown";

/// The command, date, revision and machine of one run of a tool.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Provenance {
    /// The program: `host-sim`, `policy-export`, or a script's path from the repository's root.
    pub tool: String,
    /// Its arguments after the program's name: `cargo run --release -p TOOL -- ARGV...` (or
    /// `python TOOL ARGV...`) runs it again.
    pub argv: Vec<String>,
    /// When it ran: UTC, RFC 3339 to the second.
    pub date: String,
    /// `git rev-parse --short HEAD` of the checkout the tool was built from, or [`UNKNOWN`].
    pub revision: String,
    /// Whether tracked files differed from that revision (`git status`): the code that ran
    /// was the revision with those changes. False where git is not there to say.
    pub dirty: bool,
    /// Logical CPUs this process could use (`nproc`).
    pub nproc: usize,
    /// The CPU's model name, family and model (`/proc/cpuinfo`), or [`UNKNOWN`].
    pub cpu: String,
}

impl Provenance {
    /// This process's run of `tool`, with the arguments it was given: a path need not be
    /// UTF-8, so one that is not is recorded with U+FFFD for its stray bytes (`args()`
    /// panicked there, after the work).
    pub fn of_this_run(tool: &str) -> Provenance {
        let argv = std::env::args_os().skip(1);
        Provenance::new(
            tool,
            argv.map(|a| a.to_string_lossy().into_owned()).collect(),
        )
    }

    /// A run of `tool` with `argv`, now, on this machine, of the revision it was built from.
    pub fn new(tool: &str, argv: Vec<String>) -> Provenance {
        let seconds = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .map_or(0, |d| d.as_secs());
        let (revision, dirty) = revision();
        Provenance {
            tool: tool.to_string(),
            argv,
            date: rfc3339(seconds),
            revision,
            dirty,
            nproc: std::thread::available_parallelism().map_or(1, usize::from),
            cpu: cpu_model(),
        }
    }

    /// The command as one line, the arguments joined by spaces.
    pub fn command(&self) -> String {
        std::iter::once(self.tool.as_str())
            .chain(self.argv.iter().map(String::as_str))
            .collect::<Vec<_>>()
            .join(" ")
    }

    /// A Markdown list of the command, the run and the machine, as a generated page shows it.
    pub fn markdown(&self) -> String {
        let changes = if self.dirty {
            " with uncommitted changes"
        } else {
            ""
        };
        // A results file's provenance is its writer's word: text from it (an argument with
        // a line break or a `|`, a CPU's name with an escape) is escaped, never copied.
        let text = weights::markdown::text;
        format!(
            "- command: {}\n- run: {}, revision {}{changes}\n- machine: {} CPUs, {}\n",
            weights::markdown::code(&self.command()),
            text(&self.date),
            text(&self.revision),
            self.nproc,
            text(&self.cpu)
        )
    }
}

/// The short revision of HEAD and whether tracked files differ from it, in the checkout the
/// tool was built from: the code that ran. Never the working directory's, which is any
/// checkout a user stands in: its configuration runs commands (`core.fsmonitor`) and its
/// index is rewritten by a status that refreshes it. Git is given no environment of the
/// caller's (`GIT_DIR` would send it elsewhere) and may not look above the workspace (a
/// repository around it is not its); unknown where the workspace is no checkout of its own.
fn revision() -> (String, bool) {
    let unknown = (UNKNOWN.to_string(), false);
    let Ok(root) = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .canonicalize()
    else {
        return unknown;
    };
    let ceiling = root.parent().unwrap_or(&root).to_path_buf();
    let git = |args: &[&str]| {
        let out = Command::new("git")
            .current_dir(&root)
            .env_clear()
            .env("PATH", std::env::var_os("PATH").unwrap_or_default())
            .env("GIT_CEILING_DIRECTORIES", &ceiling)
            .args(["--no-optional-locks", "-c", "core.fsmonitor=false"])
            .args(args)
            .output()
            .ok()?;
        out.status
            .success()
            .then(|| String::from_utf8_lossy(&out.stdout).trim().to_string())
    };
    if git(&["rev-parse", "--show-toplevel"]).map(PathBuf::from) != Some(root.clone()) {
        return unknown;
    }
    match git(&["rev-parse", "--short", "HEAD"]) {
        Some(rev) if !rev.is_empty() => {
            let dirty = git(&["status", "--porcelain", "--untracked-files=no"])
                .is_some_and(|s| !s.is_empty());
            (rev, dirty)
        }
        _ => unknown,
    }
}

/// The first processor's model name, family and model in `/proc/cpuinfo`.
fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|text| cpuinfo_model(&text))
        .unwrap_or_else(|| UNKNOWN.to_string())
}

/// `model name, family F, model M` of the first processor in a cpuinfo text (as many of the
/// three as it gives), or none if it gives no model name.
fn cpuinfo_model(text: &str) -> Option<String> {
    let first = text.split("\n\n").next()?;
    let field = |key: &str| {
        first.lines().find_map(|l| {
            let (k, v) = l.split_once(':')?;
            (k.trim() == key).then(|| v.trim().to_string())
        })
    };
    let mut out = field("model name")?;
    if let Some(f) = field("cpu family") {
        out += &format!(", family {f}");
    }
    if let Some(m) = field("model") {
        out += &format!(", model {m}");
    }
    Some(out)
}

/// `seconds` after the Unix epoch as `YYYY-MM-DDTHH:MM:SSZ` (the proleptic Gregorian
/// calendar; days to a date by Hinnant's `civil_from_days`).
pub fn rfc3339(seconds: u64) -> String {
    let (days, rest) = (seconds / 86_400, seconds % 86_400);
    let z = days as i64 + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1_460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}Z",
        rest / 3_600,
        rest / 60 % 60,
        rest % 60
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dates_are_the_calendars() {
        // References from Python's datetime.fromtimestamp(s, timezone.utc).isoformat().
        let cases = [
            (0, "1970-01-01T00:00:00Z"),
            (951_782_400, "2000-02-29T00:00:00Z"),
            (1_709_251_199, "2024-02-29T23:59:59Z"),
            (1_796_256_000, "2026-12-03T00:00:00Z"),
            (4_107_542_400, "2100-03-01T00:00:00Z"),
            (253_402_300_799, "9999-12-31T23:59:59Z"),
        ];
        for (s, want) in cases {
            assert_eq!(rfc3339(s), want, "{s}");
        }
    }

    #[test]
    fn the_cpu_is_the_first_processors() {
        let text = "processor\t: 0\nvendor_id\t: AuthenticAMD\ncpu family\t: 26\nmodel\t\t: 2\n\
                    model name\t: AMD EPYC 9B45\n\nprocessor\t: 1\nmodel name\t: other\n";
        assert_eq!(
            cpuinfo_model(text).as_deref(),
            Some("AMD EPYC 9B45, family 26, model 2")
        );
        // aarch64's cpuinfo names no model: unknown rather than a guess.
        assert_eq!(cpuinfo_model("processor\t: 0\nCPU part\t: 0xd0c\n"), None);
    }

    #[test]
    fn it_round_trips_and_names_its_command() {
        let mut p = Provenance::new("host-sim", vec!["eval".into(), "--json".into()]);
        assert_eq!(p.command(), "host-sim eval --json");
        assert!(p.nproc >= 1 && p.date.ends_with('Z') && p.date.len() == 20);
        let json = serde_json::to_string(&p).unwrap();
        assert_eq!(serde_json::from_str::<Provenance>(&json).unwrap(), p);
        (p.date, p.revision, p.dirty) = ("2026-12-03T00:00:00Z".into(), "abc1234".into(), true);
        (p.nproc, p.cpu) = (2, "AMD EPYC".into());
        let want = "- command: `host-sim eval --json`\n\
                    - run: 2026-12-03T00:00:00Z, revision abc1234 with uncommitted changes\n\
                    - machine: 2 CPUs, AMD EPYC\n";
        assert_eq!(p.markdown(), want);
        p.argv.push("\u{1b}[2J`\n# injected | x".into());
        (p.cpu, p.revision) = ("cpu\u{7}\n| evil |".into(), "<b>".into());
        let want = "- command: `host-sim eval --json \\u{1b}[2J\\u{60}\\n# injected \\| x`\n\
                    - run: 2026-12-03T00:00:00Z, revision \\<b> with uncommitted changes\n\
                    - machine: 2 CPUs, cpu\\u{7}\\n\\| evil \\|\n";
        assert_eq!(p.markdown(), want);
    }
}
