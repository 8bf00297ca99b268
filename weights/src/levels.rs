//! Duty levels given for a policy file: how a command's `--levels` and the Python package's
//! `levels=` reach the importer, and which levels an imported network drives (the ones its
//! file records, else the ones given, else the paper's two for a two-output network).
//!
//! A checkpoint saved by PyTorch, Stable-Baselines3 or an ONNX exporter records no levels:
//! its outputs are only numbers. A two-output one is taken to be the paper's (full push left
//! and right); one of more outputs needs its levels given, and is refused without them
//! rather than guessed at.

use std::collections::BTreeMap;

use firmware::ConfigError;
use firmware::controller::{Duty, check_levels};

use crate::{BANG_BANG, Error, Result, few, quote};

/// The safetensors `__metadata__` key of a policy's duty levels (a JSON list of fractions
/// of the full push), written where they are not the paper's two ([`crate::BANG_BANG`]).
pub const LEVELS_KEY: &str = "levels";

/// Duty levels given for a policy file, and the argument that gave them (`--levels`,
/// `levels`), which a refusal names.
#[derive(Clone, Debug, PartialEq)]
pub struct GivenLevels {
    levels: Vec<f32>,
    by: &'static str,
}

impl GivenLevels {
    /// `levels` (fractions of the full push, one per output) given by the argument `by`;
    /// refused as the firmware refuses levels ([`check_levels`]).
    pub fn new(levels: &[f64], by: &'static str) -> Result<GivenLevels> {
        let levels =
            narrow(levels).map_err(|e| Error::Input(format!("{by} {}: {e}", show(levels))))?;
        Ok(GivenLevels { levels, by })
    }

    /// The levels `spec` lists, given by the argument `by` ([`parse_levels`]).
    pub fn parse(spec: &str, by: &'static str) -> Result<GivenLevels> {
        Ok(GivenLevels {
            levels: parse_levels(spec, by)?,
            by,
        })
    }

    /// The levels, in output order.
    pub fn levels(&self) -> &[f32] {
        &self.levels
    }

    /// Refused unless these levels drive the duties of `policy`'s (to the thousandth, as
    /// the bridge drives them): levels given beside a policy that has its own.
    pub fn agree(&self, policy: &[f32]) -> Result<()> {
        if same_duties(policy, &self.levels) {
            return Ok(());
        }
        Err(Error::Input(format!(
            "{} {}: the policy drives the duty levels {}; expected those or no {}",
            self.by,
            show(&self.levels),
            show(policy),
            self.by
        )))
    }
}

/// The duty levels `spec` lists, comma-separated fractions of the full push in increasing
/// order (`-1,-0.2,0,0.2,1`). Refused, naming the argument `by` and quoting `spec`: an empty
/// list, a word that is no number, and levels the firmware refuses ([`check_levels`]: fewer
/// than two, not finite, beyond `[-1, 1]`, not strictly increasing in thousandths).
pub fn parse_levels(spec: &str, by: &str) -> Result<Vec<f32>> {
    let refuse = |why: String| Error::Input(format!("{by} {}: {why}", quote(spec)));
    if spec.trim().is_empty() {
        return Err(refuse(
            "expected comma-separated duty levels, fractions of the full push in increasing \
             order (-1,-0.2,0,0.2,1); found none"
                .into(),
        ));
    }
    let levels = spec
        .split(',')
        .map(|v| {
            v.trim().parse::<f64>().map_err(|_| {
                refuse(format!(
                    "expected comma-separated numbers, found {}",
                    quote(v)
                ))
            })
        })
        .collect::<Result<Vec<f64>>>()?;
    narrow(&levels).map_err(refuse)
}

/// `levels` as the board holds them, or why they are not ones the firmware takes
/// ([`check_levels`]) or not each zero or normal ([`crate::plain`]). They are checked before
/// narrowing: a subnormal is a slip the board rounds to off, and one below f32's least
/// (`5e-324`) would become a zero that passes; a level just beyond the full push
/// (`1.0000000001`) would round to it, and one beyond f32's range to an infinity.
fn narrow(levels: &[f64]) -> std::result::Result<Vec<f32>, String> {
    if let Some(l) = levels.iter().find(|l| l.is_finite() && !crate::plain(**l)) {
        return Err(format!(
            "levels: expected each zero or a normal number, found {l:e}"
        ));
    }
    if let Some(l) = levels.iter().find(|l| l.is_finite() && l.abs() > 1.0) {
        return Err(format!(
            "{}, found {l:?}",
            ConfigError::OutOfRange("levels")
        ));
    }
    let narrowed: Vec<f32> = levels.iter().map(|&l| l as f32).collect();
    if let Some(why) = collision(levels, &narrowed) {
        return Err(why);
    }
    check_levels(&narrowed).map_err(|e| e.to_string())?;
    Ok(narrowed)
}

/// The first two neighbouring levels that are not strictly increasing once rounded to the
/// thousandths of the full push the board drives, named with what they round to: `-1,
/// -0.9995` increase as written and were refused as "expected strictly increasing".
fn collision(levels: &[f64], narrowed: &[f32]) -> Option<String> {
    let duty = |l: f32| Duty::from_fraction(l).ok().map(Duty::thousandths);
    let k = (1..narrowed.len()).find(
        |&k| matches!((duty(narrowed[k - 1]), duty(narrowed[k])), (Some(a), Some(b)) if b <= a),
    )?;
    let (a, b) = (duty(narrowed[k - 1])?, duty(narrowed[k])?);
    let one = |x: f64| show(&[x]).trim_matches(['[', ']']).to_string();
    let round = |t: i16| one(f64::from(t) / 1000.0);
    Some(format!(
        "levels: expected strictly increasing once rounded to thousandths of the full push, as \
         the board drives them; found {} and {} (items {} and {k}), which round to {} and {}",
        one(levels[k - 1]),
        one(levels[k]),
        k - 1,
        round(a),
        round(b),
    ))
}

/// `levels` for a message: `[-1, -0.2, 0, 0.2, 1]`, each shortest (`5e-324`, not its 324
/// digits), a long list cut.
fn show<T: std::fmt::Debug>(levels: &[T]) -> String {
    let one = |l: &T| {
        let s = format!("{l:?}");
        s.strip_suffix(".0")
            .map_or_else(|| s.clone(), str::to_string)
    };
    format!("[{}]", few(levels.iter().map(one), 12))
}

/// The duty levels of a network of `outputs` outputs read from a file with `metadata`: the
/// levels the file records ([`LEVELS_KEY`]), which `given` may repeat (to the thousandth,
/// as the bridge drives them) but not contradict; else the levels `given`, one per output;
/// else the paper's two for a two-output network. A network of more outputs with neither is
/// refused.
pub(crate) fn of_file(
    metadata: &BTreeMap<String, String>,
    outputs: usize,
    given: Option<&GivenLevels>,
) -> Result<Vec<f32>> {
    match (recorded(metadata, outputs)?, given) {
        (Some(file), None) => Ok(file),
        (Some(file), Some(g)) if same_duties(&file, &g.levels) => Ok(file),
        (Some(file), Some(g)) => Err(Error::Input(format!(
            "{} {}: the file records the duty levels {}; expected those or no {}",
            g.by,
            show(&g.levels),
            show(&file),
            g.by
        ))),
        (None, Some(g)) if g.levels.len() == outputs => Ok(g.levels.clone()),
        (None, Some(g)) => Err(Error::Input(format!(
            "{} {}: expected one level per output of the network, {outputs}; found {}",
            g.by,
            show(&g.levels),
            g.levels.len()
        ))),
        (None, None) if outputs == 2 => Ok(BANG_BANG.to_vec()),
        (None, None) => Err(Error::Input(format!(
            "the network has {outputs} outputs and its file records no duty levels: expected \
             the {outputs} levels its outputs drive, given with --levels (levels= in Python) \
             or recorded as `{LEVELS_KEY}` in its metadata"
        ))),
    }
}

/// The levels `metadata` records for a network of `outputs` outputs, if any.
fn recorded(metadata: &BTreeMap<String, String>, outputs: usize) -> Result<Option<Vec<f32>>> {
    let Some(text) = metadata.get(LEVELS_KEY) else {
        return Ok(None);
    };
    if let Some(why) = crate::hidden_zero(text) {
        return Err(Error::Input(format!(
            "the file's metadata `{LEVELS_KEY}`: {why}"
        )));
    }
    let levels: Vec<f64> = serde_json::from_str(text).map_err(|_| {
        Error::Input(format!(
            "the file's metadata `{LEVELS_KEY}`: expected a JSON list of numbers, such as \
             [-1, 1], found {}",
            quote(text)
        ))
    })?;
    if levels.len() != outputs {
        return Err(Error::Input(format!(
            "the file records {} duty levels for a network of {outputs} outputs",
            levels.len()
        )));
    }
    narrow(&levels)
        .map(Some)
        .map_err(|e| Error::Input(format!("the file's duty levels {}: {e}", show(&levels))))
}

/// Whether two lists of levels drive the same duties.
fn same_duties(a: &[f32], b: &[f32]) -> bool {
    let duties = |l: &[f32]| -> Vec<Option<Duty>> {
        l.iter().map(|&f| Duty::from_fraction(f).ok()).collect()
    };
    duties(a) == duties(b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn given_levels_agree_with_a_policys_to_the_thousandth() {
        let given = GivenLevels::new(&[-1.0, 0.2, 1.0], "levels").unwrap();
        assert!(given.agree(&[-1.0, 0.2004, 1.0]).is_ok());
        let e = given.agree(&[-1.0, 1.0]).unwrap_err().to_string();
        assert!(
            e.contains("levels [-1, 0.2, 1]: the policy drives the duty levels [-1, 1]"),
            "{e}"
        );
    }

    fn refused(spec: &str) -> String {
        let e = parse_levels(spec, "--levels").unwrap_err();
        assert!(e.is_input(), "{e}");
        e.to_string()
    }

    #[test]
    fn a_spec_is_parsed_or_refused_naming_the_flag_and_quoting_it() {
        let five = parse_levels(" -1, -0.2,0 ,0.2,1", "--levels").unwrap();
        assert_eq!(five, [-1.0, -0.2, 0.0, 0.2, 1.0]);
        for (spec, says) in [
            ("", "found none"),
            ("  ", "found none"),
            ("-1,,1", "expected comma-separated numbers, found \"\""),
            ("-1,half,1", "found \"half\""),
            ("0x10,1", "found \"0x10\""),
            ("1,0", "expected strictly increasing"),
            (
                "-1,1e-40,1",
                "expected each zero or a normal number, found 1e-40",
            ),
            // Below f32's least subnormal: read as f32 first, these were a zero that passed.
            (
                "-1,5e-324",
                "expected each zero or a normal number, found 5e-324",
            ),
            ("-5e-324,1", "found -5e-324"),
            ("-1,1e-46,1", "found 1e-46"),
            ("-1,1e-50,1", "found 1e-50"),
            ("0.2,0.2004", "expected strictly increasing"),
            (
                "-1,-0.9995",
                "levels: expected strictly increasing once rounded to thousandths of the full \
                 push, as the board drives them; found -1 and -0.9995 (items 0 and 1), which \
                 round to -1 and -1",
            ),
            ("-1,0,1.5", "expected within [-1, 1], found 1.5"),
            // Beyond the range in f64, the full push or an infinity in f32: read as f32
            // first, the first two passed and the last was called infinite.
            (
                "-1,1.0000000001",
                "expected within [-1, 1], found 1.0000000001",
            ),
            (
                "-1.00000001,1",
                "expected within [-1, 1], found -1.00000001",
            ),
            ("-1,1e300", "expected within [-1, 1], found 1e300"),
            ("-1,NaN", "expected a finite number"),
            ("-1,1e999", "expected a finite number"),
            ("1", "expected at least two"),
        ] {
            let m = refused(spec);
            assert!(m.starts_with("--levels \""), "{spec:?}: {m}");
            assert!(m.contains(says), "{spec:?}: {m}");
        }
        // Hostile text is quoted short and on one line.
        let long = format!("1,{}\u{1b}", "9".repeat(10_000));
        let m = refused(&long);
        assert!(m.len() < 600 && !m.chars().any(char::is_control), "{m}");
    }

    #[test]
    fn given_levels_are_checked_as_the_firmware_checks_them() {
        let ok = GivenLevels::new(&[-1.0, 0.0, 1.0], "levels").unwrap();
        assert_eq!(ok.levels(), [-1.0, 0.0, 1.0]);
        let e = GivenLevels::new(&[0.5, -0.5], "levels").unwrap_err();
        assert_eq!(
            e.to_string(),
            "levels [0.5, -0.5]: levels: expected strictly increasing once rounded to \
             thousandths of the full push, as the board drives them; found 0.5 and -0.5 (items 0 \
             and 1), which round to 0.5 and -0.5"
        );
        let e = GivenLevels::new(&[-1.0, 5e-324], "levels").unwrap_err();
        assert_eq!(
            e.to_string(),
            "levels [-1, 5e-324]: levels: expected each zero or a normal number, found 5e-324"
        );
        let e = GivenLevels::new(&[-1.0, 1.0000000001], "levels").unwrap_err();
        assert_eq!(
            e.to_string(),
            "levels [-1, 1.0000000001]: levels: expected within [-1, 1], found 1.0000000001"
        );
        let e = GivenLevels::new(&[], "levels").unwrap_err().to_string();
        assert!(e.contains("expected at least two"), "{e}");
        let many: Vec<f64> = (0..1000).map(|i| f64::from(i) / 1000.0).collect();
        assert!(GivenLevels::new(&many, "levels").is_ok());
        let mut bad = many;
        bad.push(2.0);
        let e = GivenLevels::new(&bad, "levels").unwrap_err().to_string();
        assert!(e.contains("and 989 more") && e.len() < 300, "{e}");
    }

    fn meta(levels: Option<&str>) -> BTreeMap<String, String> {
        levels
            .map(|l| (LEVELS_KEY.to_string(), l.to_string()))
            .into_iter()
            .collect()
    }

    fn given(spec: &str) -> GivenLevels {
        GivenLevels::parse(spec, "--levels").unwrap()
    }

    #[test]
    fn a_files_levels_come_from_it_or_the_caller_never_both_differing() {
        let five = [-1.0, -0.2, 0.0, 0.2, 1.0];
        let rec = meta(Some("[-1.0,-0.2,0.0,0.2,1.0]"));
        // Recorded: taken, and given levels may repeat them to the thousandth.
        assert_eq!(of_file(&rec, 5, None).unwrap(), five);
        let g = given("-1,-0.2,0.0001,0.2,1");
        assert_eq!(of_file(&rec, 5, Some(&g)).unwrap(), five);
        let e = of_file(&rec, 5, Some(&given("-1,-0.5,0,0.5,1"))).unwrap_err();
        assert_eq!(
            e.to_string(),
            "--levels [-1, -0.5, 0, 0.5, 1]: the file records the duty levels \
             [-1, -0.2, 0, 0.2, 1]; expected those or no --levels"
        );
        let e = of_file(&rec, 5, Some(&given("-1,1")))
            .unwrap_err()
            .to_string();
        assert!(e.contains("records the duty levels [-1, -0.2"), "{e}");
        // None recorded: the given ones, one per output.
        let none = meta(None);
        assert_eq!(
            of_file(&none, 5, Some(&given("-1,-0.2,0,0.2,1"))).unwrap(),
            five
        );
        assert_eq!(
            of_file(&none, 2, Some(&given("-0.5,0.5"))).unwrap(),
            [-0.5, 0.5]
        );
        let e = of_file(&none, 5, Some(&given("-1,1"))).unwrap_err();
        assert_eq!(
            e.to_string(),
            "--levels [-1, 1]: expected one level per output of the network, 5; found 2"
        );
        let e = of_file(&none, 2, Some(&given("-1,0,1")))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("expected one level per output of the network, 2; found 3"),
            "{e}"
        );
        // Neither: the paper's two for two outputs, a refusal for more.
        assert_eq!(of_file(&none, 2, None).unwrap(), BANG_BANG);
        let e = of_file(&none, 7, None).unwrap_err().to_string();
        assert!(
            e.contains("7 outputs and its file records no duty levels") && e.contains("--levels"),
            "{e}"
        );
    }

    #[test]
    fn recorded_levels_that_are_no_levels_are_refused() {
        for (text, n, says) in [
            (
                "[-1, 1",
                2,
                "metadata `levels`: expected a JSON list of numbers, such as [-1, 1], found \
                 \"[-1, 1\"",
            ),
            ("\"-1,1\"", 2, "expected a JSON list of numbers"),
            (" -1 , 1 ", 2, "found \" -1 , 1 \""),
            (
                "[-1, 0, 1]",
                2,
                "records 3 duty levels for a network of 2 outputs",
            ),
            ("[1, -1]", 2, "expected strictly increasing"),
            ("[-2, 1]", 2, "expected within [-1, 1]"),
            (
                "[-1, 1.0000000001]",
                2,
                "expected within [-1, 1], found 1.0000000001",
            ),
            (
                "[-1, 5e-324]",
                2,
                "expected each zero or a normal number, found 5e-324",
            ),
            // JSON reads it as 0, a level the file did not mean.
            (
                "[-1, 1e-400, 1]",
                3,
                "metadata `levels`: line 1, column 6: 1e-400 reads as 0",
            ),
        ] {
            let e = of_file(&meta(Some(text)), n, None).unwrap_err();
            assert!(e.is_input() && e.to_string().contains(says), "{text}: {e}");
        }
    }
}
