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
    // The tip quotes the argument twice.
    let (_, all) = refusal(&["tool", "run", "x", "-\u{1b}[2J\ny"]);
    assert!(
        all.contains("goes after '--' ('-- -\\u{1b}[2J\\ny')"),
        "{all}"
    );
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
    let item = "error: '--mode <mode>' takes a list separated by ',', and found an empty item in";
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

/// An argument starting with `-` that is no flag (a file's name) is named whole, not by the
/// fragment clap read as a short flag.
#[test]
fn a_dash_led_argument_is_named_whole() {
    let cmd = numbers_tool();
    let args = ["tool", "run", "-dash\u{1b}.bin"].map(OsString::from);
    let e = (cmd.clone()).try_get_matches_from(&args).unwrap_err();
    let lines = refusal(&e, &cmd, &args);
    assert_eq!(
        lines[0],
        "error: unexpected argument '-dash\\u{1b}.bin' found"
    );
    assert!(!lines.iter().any(|l| l.contains("'-d'")), "{lines:?}");
    // The first of several, up to `--`; a flag's value offered as `--flag=...`; the fragment
    // itself, given as such, kept.
    for (args, first, tip) in [
        (
            &["tool", "run", "-dx", "-dy"][..],
            "'-dx'",
            "after '--' ('-- -dx')",
        ),
        (
            &["tool", "run", "--seed", "-dx"],
            "'-dx'",
            "write '--seed=-dx'",
        ),
        (&["tool", "run", "-d", "--", "-dx"], "'-d'", ""),
    ] {
        let args = args.iter().map(OsString::from).collect::<Vec<_>>();
        let e = (cmd.clone()).try_get_matches_from(&args).unwrap_err();
        let lines = refusal(&e, &cmd, &args);
        assert_eq!(
            lines[0],
            format!("error: unexpected argument {first} found")
        );
        assert!(lines.iter().any(|l| l.contains(tip)), "{lines:?}");
    }
}

/// A whole number with a `+` is refused as not digits alone, in a subcommand too; a float
/// flag keeps it (`+0.5` is decimal notation).
#[test]
fn a_plus_signed_whole_number_is_refused() {
    let cmd = numbers_tool();
    let m = (cmd.clone())
        .try_get_matches_from(["tool", "run", "--seed=+3"])
        .unwrap();
    assert_eq!(
        plus_signed(&cmd, &m).unwrap(),
        format!("invalid value '+3' for '--seed <seed>': {DIGITS_ALONE}")
    );
    for args in [["tool", "run", "--seed=3"], ["tool", "run", "--at=+0.5"]] {
        let m = (cmd.clone()).try_get_matches_from(args).unwrap();
        assert_eq!(plus_signed(&cmd, &m), None, "{args:?}");
    }
}
