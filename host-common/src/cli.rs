//! Command-line parsing with the project's refusal rules: clap's own message for a bad
//! flag, but with no line longer than a few hundred characters (clap quotes the offending
//! value whole, and a value can be 128 KB), and exit status 2.

use clap::error::ErrorKind;

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
        Ok(t) => t,
        Err(e) => {
            if matches!(
                e.kind(),
                ErrorKind::DisplayHelp
                    | ErrorKind::DisplayVersion
                    | ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand
            ) {
                e.exit()
            }
            for line in e.render().to_string().lines() {
                eprintln!("{}", cut(line));
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
