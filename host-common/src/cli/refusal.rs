//! clap's refusal of a command line, rendered with the user's text in it escaped and cut.

use std::ffi::OsString;

use clap::error::{ContextKind, ContextValue};

use super::cut;

/// clap's refusal `e` of a command line given to `cmd`, as printed: clap's own lines (the
/// reason, a tip, the usage, where to read more), but every piece of the user's text in them
/// (a value, an unknown flag or subcommand) escaped and cut as [`weights::excerpt`] does, a
/// value parser's reason as [`weights::located`] does, and each line cut at
/// [`LINE_MAX`](super::LINE_MAX). clap quotes them raw: a line break in a value forged a
/// line of its own (`--seeds $'a\nerror: fake'`), and its plain rendering dropped an escape,
/// a carriage return or a backspace without a trace. The message is built again from clap's
/// kind and context, each text escaped; a value parser's reason, which clap writes raw after
/// the value, is escaped and put back where clap puts it. Any control character left after
/// that (in a message clap holds whole, which quotes no input) is escaped too, line by line.
pub(super) fn refusal(e: &clap::Error, cmd: &clap::Command, args: &[OsString]) -> Vec<String> {
    let mut bare = clap::Error::new(e.kind()).with_cmd(cmd);
    let mut context = false;
    for (kind, value) in e.context() {
        bare.insert(kind, escaped_context(kind, value));
        context = true;
    }
    // Cut in its middle, if long, so that its end (what was expected) survives.
    let source = std::error::Error::source(e).map(|s| {
        let reason = whole_reason(e, running(cmd, args), s.to_string());
        weights::located("", None, &reason)
    });
    let text = match source {
        // A message clap holds whole (the program's own, or a mismatch of its definitions).
        _ if !context => e.render().to_string(),
        None => bare.render().to_string(),
        // clap's `invalid value '...' for '--flag <FLAG>': REASON`, its first line; any
        // other refusal with a reason and the user's text takes it the same way, since the
        // whole rendering would copy that text raw.
        Some(reason) => {
            let text = bare.render().to_string();
            let (head, rest) = text.split_once('\n').unwrap_or((&text, ""));
            format!("{head}: {reason}\n{rest}")
        }
    };
    let text = match empty_item(e, cmd, args) {
        Some(line) => {
            let rest = text.split_once('\n').map_or("", |(_, rest)| rest);
            format!("{line}\n{rest}")
        }
        None => text,
    };
    text.lines().map(|l| cut(&escape_controls(l))).collect()
}

/// clap's refusal `e` of an empty value, said again where one was given: an item of a list
/// was empty (`--controller lqr,`), or the value was (`--seed=`), where clap said "a value is
/// required ... but none was supplied". A flag given no value keeps clap's words.
fn empty_item(e: &clap::Error, cmd: &clap::Command, args: &[OsString]) -> Option<String> {
    let text = |kind| match e.get(kind) {
        Some(ContextValue::String(s)) => Some(s.as_str()),
        _ => None,
    };
    let (shown, value) = (
        text(ContextKind::InvalidArg)?,
        text(ContextKind::InvalidValue)?,
    );
    if e.kind() != clap::error::ErrorKind::InvalidValue || !value.is_empty() {
        return None;
    }
    let flag = shown.split(' ').next()?;
    let by = list_separator(running(cmd, args), flag);
    // A path or a number has no values to list: "one of its values" named none.
    let listed =
        arg_named(running(cmd, args), flag).is_some_and(|a| !a.get_possible_values().is_empty());
    let expected = if listed {
        "one of its values"
    } else {
        "a value"
    };
    let args: Vec<String> = args
        .iter()
        .map(|a| a.to_string_lossy().into_owned())
        .collect();
    let given = args
        .iter()
        .enumerate()
        .filter_map(|(i, a)| match a.strip_prefix(flag)? {
            "" => args.get(i + 1).map(String::as_str),
            v => v.strip_prefix('='),
        });
    let shown = weights::excerpt(shown);
    for v in given {
        if v.is_empty() {
            return Some(format!(
                "error: '{shown}' was given an empty value; expected {expected}"
            ));
        }
        if let Some(by) = by
            && v.split(by).any(str::is_empty)
        {
            return Some(format!(
                "error: '{shown}' takes a list separated by '{by}', and found an empty item in \
                 {} ('{by}' at its start or end, or two together); expected {expected} in \
                 each",
                weights::quote(v)
            ));
        }
    }
    None
}

/// The argument of `cmd` the command line names `flag`.
fn arg_named<'c>(cmd: &'c clap::Command, flag: &str) -> Option<&'c clap::Arg> {
    cmd.get_arguments().find(|a| super::named(a) == flag)
}

/// The separator of the items of `flag`'s list in `cmd`, if it takes one.
fn list_separator(cmd: &clap::Command, flag: &str) -> Option<char> {
    (cmd.get_arguments())
        .find(|a| super::named(a) == flag)
        .and_then(clap::Arg::get_value_delimiter)
}

/// The subcommand `args` run, as far as clap matched them (`cmd` itself if none).
fn running<'c>(cmd: &'c clap::Command, args: &[OsString]) -> &'c clap::Command {
    let Ok(matched) = cmd.clone().ignore_errors(true).try_get_matches_from(args) else {
        return cmd;
    };
    let (mut at, mut m) = (cmd, &matched);
    while let Some((name, sub)) = m.subcommand()
        && let Some(c) = at.find_subcommand(name)
    {
        (at, m) = (c, sub);
    }
    at
}

/// A whole-number parser's `reason` for refusing `e`'s value, or what it means where the value
/// is a negative whole number given to a flag that takes none (`--seed -1`), or one beyond
/// what the flag of `cmd` holds: std's "invalid digit found in string" and "number too large
/// to fit in target type" said neither.
fn whole_reason(e: &clap::Error, cmd: &clap::Command, reason: String) -> String {
    let Some(ContextValue::String(value)) = e.get(ContextKind::InvalidValue) else {
        return reason;
    };
    let digits = value.strip_prefix('-').unwrap_or_default();
    let whole = !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit());
    if reason == "invalid digit found in string" && whole && digits.bytes().any(|b| b != b'0') {
        return "expected a whole number of 0 or more, found a negative one".into();
    }
    // `-0`, `1e3`, `0x10`, `1_000`, `1.0`, ``: std said "invalid digit found in string".
    if [
        "invalid digit found in string",
        "cannot parse integer from empty string",
    ]
    .contains(&reason.as_str())
    {
        return "expected a whole number in decimal digits alone, such as 42".into();
    }
    if reason == "invalid float literal" {
        return "expected a number in decimal, such as 0.5, -2 or 1e-3".into();
    }
    if reason == "number too large to fit in target type"
        && let Some(max) = largest(e, cmd)
    {
        return format!("expected a whole number of at most {max}, found a larger one");
    }
    reason
}

/// The largest value the flag `e` refused takes, by asking its own parser (which may hold a
/// range narrower than its type: `--threads` takes 1 to 256 in a u16), if it takes a whole
/// number of a type whose parse said none.
fn largest(e: &clap::Error, cmd: &clap::Command) -> Option<u64> {
    let Some(ContextValue::String(shown)) = e.get(ContextKind::InvalidArg) else {
        return None;
    };
    let flag = shown.split(' ').next()?;
    let arg = arg_named(cmd, flag)?;
    let parser = arg.get_value_parser();
    let id = parser.type_id();
    use std::any::TypeId;
    let (_, top) = [
        (TypeId::of::<u8>(), u64::from(u8::MAX)),
        (TypeId::of::<u16>(), u64::from(u16::MAX)),
        (TypeId::of::<u32>(), u64::from(u32::MAX)),
        (TypeId::of::<u64>(), u64::MAX),
        (TypeId::of::<usize>(), usize::MAX as u64),
        (TypeId::of::<i32>(), i32::MAX as u64),
        (TypeId::of::<i64>(), i64::MAX as u64),
    ]
    .into_iter()
    .find(|(t, _)| id == *t)?;
    // The parser alone, on a flag of its own.
    let probe = clap::Command::new("probe").arg(
        clap::Arg::new("value")
            .long("value")
            .value_parser(parser.clone()),
    );
    let takes = |n: u64| {
        let args = ["probe".to_string(), format!("--value={n}")];
        probe.clone().try_get_matches_from(args).is_ok()
    };
    // A value it takes, from the top down by powers of two; then the last one below the
    // first it refuses above, halving (a parser's values are a range).
    let below = |k: u32| 1u64.checked_shl(k).map_or(top, |p| p.min(top));
    let k = (0..=64).rev().find(|&k| takes(below(k)))?;
    let (mut lo, mut hi) = (below(k), below(k + 1));
    if lo == hi || takes(hi) {
        return Some(hi);
    }
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if takes(mid) { lo = mid } else { hi = mid }
    }
    Some(lo)
}

/// A piece of clap's context with the user's text in it escaped and cut: every text but the
/// usage, which clap makes from the command alone and may lay out on several lines. A tip
/// (`to pass '-x' as a value, use '-- -x'`) quotes the user's text inside clap's styling,
/// which is dropped, as it is when printed.
fn escaped_context(kind: ContextKind, value: &ContextValue) -> ContextValue {
    match value {
        _ if kind == ContextKind::Usage => value.clone(),
        ContextValue::String(s) => ContextValue::String(weights::excerpt(s)),
        ContextValue::Strings(v) => {
            ContextValue::Strings(v.iter().map(|s| weights::excerpt(s)).collect())
        }
        ContextValue::StyledStr(s) => {
            ContextValue::StyledStr(weights::excerpt(&s.to_string()).into())
        }
        ContextValue::StyledStrs(v) => ContextValue::StyledStrs(
            v.iter()
                .map(|s| weights::excerpt(&s.to_string()).into())
                .collect(),
        ),
        _ => value.clone(),
    }
}

/// `line` with every character that is not printable escaped as [`weights::quote`] escapes
/// it (`\u{1b}`, `\n`), quotes and backslashes left as they are, and nothing cut.
fn escape_controls(line: &str) -> String {
    let mut out = String::with_capacity(line.len());
    for c in line.chars() {
        if matches!(c, '"' | '\\' | '\'') {
            out.push(c);
        } else {
            out.extend(c.escape_debug());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::super::LINE_MAX;
    use super::*;

    #[test]
    fn refusals_show_the_users_text_escaped_on_clap_s_lines() {
        use clap::{Arg, Command};
        // A value parser that quotes the value raw, as std's and clap's own need not.
        let raw = |s: &str| -> Result<String, String> { Err(format!("no good: {s}")) };
        let cmd = Command::new("tool").subcommand(
            Command::new("run")
                .arg(Arg::new("mode").long("mode").value_parser(["fast", "slow"]))
                .arg(
                    Arg::new("count")
                        .long("count")
                        .value_parser(clap::value_parser!(u32)),
                )
                .arg(Arg::new("raw").long("raw").value_parser(raw))
                .arg(Arg::new("label")),
        );
        let refusal = |argv: &[&str]| {
            let e = cmd.clone().try_get_matches_from(argv).unwrap_err();
            let os: Vec<OsString> = argv.iter().map(OsString::from).collect();
            let lines = refusal(&e, &cmd, &os);
            let seen = format!("{argv:?}: {lines:#?}");
            assert!(
                lines.iter().all(|l| !l.chars().any(char::is_control)),
                "{seen}"
            );
            let errors: Vec<&String> = lines.iter().filter(|l| l.contains("error")).collect();
            assert!(
                errors.len() == 1 && errors[0].starts_with("error: "),
                "{seen}"
            );
            (errors[0].clone(), lines.join("\n"))
        };
        let forged = "a\nerror: fake\u{1b}[2J";
        let shown = "a\\nerror: fake\\u{1b}[2J";
        let (line, _) = refusal(&["tool", "run", "--count", forged]);
        assert_eq!(
            line,
            format!(
                "error: invalid value '{shown}' for '--count <count>': expected a whole number \
                 in decimal digits alone, such as 42"
            )
        );
        let (line, _) = refusal(&["tool", "run", "--raw", forged]);
        assert_eq!(
            line,
            format!("error: invalid value '{shown}' for '--raw <raw>': no good: {shown}")
        );
        let (line, all) = refusal(&["tool", "run", "--mode", "fas\nt"]);
        assert_eq!(line, "error: invalid value 'fas\\nt' for '--mode <mode>'");
        assert!(all.contains("[possible values: fast, slow]"), "{all}");
        let (line, all) = refusal(&["tool", "run", "--mod\ne", "fast"]);
        assert_eq!(line, "error: unexpected argument '--mod\\ne' found");
        assert!(all.contains("Usage: tool run"), "{all}");
        // clap's tip quotes the flag twice.
        let (_, all) = refusal(&["tool", "run", "x", "-\u{1b}[2J\ny"]);
        assert!(all.contains("as a value, use '-- -"), "{all}");
        let (line, all) = refusal(&["tool", "ru\nn"]);
        assert_eq!(line, "error: unrecognized subcommand 'ru\\nn'");
        assert!(
            all.contains("tip: a similar subcommand exists: 'run'"),
            "{all}"
        );
        let (line, _) = refusal(&["tool", "run", "--count"]);
        assert_eq!(
            line,
            "error: a value is required for '--count <count>' but none was supplied"
        );
        // A long value is cut, and the reason after it survives.
        let long = format!("{}\nend", "x".repeat(100_000));
        let (line, _) = refusal(&["tool", "run", "--raw", &long]);
        assert!(line.chars().count() <= LINE_MAX + 3, "{line}");
        assert!(line.starts_with("error: invalid value 'xxx"), "{line}");
        assert!(line.ends_with("xxx\\nend"), "{line}");
    }

    /// Every valued flag of every subcommand takes a negative number as its value, which its
    /// parser judges; anything else starting with `-` is still a flag.
    #[test]
    fn a_negative_number_is_a_flags_value_in_every_subcommand() {
        let cmd = numbers_tool();
        let m = cmd
            .clone()
            .try_get_matches_from(["tool", "run", "--at", "-0.5"]);
        let at = m
            .unwrap()
            .subcommand_matches("run")
            .unwrap()
            .get_one::<f64>("at")
            .copied();
        assert_eq!(at, Some(-0.5));
        let e = (cmd.clone())
            .try_get_matches_from(["tool", "run", "--seed", "-1"])
            .unwrap_err();
        assert_eq!(
            refusal(
                &e,
                &cmd,
                &["tool", "run", "--seed", "-1"].map(OsString::from)
            )[0],
            "error: invalid value '-1' for '--seed <seed>': expected a whole number of 0 or \
             more, found a negative one"
        );
        let e = (cmd.clone())
            .try_get_matches_from(["tool", "run", "--seed", "-x"])
            .unwrap_err();
        assert_eq!(e.kind(), clap::error::ErrorKind::UnknownArgument);
    }

    /// A tool with a whole-number flag, a float flag and a ranged one, every subcommand's
    /// values allowed to be negative numbers, as the tools' are.
    fn numbers_tool() -> clap::Command {
        use clap::{Arg, Command};
        let run = Command::new("run")
            .arg(
                Arg::new("seed")
                    .long("seed")
                    .value_parser(clap::value_parser!(u64)),
            )
            .arg(
                Arg::new("at")
                    .long("at")
                    .value_parser(clap::value_parser!(f64)),
            )
            .arg(
                Arg::new("threads")
                    .long("threads")
                    .value_parser(clap::value_parser!(u16).range(1..=256)),
            );
        super::super::negative_numbers(Command::new("tool").subcommand(run))
    }

    /// A number past its type's range, or in a spelling std's parser named no expectation
    /// for, is refused naming what the flag takes.
    #[test]
    fn numbers_out_of_range_or_form_name_what_the_flag_takes() {
        let cmd = numbers_tool();
        // Past the type's range: std's reason said no range.
        let big = ["tool", "run", "--seed", "18446744073709551616"];
        let e = (cmd.clone()).try_get_matches_from(big).unwrap_err();
        assert_eq!(
            refusal(&e, &cmd, &big.map(OsString::from))[0],
            "error: invalid value '18446744073709551616' for '--seed <seed>': expected a whole \
             number of at most 18446744073709551615, found a larger one"
        );
        // Spellings std's parser named no expectation for.
        for (value, want) in [
            (
                "-0",
                "expected a whole number in decimal digits alone, such as 42",
            ),
            (
                "1e3",
                "expected a whole number in decimal digits alone, such as 42",
            ),
            (
                "0x10",
                "expected a whole number in decimal digits alone, such as 42",
            ),
            (
                "1_000",
                "expected a whole number in decimal digits alone, such as 42",
            ),
        ] {
            let args = ["tool", "run", "--seed", value];
            let e = (cmd.clone()).try_get_matches_from(args).unwrap_err();
            let line = refusal(&e, &cmd, &args.map(OsString::from))[0].clone();
            assert!(line.ends_with(want), "{value}: {line}");
        }
        let args = ["tool", "run", "--at", "0x10"];
        let e = (cmd.clone()).try_get_matches_from(args).unwrap_err();
        let line = refusal(&e, &cmd, &args.map(OsString::from))[0].clone();
        assert!(
            line.ends_with("expected a number in decimal, such as 0.5, -2 or 1e-3"),
            "{line}"
        );
        // The flag's own range, not its type's.
        let big = ["tool", "run", "--threads", "99999999999999999999"];
        let e = (cmd.clone()).try_get_matches_from(big).unwrap_err();
        assert_eq!(
            refusal(&e, &cmd, &big.map(OsString::from))[0],
            "error: invalid value '99999999999999999999' for '--threads <threads>': expected a \
             whole number of at most 256, found a larger one"
        );
    }

    /// An empty item of a list, or an empty value, is said as such: clap said none was
    /// supplied. A flag given no value keeps clap's words.
    #[test]
    fn an_empty_item_or_value_is_named_as_found() {
        use clap::{Arg, Command};
        let cmd = Command::new("tool").subcommand(
            Command::new("run")
                .arg(
                    Arg::new("mode")
                        .long("mode")
                        .value_parser(["fast", "slow"])
                        .value_delimiter(','),
                )
                .arg(Arg::new("one").long("one").value_parser(["a", "b"]))
                .arg(
                    Arg::new("out")
                        .long("out")
                        .value_parser(clap::value_parser!(std::path::PathBuf)),
                ),
        );
        let first = |argv: &[&str]| {
            let e = cmd.clone().try_get_matches_from(argv).unwrap_err();
            refusal(
                &e,
                &cmd,
                &argv.iter().map(OsString::from).collect::<Vec<_>>(),
            )[0]
            .clone()
        };
        let item =
            "error: '--mode <mode>' takes a list separated by ',', and found an empty item in";
        for v in ["fast,", ",slow", "fast,,slow", ","] {
            let line = first(&["tool", "run", "--mode", v]);
            assert!(line.starts_with(&format!("{item} \"{v}\"")), "{v}: {line}");
        }
        assert_eq!(
            first(&["tool", "run", "--one="]),
            "error: '--one <one>' was given an empty value; expected one of its values"
        );
        // A path has no values to list.
        assert_eq!(
            first(&["tool", "run", "--out="]),
            "error: '--out <out>' was given an empty value; expected a value"
        );
        assert_eq!(
            first(&["tool", "run", "--one"]),
            "error: a value is required for '--one <one>' but none was supplied"
        );
    }
}
