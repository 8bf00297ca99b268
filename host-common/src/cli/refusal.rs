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
        None => match dash_led(e, cmd, args) {
            Some(head) => {
                let usage = text.find("Usage:").map_or("", |i| &text[i..]);
                format!("{head}\n\n{usage}")
            }
            None => text,
        },
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

/// The refusal and a tip for the argument clap refused as an unknown short flag (`-d`): the
/// first before any `--` that starts with it (`-dash.safetensors`, a file's name), named
/// whole and escaped, where clap quoted the fragment, which the user never wrote, and
/// offered `-- -d`. The tip is `--out=-dash.rs` for a flag's value, as `--` cannot give one.
fn dash_led(e: &clap::Error, cmd: &clap::Command, args: &[OsString]) -> Option<String> {
    let Some(ContextValue::String(part)) = e.get(ContextKind::InvalidArg) else {
        return None;
    };
    if e.kind() != clap::error::ErrorKind::UnknownArgument || part.starts_with("--") {
        return None;
    }
    let text = super::before_dashes(args);
    let at = (1..text.len()).find(|&i| text[i].starts_with(part.as_str()))?;
    if text[at] == part {
        return None;
    }
    let valued = |f: &&str| {
        f.starts_with("--")
            && arg_named(running(cmd, args), f).is_some_and(|a| a.get_action().takes_values())
    };
    Some(unexpected(text[at], Some(text[at - 1]).filter(valued)))
}

/// The refusal of `arg`, an argument starting with `-` that is no flag, escaped, with how
/// to give it: as `flag`'s value, if it follows one that takes a value, else as a name.
pub(super) fn unexpected(arg: &str, flag: Option<&str>) -> String {
    let whole = weights::excerpt(arg);
    let tip = match flag {
        Some(flag) => format!("to give it as {flag}'s value, write '{flag}={whole}'"),
        None => {
            format!("a name that starts with '-' goes after '--' ('-- {whole}') or as './{whole}'")
        }
    };
    format!("error: unexpected argument '{whole}' found\n\n  tip: {tip}")
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
        return DIGITS_ALONE.into();
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

/// The largest value of the whole-number type `arg` takes, if it takes one.
fn whole_type(arg: &clap::Arg) -> Option<u64> {
    use std::any::TypeId;
    let id = arg.get_value_parser().type_id();
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
    Some(top)
}

/// The refusal of the first whole number in `m` (matched by `cmd`) written with a `+`
/// (`--episodes=+3`): std's parse takes it, where every other spelling but digits is refused
/// as not [`DIGITS_ALONE`].
pub(super) fn plus_signed(cmd: &clap::Command, m: &clap::ArgMatches) -> Option<String> {
    for arg in cmd.get_arguments().filter(|a| whole_type(a).is_some()) {
        let Ok(Some(raw)) = m.try_get_raw(arg.get_id().as_str()) else {
            continue;
        };
        if let Some(v) = raw.filter_map(|v| v.to_str()).find(|v| v.starts_with('+')) {
            // As clap words its other refusals of a value.
            let value = weights::excerpt(v);
            let (flag, name) = (super::named(arg), super::value_name(arg));
            return Some(format!(
                "invalid value '{value}' for '{flag} <{name}>': {DIGITS_ALONE}"
            ));
        }
    }
    let (name, sub) = m.subcommand()?;
    plus_signed(cmd.find_subcommand(name)?, sub)
}

/// What a whole-number flag takes, said of any other spelling.
const DIGITS_ALONE: &str = "expected a whole number in decimal digits alone, such as 42";

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
    let top = whole_type(arg)?;
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
mod tests;
