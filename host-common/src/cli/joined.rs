//! Negative numbers, lists and ranges in every spelling as their flags' values.

use std::ffi::OsString;

/// `args` with each negative value ([`negative`]) written after a flag that takes a value
/// joined to it (`--hours -1e-5` as `--hours=-1e-5`, `--seeds -1..3` as `--seeds=-1..3`):
/// clap takes a negative number for a value only in the form `-1.5`
/// ([`super::negative_numbers`]), and any other (`-1e-5`, `-.5`, `-inf`, a list `-5,10`)
/// for short flags, naming neither the flag nor the value. Nothing after `--` is touched.
pub(super) fn numbers_joined(cmd: &clap::Command, args: Vec<OsString>) -> Vec<OsString> {
    fn valued(cmd: &clap::Command, into: &mut Vec<String>) {
        let longs = cmd
            .get_arguments()
            .filter(|a| a.get_action().takes_values());
        into.extend(longs.filter_map(|a| a.get_long()).map(|l| format!("--{l}")));
        cmd.get_subcommands().for_each(|c| valued(c, into));
    }
    let mut flags = Vec::new();
    valued(cmd, &mut flags);
    let mut out: Vec<OsString> = Vec::with_capacity(args.len());
    let mut rest = args.into_iter();
    while let Some(a) = rest.next() {
        let flag = a
            .to_str()
            .filter(|f| flags.iter().any(|v| v == f))
            .map(String::from);
        let Some(flag) = flag else {
            let end = a == "--";
            out.push(a);
            if end {
                out.extend(rest.by_ref());
            }
            continue;
        };
        match rest.next() {
            Some(v) if v.to_str().is_some_and(negative) => {
                out.push(format!("{flag}={}", v.to_string_lossy()).into());
            }
            next => out.extend(std::iter::once(flag.into()).chain(next)),
        }
    }
    out
}

/// Whether `arg` reads as a negative value rather than a flag: a number a float parser
/// takes (`-inf` too), or `-` before anything but a letter or another `-` (a list `-5,10`, a
/// range `-1..3`, a spelling the flag's own parser names: `-0x10`, `-1_0`, `-.`).
fn negative(arg: &str) -> bool {
    let Some(rest) = arg.strip_prefix('-') else {
        return false;
    };
    let first = rest.chars().next();
    arg.parse::<f64>().is_ok() || first.is_some_and(|c| c != '-' && !c.is_alphabetic())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every spelling of a negative number a float parser takes is a flag's value, separate
    /// as joined; other text starting with `-` stays a flag, and nothing after `--` moves.
    #[test]
    fn a_number_in_any_spelling_is_joined_to_its_flag() {
        use clap::{Arg, ArgAction, Command};
        let cmd = Command::new("tool").subcommand(
            Command::new("run")
                .arg(Arg::new("at").long("at"))
                .arg(Arg::new("quiet").long("quiet").action(ArgAction::SetTrue))
                .arg(Arg::new("rest").num_args(0..).last(true)),
        );
        let joined = |args: &[&str]| -> Vec<String> {
            let args = args.iter().map(OsString::from).collect();
            let out = numbers_joined(&cmd, args);
            out.into_iter().map(|a| a.into_string().unwrap()).collect()
        };
        for n in [
            "-1e-5", "-.5", "-inf", "-NaN", "-1E-400", "-1", "-5,10", "-1..3", "-0x10", "-1_0",
            "-\u{661}", "-.",
        ] {
            let want = ["tool", "run", &format!("--at={n}")];
            assert_eq!(joined(&["tool", "run", "--at", n]), want, "{n}");
        }
        for kept in [
            &["tool", "run", "--at", "-x"][..],
            &["tool", "run", "--at", "-\u{e9}"],
            &["tool", "run", "--at", "--quiet"],
            &["tool", "run", "--at", "-"],
            &["tool", "run", "--quiet", "-1e-5"],
            &["tool", "run", "--", "--at", "-1e-5"],
            &["tool", "run", "--at"],
        ] {
            assert_eq!(joined(kept), kept, "{kept:?}");
        }
    }
}
