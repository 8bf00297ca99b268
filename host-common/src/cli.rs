//! Command-line parsing with the project's refusal rules: clap's own message for a bad
//! flag, but with no line longer than a few hundred characters (clap quotes the offending
//! value whole, and a value can be 128 KB), and exit status 2.
//!
//! And the tools' one way to print: [`out!`](crate::out), [`outln!`](crate::outln) and
//! [`errln!`](crate::errln) never panic, where `print!` panics once its reader has gone
//! (`host-sim eval --json | head -c 100`). A closed standard output ends the printing, not
//! the work: files being written are still finished, and [`exit`] then reports success
//! quietly, as Unix tools do when their reader has seen enough. Any other failure to write
//! it (a full disk) turns success into exit status 1. Both binaries deny `print!` and
//! `eprint!` (clippy's `print_stdout`, `print_stderr`), so nothing prints another way.

use std::io::Write;
use std::process::ExitCode;
use std::sync::Mutex;

use clap::error::ErrorKind;

/// The first error writing standard output, after which nothing more is written to it.
static STDOUT_FAILED: Mutex<Option<std::io::Error>> = Mutex::new(None);

/// Writes to standard output unless an earlier write failed; a failure is kept for
/// [`exit`], never a panic. What [`out!`](crate::out) and [`outln!`](crate::outln) call.
pub fn write_stdout(args: std::fmt::Arguments<'_>) {
    let mut failed = STDOUT_FAILED.lock().unwrap_or_else(|p| p.into_inner());
    if failed.is_some() {
        return;
    }
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_fmt(args).and_then(|()| out.flush()) {
        *failed = Some(e);
    }
}

/// Writes to standard error, ignoring failure: with standard error gone there is nowhere
/// left to say anything. What [`errln!`](crate::errln) calls.
pub fn write_stderr(args: std::fmt::Arguments<'_>) {
    let _ = std::io::stderr().lock().write_fmt(args);
}

/// `print!` that never panics: see the module's documentation.
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => { $crate::cli::write_stdout(format_args!($($arg)*)) };
}

/// `println!` that never panics: see the module's documentation.
#[macro_export]
macro_rules! outln {
    () => { $crate::cli::write_stdout(format_args!("\n")) };
    ($($arg:tt)*) => { $crate::cli::write_stdout(format_args!("{}\n", format_args!($($arg)*))) };
}

/// `eprintln!` that never panics.
#[macro_export]
macro_rules! errln {
    ($($arg:tt)*) => { $crate::cli::write_stderr(format_args!("{}\n", format_args!($($arg)*))) };
}

/// The process's exit status for a command that ended with `status`: unchanged, except that
/// a success whose standard output could not be written for another reason than a reader
/// that left (a closed pipe) becomes 1, with the reason.
pub fn exit(status: u8) -> ExitCode {
    ExitCode::from(status_after(status))
}

/// [`exit`]'s status, as a number.
fn status_after(status: u8) -> u8 {
    let failed = STDOUT_FAILED.lock().unwrap_or_else(|p| p.into_inner());
    match failed.as_ref() {
        Some(e) if status == 0 && e.kind() != std::io::ErrorKind::BrokenPipe => {
            write_stderr(format_args!("error: writing standard output: {e}\n"));
            1
        }
        _ => status,
    }
}

/// Most threads a pool may be given, by `--threads` or by `RAYON_NUM_THREADS`.
pub const MAX_THREADS: usize = 256;

/// Refuses a thread count from the environment the thread pools would take unchecked
/// (`RAYON_NUM_THREADS`, or the older `RAYON_RS_NUM_CPUS` they still read): a whole number
/// from 0 (one a processor) to [`MAX_THREADS`], or unset. 100,000 spent 20 s starting
/// threads and then panicked.
pub fn check_threads_env() -> Result<(), String> {
    for var in ["RAYON_NUM_THREADS", "RAYON_RS_NUM_CPUS"] {
        let Some(v) = std::env::var_os(var) else {
            continue;
        };
        if v.to_str()
            .and_then(|t| t.parse::<usize>().ok())
            .is_some_and(|n| n <= MAX_THREADS)
        {
            continue;
        }
        // Debug-quoted, so escaped; and cut, as every input a message shows.
        let shown: String = v.to_string_lossy().chars().take(200).collect();
        return Err(format!(
            "{var}: expected a whole number of threads from 0 (one a processor) to \
             {MAX_THREADS}, or unset; found {shown:?}"
        ));
    }
    Ok(())
}

/// Longest line of a refusal printed.
const LINE_MAX: usize = 300;

/// `T::parse()`, except that a refusal's lines are cut at [`LINE_MAX`] characters.
pub fn parse<T: clap::Parser>() -> T {
    parse_with(|c| c)
}

/// [`parse`], with the command changed by `edit` first: help made at run time (from a table
/// of the parts a flag takes, say).
pub fn parse_with<T: clap::Parser>(edit: impl FnOnce(clap::Command) -> clap::Command) -> T {
    let parsed = edit(T::command())
        .try_get_matches()
        .and_then(|mut m| <T as clap::FromArgMatches>::from_arg_matches_mut(&mut m));
    match parsed {
        Ok(t) => {
            if let Err(e) = check_threads_env() {
                crate::errln!("error: {e}");
                std::process::exit(2)
            }
            t
        }
        Err(e) => {
            // Printed through this module, so that a full disk is exit status 1 here too.
            if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
                write_stdout(format_args!("{}", e.render()));
                std::process::exit(i32::from(status_after(0)))
            }
            if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
                e.exit()
            }
            for line in e.render().to_string().lines() {
                crate::errln!("{}", cut(line));
            }
            std::process::exit(2)
        }
    }
}

/// The line, or its beginning and end around `...`: clap puts the offending value in the
/// middle and the reason at the end, which must survive.
fn cut(line: &str) -> String {
    let n = line.chars().count();
    if n <= LINE_MAX {
        return line.to_string();
    }
    let half = LINE_MAX / 2;
    let head: String = line.chars().take(half).collect();
    let tail: String = line.chars().skip(n - half).collect();
    format!("{head}...{tail}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_lines_are_cut_short_ones_kept() {
        assert_eq!(cut("error: no"), "error: no");
        let long = format!("error: '{}' is bad: the reason", "x".repeat(10_000));
        let c = cut(&long);
        assert_eq!(c.chars().count(), LINE_MAX + 3);
        assert!(
            c.starts_with("error: 'xx") && c.ends_with("is bad: the reason"),
            "{c}"
        );
    }
}
