//! Command-line parsing with the project's refusal rules: clap's own message for a bad
//! flag, but with what it quotes of the command line escaped and cut as every message quotes
//! input (clap quotes a value or an unknown flag raw and whole: a line break in it forged a
//! line of its own, and a value can be 128 KB), no line longer than a few hundred
//! characters, and exit status 2.
//!
//! A text flag given bytes that are not UTF-8 is refused naming the flag and showing what was
//! found, its stray bytes as U+FFFD, where clap's message named neither.
//!
//! And the tools' one way to print: [`out!`](crate::out), [`outln!`](crate::outln) and
//! [`errln!`](crate::errln) never panic, where `print!` panics once its reader has gone
//! (`host-sim eval --json | head -c 100`). A closed standard output ends the printing, not
//! the work: files being written are still finished, and [`exit`] then reports success
//! quietly, as Unix tools do when their reader has seen enough. Any other failure to write
//! it (a full disk) turns success into exit status 1. Both binaries deny `print!` and
//! `eprint!` (clippy's `print_stdout`, `print_stderr`), so nothing prints another way.

use std::ffi::OsString;
use std::io::Write;
use std::process::ExitCode;
use std::sync::Mutex;

use clap::error::{ContextKind, ContextValue, ErrorKind};

mod joined;
mod refusal;

use joined::numbers_joined;
use refusal::{plus_signed, refusal};

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
            .and_then(weights::whole::<usize>)
            .is_some_and(|n| n <= MAX_THREADS)
        {
            continue;
        }
        return Err(format!(
            "{var}: expected a whole number of threads from 0 (one a processor) to \
             {MAX_THREADS}, or unset; found {}",
            weights::quote(&v.to_string_lossy())
        ));
    }
    Ok(())
}

/// Refuses a number in any argument, alone or as a part of a list or a spec (`--levels=-1,X`,
/// `friction=X/0.1`), that is written with a non-zero digit and reads as zero
/// ([`weights::reads_as_zero`]): every flag's own check passes a zero.
fn check_numbers(args: &[OsString]) -> Result<(), String> {
    let text: Vec<Option<&str>> = args.iter().map(|a| a.to_str()).collect();
    for (i, arg) in text.iter().enumerate() {
        let Some(arg) = arg else { continue };
        let pieces = arg.split([',', '+', '=', '@', '/', ':', ' ']);
        let mut numbers = pieces.flat_map(|p| p.split(".."));
        if let Some(piece) = numbers.find(|p| weights::reads_as_zero(p)) {
            let why = weights::zero_in_disguise(piece);
            // A value given apart from its flag is named by it; a flag holds its own.
            let before = i.checked_sub(1).and_then(|k| text[k]);
            let flag = before.filter(|f| f.starts_with("--") && !f.contains('='));
            let shown = match flag.filter(|_| !arg.starts_with("--")) {
                Some(f) => format!("{f} {}", weights::quote(arg)),
                None => weights::quote(arg),
            };
            return Err(format!("{shown}: {why}"));
        }
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
    let cmd = negative_numbers(edit(T::command()));
    let args = numbers_joined(&cmd, std::env::args_os().collect());
    let matched = cmd.clone().try_get_matches_from(&args);
    let signed = matched.as_ref().ok().and_then(|m| plus_signed(&cmd, m));
    let parsed =
        matched.and_then(|mut m| <T as clap::FromArgMatches>::from_arg_matches_mut(&mut m));
    match parsed {
        Ok(t) => {
            let checked = signed
                .map_or(Ok(()), Err)
                .and_then(|()| check_threads_env());
            if let Err(e) = checked.and_then(|()| check_numbers(&args)) {
                crate::errln!("error: {e}");
                std::process::exit(2)
            }
            t
        }
        Err(e) => {
            // Printed through this module, so that a full disk is exit status 1 here too.
            if let Some(arg) = clustered(&e, &args) {
                crate::errln!("{}", refusal::unexpected(arg, None));
                std::process::exit(2)
            }
            if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
                write_stdout(format_args!("{}", e.render()));
                std::process::exit(i32::from(status_after(0)))
            }
            if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
                e.exit()
            }
            if e.kind() == ErrorKind::InvalidUtf8 {
                crate::errln!("error: {}", not_utf8(&cmd, &args));
                std::process::exit(2)
            }
            for line in refusal(&e, &cmd, &args) {
                crate::errln!("{line}");
            }
            std::process::exit(2)
        }
    }
}

/// The argument that asked for the help or the version as the first of a cluster of short
/// flags (`-hello.pt`, a file's name), where no argument asked for it alone: clap printed
/// the help, exit 0, and did nothing.
fn clustered<'a>(e: &clap::Error, args: &'a [OsString]) -> Option<&'a str> {
    if !matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) {
        return None;
    }
    let text = before_dashes(args);
    let asked = ["-h", "--help", "-V", "--version", "help"];
    if text.iter().any(|a| asked.contains(a)) {
        return None;
    }
    text.into_iter()
        .skip(1)
        .find(|a| a.len() > 2 && (a.starts_with("-h") || a.starts_with("-V")))
}

/// The arguments before any `--`, the program's name first, as text: one that is not UTF-8
/// as empty, which no flag's name starts.
fn before_dashes(args: &[OsString]) -> Vec<&str> {
    let before = args.iter().take_while(|a| *a != "--");
    before.map(|a| a.to_str().unwrap_or_default()).collect()
}

/// `cmd` with every argument that takes a value, in it and its subcommands, taking one that
/// is a negative number (`--seed -1`, `--cart-start -0.1`): clap took it for a flag and said
/// "unexpected argument '-1' found", naming neither the flag nor what it takes, where the
/// flag's own parser or range check names both. A value that is no number (`--out -x`) is
/// still a flag to clap.
pub fn negative_numbers(mut cmd: clap::Command) -> clap::Command {
    let valued: Vec<clap::Id> = (cmd.get_arguments())
        .filter(|a| a.get_action().takes_values())
        .map(|a| a.get_id().clone())
        .collect();
    for id in valued {
        cmd = cmd.mut_arg(id, |a| a.allow_negative_numbers(true));
    }
    let subcommands: Vec<String> = (cmd.get_subcommands())
        .map(|c| c.get_name().to_string())
        .collect();
    for name in subcommands {
        cmd = cmd.mut_subcommand(name, negative_numbers);
    }
    cmd
}

/// Stands for the stray bytes of the one argument being traced, in the parse that finds the
/// flag holding it (a private-use character nobody types).
const MARK: &str = "\u{10FFFD}";

/// The refusal of `args`, which `cmd` refuses as not UTF-8: the flag that takes text and
/// what it was given, stray bytes as U+FFFD. clap names neither, and the first argument
/// that is not UTF-8 need not be it: a path may hold any bytes.
fn not_utf8(cmd: &clap::Command, args: &[OsString]) -> String {
    let bad: Vec<usize> = (1..args.len())
        .filter(|&i| args[i].to_str().is_none())
        .collect();
    let lossy = |i: usize, mark: bool| -> OsString {
        let text = args[i].to_string_lossy();
        if mark {
            text.replace('\u{fffd}', MARK).into()
        } else {
            text.into_owned().into()
        }
    };
    let Some(at) = first_refused(cmd, args, &bad, |i| lossy(i, false)) else {
        return "expected UTF-8 text in every argument but paths".into();
    };
    // Read no further than the argument: a flag given again later (`--name a\xff --name b`)
    // would replace the value traced in what clap matched.
    let mut traced = args[..=at].to_vec();
    for &i in bad.iter().filter(|&&i| i <= at) {
        traced[i] = lossy(i, i == at);
    }
    let given = args[at].to_string_lossy();
    match holder(cmd, &traced) {
        Some(flag) => {
            let value = given.strip_prefix(&format!("{flag}=")).unwrap_or(&given);
            format!(
                "{flag}: expected UTF-8 text, found {}",
                weights::quote(value)
            )
        }
        None => format!(
            "argument {at}: expected UTF-8 text, found {}",
            weights::quote(&given)
        ),
    }
}

/// Which of the arguments at `bad` clap refuses first as not UTF-8. clap reads the
/// arguments in order and stops at the first it refuses, so with those from `bad[k]` on
/// read through `lossy`, it still refuses one exactly when that one lies before `bad[k]`:
/// a search by halves, a parse a step.
fn first_refused(
    cmd: &clap::Command,
    args: &[OsString],
    bad: &[usize],
    lossy: impl Fn(usize) -> OsString,
) -> Option<usize> {
    let refused = |k: usize| {
        let mut a = args.to_vec();
        for &i in &bad[k..] {
            a[i] = lossy(i);
        }
        cmd.clone()
            .try_get_matches_from(a)
            .is_err_and(|e| e.kind() == ErrorKind::InvalidUtf8)
    };
    let (mut low, mut high) = (1, bad.len());
    while low < high {
        let mid = low + (high - low) / 2;
        if refused(mid) {
            high = mid;
        } else {
            low = mid + 1;
        }
    }
    bad.get(low.checked_sub(1)?).copied()
}

/// A flag as a person types it, or a positional as clap's usage shows it.
fn named(arg: &clap::Arg) -> String {
    if let Some(long) = arg.get_long() {
        format!("--{long}")
    } else if let Some(short) = arg.get_short() {
        format!("-{short}")
    } else {
        format!("<{}>", value_name(arg).to_uppercase())
    }
}

/// The name of the value `arg` takes, as clap's usage shows it.
fn value_name(arg: &clap::Arg) -> &str {
    let names = arg.get_value_names().unwrap_or_default();
    names.first().map_or(arg.get_id().as_str(), |n| n.as_str())
}

/// The flag (or positional, `<NAME>`) whose value holds [`MARK`] in `args`: the one clap
/// names refusing the value, or else the one holding it in what clap matched.
fn holder(cmd: &clap::Command, args: &[OsString]) -> Option<String> {
    let first = |shown: &str| shown.split(' ').next().unwrap_or_default().to_string();
    if let Err(e) = cmd.clone().try_get_matches_from(args) {
        let text = |kind| match e.get(kind) {
            Some(ContextValue::String(s)) => Some(s.clone()),
            _ => None,
        };
        if let (Some(arg), Some(value)) = (
            text(ContextKind::InvalidArg),
            text(ContextKind::InvalidValue),
        ) && value.contains(MARK)
        {
            return Some(first(&arg));
        }
    }
    let matched = cmd
        .clone()
        .ignore_errors(true)
        .try_get_matches_from(args)
        .ok()?;
    let mut at = (cmd, &matched);
    loop {
        let (cmd, m) = at;
        let holds = |arg: &&clap::Arg| {
            m.try_get_raw(arg.get_id().as_str()).is_ok_and(|raw| {
                raw.into_iter()
                    .flatten()
                    .any(|v| v.to_string_lossy().contains(MARK))
            })
        };
        if let Some(arg) = cmd.get_arguments().find(holds) {
            return Some(named(arg));
        }
        let (name, sub) = m.subcommand()?;
        at = (cmd.find_subcommand(name)?, sub);
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
    fn text_that_is_not_utf8_is_refused_naming_its_flag_past_paths_that_are_not() {
        use clap::{Arg, Command};
        use std::os::unix::ffi::OsStrExt;
        let path = || Arg::new("path").value_parser(clap::value_parser!(std::path::PathBuf));
        let cmd = Command::new("tool").subcommand(
            Command::new("run")
                .arg(path().long("policy"))
                .arg(Arg::new("name").long("name"))
                .arg(Arg::new("tag").long("tag"))
                .arg(
                    Arg::new("count")
                        .long("count")
                        .value_parser(clap::value_parser!(u32)),
                )
                .arg(Arg::new("label").value_name("LABEL")),
        );
        let refusal = |argv: &[&[u8]]| {
            let args: Vec<OsString> = argv
                .iter()
                .map(|a| std::ffi::OsStr::from_bytes(a).to_owned())
                .collect();
            let e = cmd.clone().try_get_matches_from(&args).unwrap_err();
            assert_eq!(e.kind(), ErrorKind::InvalidUtf8, "{argv:?}");
            not_utf8(&cmd, &args)
        };
        let bad_path: &[u8] = b"p\xff.safetensors";
        assert_eq!(
            refusal(&[b"tool", b"run", b"--policy", bad_path, b"--name", b"a\xffb"]),
            "--name: expected UTF-8 text, found \"a\u{fffd}b\""
        );
        assert_eq!(
            refusal(&[b"tool", b"run", b"--name=\x1b\xfe", b"--policy", bad_path]),
            "--name: expected UTF-8 text, found \"\\u{1b}\u{fffd}\""
        );
        assert_eq!(
            refusal(&[b"tool", b"run", b"--count", b"1\xff", b"--name", b"\xff"]),
            "--count: expected UTF-8 text, found \"1\u{fffd}\""
        );
        assert_eq!(
            refusal(&[b"tool", b"run", b"--policy", bad_path, b"x\xff"]),
            "<LABEL>: expected UTF-8 text, found \"x\u{fffd}\""
        );
        // Two flags given bytes that are not UTF-8: the first is named, whichever it is.
        for (first, second) in [(&b"--name"[..], &b"--tag"[..]), (b"--tag", b"--name")] {
            let want = format!(
                "{}: expected UTF-8 text, found \"a\u{fffd}\"",
                String::from_utf8_lossy(first)
            );
            assert_eq!(
                refusal(&[b"tool", b"run", first, b"a\xff", second, b"b\xfe"]),
                want
            );
        }
        // A flag given again, after the bytes or with them too: clap keeps the last value,
        // which named only "argument 3".
        for again in [b"b".as_slice(), b"b\xfe"] {
            assert_eq!(
                refusal(&[b"tool", b"run", b"--name", b"a\xff", b"--name", again]),
                "--name: expected UTF-8 text, found \"a\u{fffd}\""
            );
        }
        assert_eq!(
            refusal(&[b"tool", b"run", b"--count", b"1\xff", b"--count=2"]),
            "--count: expected UTF-8 text, found \"1\u{fffd}\""
        );
        // A path alone is no refusal.
        let args = [b"tool".as_slice(), b"run", b"--policy", bad_path]
            .map(|a| std::ffi::OsStr::from_bytes(a).to_owned());
        assert!(cmd.clone().try_get_matches_from(args).is_ok());
    }

    /// A number that reads as zero is found at a range's end too, and named by the flag
    /// its value follows, not by a flag before a flag.
    #[test]
    fn a_zero_in_disguise_is_found_in_ranges_and_named_by_its_flag() {
        let check = |args: &[&str]| {
            let args: Vec<OsString> = args.iter().map(OsString::from).collect();
            check_numbers(&args).unwrap_err()
        };
        let e = check(&["tool", "--set", "domain=glitch=1e-400..0.3"]);
        assert!(
            e.starts_with("--set \"domain=glitch=1e-400..0.3\": 1e-400 reads"),
            "{e}"
        );
        let e = check(&["tool", "--json", "--zero-error=1e-400"]);
        assert!(
            e.starts_with("\"--zero-error=1e-400\": 1e-400 reads"),
            "{e}"
        );
    }

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
