//! Outputs kept apart from each other, and reals shown as written in refusals.

use std::ffi::OsString;
use std::path::Path;

use super::hostile::{Case, Scratch};
use super::{os, repo};

/// Two outputs at one place: the rig file written where the plots went (or they below it),
/// after the plots were drawn; and many logs with plots, kept apart in linear time.
pub fn apart(s: &Scratch, log: &Path, rig: &Path) -> Vec<Case> {
    let mut cases = Vec::new();
    // Two outputs at one place: the rig file written where the plots went (or they below
    // it), after the plots were drawn.
    let (plots, id) = (s.join("plots"), s.join("id-out.toml"));
    std::os::unix::fs::symlink(&s.0, s.join("here")).unwrap();
    for (label, out, dir) in [
        ("the plots", plots.clone(), plots.clone()),
        ("a plot", plots.join("identify-1-cart.png"), plots.clone()),
        ("above the plots", id.clone(), id.join("plots")),
        (
            "the plots through a link",
            s.join("here/plots"),
            plots.clone(),
        ),
    ] {
        let args = os(&[
            &"identify",
            &log,
            &"--rig",
            &rig,
            &"--out",
            &out,
            &"--plots",
            &dir,
        ]);
        cases.push(Case::new(
            format!("identify --out {label}"),
            &args,
            &["expected a place of its own"],
        ));
    }
    // 3,000 logs of a row each, with plots: 12,000 plots kept apart pairwise took seconds
    // (10,000 logs, minutes). Each row's duty is its own (counts are compared from each
    // log's first, so another cart count alone is the same experiment): an experiment given
    // twice is refused before the plots' places are.
    let one = std::fs::read_to_string(log).unwrap();
    let row = one.find("\n0,").unwrap() + 1;
    let (head, rest) = one.split_at(row);
    let fields: Vec<&str> = rest[..rest.find('\n').unwrap()].split(',').collect();
    let many = s.join("many.log");
    let logs: String = (0..3_000)
        .map(|k| {
            format!(
                "{head}0,{},{},{}\n",
                f64::from(k) / 4000.0,
                fields[2],
                fields[3]
            )
        })
        .collect();
    std::fs::write(&many, logs).unwrap();
    let args = os(&[
        &"identify",
        &many,
        &"--rig",
        &rig,
        &"--out",
        &id,
        &"--plots",
        &plots,
    ]);
    cases.push(Case::new(
        "identify 10000 logs".into(),
        &args,
        &["too short"],
    ));
    cases
}

/// A tiny real shown as written, not as 300 decimal places.
pub fn tiny_reals(s: &Scratch) -> Vec<Case> {
    let mut cases = Vec::new();
    let (desk, out) = (repo("rigs/desk.toml"), s.join("tiny.log"));
    let simulate = os(&[
        &"simulate-logs",
        &"--world",
        &desk,
        &"--rig",
        &desk,
        &"--out",
        &out,
    ]);
    let reals: [(Vec<OsString>, &str); 9] = [
        (os(&[&"envelope"]), "--quantile"),
        (os(&[&"envelope"]), "--margin"),
        (os(&[&"eval", &"--episodes", &"1"]), "--min-success"),
        (os(&[&"soak"]), "--hours"),
        (os(&[&"startup"]), "--within"),
        (os(&[&"startup"]), "--hold"),
        (simulate.clone(), "--cart-s"),
        (simulate.clone(), "--swing-s"),
        (simulate, "--jitter"),
    ];
    // A tiny negative number, and a subnormal: a slip either way, which the refusal shows as
    // typed (shortest), not with 324 decimal places.
    for (cmd, flag) in reals {
        for tiny in ["-1e-300", "5e-324"] {
            let args = [cmd.clone(), os(&[&format!("{flag}={tiny}")])].concat();
            cases.push(Case::new(format!("{flag} {tiny}"), &args, &[tiny]));
        }
    }
    cases
}
