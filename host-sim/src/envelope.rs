//! The runtime monitor's envelope, measured: the readings a policy decided on in the
//! episodes it balanced, per channel, as a histogram; the envelope is a quantile of each
//! channel's `|reading|` with a margin ([`Visited::envelope`]), and it is written as the
//! Rust module `shipped::envelope` beside the shipped policy ([`rust_module`]).
//!
//! Only successful episodes count, and only the periods whose reading was taken (a rejected
//! reading coasts and is no state the policy chose to be in).

use std::fmt::Write as _;

use std::path::Path;

use firmware::controller::{Command, Limits};
use firmware::linear::balance_gain;
use firmware::rig::Rig;
use host_common::provenance::Provenance;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use twin::Scenario;
use weights::source::comment_text;

use crate::eval::{ControllerKind, Net, episode};

/// Bins per channel: each covers 1/4096 of the channel's bound.
const BINS: usize = 4096;
/// The bound each channel's bins cover, `[x, x_dot, theta, theta_dot]`: the widest readings
/// a controller on Gymnasium's machine accepts ([`firmware::controller::Limits::track`]).
/// Larger readings fall in the last bin.
const RANGE: [f32; 4] = [2.4, 20.0, 0.42, 20.0];

/// How often each `|reading|` was seen, per channel, over the periods of balanced episodes.
#[derive(Clone, Debug, PartialEq)]
pub struct Visited {
    bins: [Vec<u64>; 4],
    /// Episodes run, and those that balanced to the horizon.
    pub episodes: u64,
    /// Episodes that balanced to the horizon, whose readings are counted.
    pub balanced: u64,
    /// Readings counted.
    pub periods: u64,
}

impl Visited {
    fn empty() -> Visited {
        Visited {
            bins: std::array::from_fn(|_| vec![0; BINS]),
            episodes: 0,
            balanced: 0,
            periods: 0,
        }
    }

    fn add(&mut self, reading: &[f32; 4]) {
        for ((bins, v), range) in self.bins.iter_mut().zip(reading).zip(RANGE) {
            let i = (v.abs() / range * BINS as f32) as usize;
            bins[i.min(BINS - 1)] += 1;
        }
        self.periods += 1;
    }

    fn merge(mut self, other: Visited) -> Visited {
        for (a, b) in self.bins.iter_mut().zip(&other.bins) {
            a.iter_mut().zip(b).for_each(|(a, b)| *a += b);
        }
        self.episodes += other.episodes;
        self.balanced += other.balanced;
        self.periods += other.periods;
        self
    }

    /// Per channel, the smallest bound (a bin's upper edge) that at least `quantile` of the
    /// readings lie within; `1.0` gives the largest reading's bin.
    pub fn quantile(&self, quantile: f64) -> [f32; 4] {
        let want = (quantile * self.periods as f64).ceil() as u64;
        std::array::from_fn(|c| {
            let mut seen = 0;
            let bin = self.bins[c]
                .iter()
                .position(|n| {
                    seen += n;
                    seen >= want.max(1)
                })
                .unwrap_or(BINS - 1);
            (bin + 1) as f32 * RANGE[c] / BINS as f32
        })
    }

    /// The envelope: each channel's `quantile` times `margin`, within its bound.
    pub fn envelope(&self, quantile: f64, margin: f32) -> [f32; 4] {
        let q = self.quantile(quantile);
        std::array::from_fn(|c| (q[c] * margin).min(RANGE[c]))
    }
}

/// The readings the policy (told its dead time, as `eval` runs it) decided on in `episodes`
/// seeded episodes of each scenario, counted where the episode balanced for `horizon`
/// periods. `done` is called after each scenario.
pub fn visited(
    net: &Net,
    scenarios: &[Scenario],
    horizon: u32,
    episodes: u64,
    seed: u64,
    done: impl Fn(&Scenario) + Sync,
) -> Visited {
    scenarios
        .iter()
        .map(|s| {
            let v = (0..episodes)
                .into_par_iter()
                .map(|e| one(net, s, horizon, seed, e))
                .reduce(Visited::empty, Visited::merge);
            done(s);
            v
        })
        .fold(Visited::empty(), Visited::merge)
}

/// One episode's readings, counted only if it balanced.
fn one(net: &Net, s: &Scenario, horizon: u32, seed: u64, e: u64) -> Visited {
    let mut v = Visited::empty();
    let stats = episode(ControllerKind::Policy, net, s, horizon, seed, e, |f| {
        if f.command != Command::Coast {
            v.add(&f.reading);
        }
    });
    if !stats.success {
        v = Visited::empty();
    }
    v.episodes = 1;
    v.balanced = u64::from(stats.success);
    v
}

/// The factors on each channel's quantile `envelope --margin` takes.
pub const MARGINS: std::ops::RangeInclusive<f64> = 1.0..=10.0;

/// Whether `q` is a share `envelope --quantile` takes: a normal number in (0, 1].
pub fn quantile_taken(q: f64) -> bool {
    q > 0.0 && weights::plain(q) && q <= 1.0
}

/// Largest envelope file read: a report is under a kilobyte.
const MAX_ENVELOPE_BYTES: u64 = 64 * 1024;

/// The envelope of a file `host-sim envelope --json` printed, as the monitor takes it:
/// refused (naming the file) unless it is such a report whose four bounds are finite and
/// not negative. For the monitor of the policy of digest `policy` ([`Net::digest`]), also
/// refused when the report records that it was measured for another. With the digest of
/// the rig it was measured on, where the report records one.
pub fn read_for(path: &Path, policy: Option<u64>) -> weights::Result<(Limits, Option<u64>)> {
    #[derive(Deserialize)]
    struct Envelope {
        // Read in f64: in f32, `5e-324` would be a zero before it could be refused.
        envelope: [f64; 4],
        // What the report says of its measurement, where it says it (a file written by hand
        // holds the envelope alone): checked, since a report that contradicts itself was
        // taken without a word.
        quantile: Option<f64>,
        margin: Option<f64>,
        balanced: Option<u64>,
        episodes_run: Option<u64>,
        policy_digest: Option<String>,
        rig_digest: Option<String>,
    }
    // Every message names the file as an envelope's: the command line and the Python
    // package both read it, and a bare path says nothing of which argument it was.
    let bytes = weights::files::read_capped(path, MAX_ENVELOPE_BYTES).map_err(|e| match e {
        weights::Error::Input(m) => weights::Error::Input(format!("envelope {m}")),
        io => io,
    })?;
    let bad =
        |why: String| weights::Error::Input(format!("envelope {}: {why}", weights::shown(path)));
    // The parser reads `1e-400` as 0 without a word.
    if let Some(why) = std::str::from_utf8(&bytes)
        .ok()
        .and_then(weights::hidden_zero)
    {
        return Err(bad(why));
    }
    let e: Envelope = weights::json::parse_bytes(&bytes).map_err(|e| {
        bad(format!(
            "expected the JSON `host-sim envelope --json` prints, {e}"
        ))
    })?;
    if let Some(why) = contradiction(&e.quantile, &e.margin, (e.balanced, e.episodes_run)) {
        return Err(bad(why));
    }
    if let Some(text) = &e.policy_digest {
        let recorded = parse_digest(text).ok_or_else(|| {
            bad(format!(
                "expected policy_digest as 0x and 16 hex digits, found {}",
                weights::quote(text)
            ))
        })?;
        if let Some(p) = policy.filter(|&p| p != recorded) {
            return Err(bad(format!(
                "measured for the policy of digest {}, not this one ({}): measure its own \
                 with host-sim envelope --policy ... --json",
                show_digest(recorded),
                show_digest(p)
            )));
        }
    }
    let limits = narrowed(&e.envelope).map_err(bad)?;
    let rig = match &e.rig_digest {
        Some(text) => Some(parse_digest(text).ok_or_else(|| {
            bad(format!(
                "expected rig_digest as 0x and 16 hex digits, found {}",
                weights::quote(text)
            ))
        })?),
        None => None,
    };
    // The firmware's refusal names the channel; the values are the file's.
    let limits = Limits::new(limits)
        .map_err(|why| bad(format!("{why}, found the limits {:?}", e.envelope)))?;
    Ok((limits, rig))
}

/// The limits of a report, each a zero or a normal f32, or why not.
fn narrowed(envelope: &[f64; 4]) -> Result<[f32; 4], String> {
    if let Some(x) = envelope.iter().find(|x| weights::past_f32(**x)) {
        return Err(format!(
            "expected each limit within float32's range (+-{:e}), found {x:e}",
            f32::MAX
        ));
    }
    // A subnormal limit (`1e-40`; `1e-39`, normal in f64 alone) is a slip, as every number
    // that comes in.
    if let Some(x) = envelope.iter().find(|x| !weights::plain(**x)) {
        return Err(format!(
            "expected each limit zero or a normal number, in float32 too (at least {:e}), \
             found {x:?}",
            f32::MIN_POSITIVE
        ));
    }
    Ok(envelope.map(|x| x as f32))
}

/// Refuses an envelope measured on the rig of digest `measured` for a board of `rig`, where
/// they differ: it bounds the readings of another plant (the shipped one, measured on
/// Gymnasium's machine, ran the desk rig's monitor).
pub fn measured_on(measured: Option<u64>, rig: &Rig) -> Result<(), String> {
    let this = firmware::link::digest::rig(rig);
    match measured {
        Some(m) if m != this => Err(format!(
            "the runtime monitor's envelope was measured on another machine (rig digest {}), \
             not this one ({}): measure one on it (host-sim envelope --rig FILE --json) and \
             give it with --envelope (envelope= in Python)",
            show_digest(m),
            show_digest(this)
        )),
        _ => Ok(()),
    }
}

/// A digest as a report writes it, [`show_digest`].
fn parse_digest(text: &str) -> Option<u64> {
    let hex = text.strip_prefix("0x")?;
    let digits = hex.len() == 16 && hex.bytes().all(|b| b.is_ascii_hexdigit());
    digits.then(|| u64::from_str_radix(hex, 16).ok()).flatten()
}

/// A digest as a report and the shipped module write it: `0x` and 16 hex digits (JSON's
/// numbers cannot hold 64 bits exactly in every reader).
pub fn show_digest(digest: u64) -> String {
    format!("{digest:#018x}")
}

/// What in a report's account of its measurement no `host-sim envelope` run could have
/// written: a quantile or margin the command refuses, more episodes balanced than ran.
fn contradiction(
    quantile: &Option<f64>,
    margin: &Option<f64>,
    (balanced, run): (Option<u64>, Option<u64>),
) -> Option<String> {
    if let Some(q) = quantile.filter(|&q| !quantile_taken(q)) {
        return Some(format!(
            "expected a quantile in (0, 1], normal, found {q:?}"
        ));
    }
    if let Some(m) = margin.filter(|m| !MARGINS.contains(m)) {
        let (lo, hi) = (MARGINS.start(), MARGINS.end());
        return Some(format!("expected a margin in [{lo}, {hi}], found {m:?}"));
    }
    match (balanced, run) {
        (Some(b), Some(r)) if b > r => Some(format!(
            "expected at most the episodes run ({r}) balanced, found {b}"
        )),
        _ => None,
    }
}

/// What `host-sim envelope --json` reports.
#[derive(Debug, Serialize)]
pub struct Report {
    /// Scenarios measured.
    pub scenarios: Vec<String>,
    /// Episodes per scenario, and their horizon.
    pub episodes: u64,
    /// Periods per episode.
    pub horizon: u32,
    /// Episodes that balanced, of all run.
    pub balanced: u64,
    /// All episodes run.
    pub episodes_run: u64,
    /// Readings counted.
    pub periods: u64,
    /// The quantile taken and the margin on it.
    pub quantile: f64,
    /// See `quantile`.
    pub margin: f32,
    /// Each channel's 0.99, 0.999 and 0.9999 quantiles and largest reading.
    pub quantiles: [[f32; 4]; 4],
    /// The envelope, `[x, x_dot, theta, theta_dot]`.
    pub envelope: [f32; 4],
    /// The policy measured, as a target's link names it ([`Net::digest`]).
    pub policy_digest: String,
    /// The rig it was measured on ([`firmware::link::digest::rig`]).
    pub rig_digest: String,
    /// The command that measured it, when, where.
    pub provenance: Provenance,
}

impl Report {
    /// The report of `v`, measured for the policy of digest `policy` on the rig of digest
    /// `rig`, with its envelope.
    pub fn of(
        v: &Visited,
        (policy, rig): (u64, u64),
        names: Vec<String>,
        run: (u64, u32),
        quantile: f64,
        margin: f32,
        provenance: Provenance,
    ) -> Report {
        Report {
            scenarios: names,
            episodes: run.0,
            horizon: run.1,
            balanced: v.balanced,
            episodes_run: v.episodes,
            periods: v.periods,
            quantile,
            margin,
            quantiles: [0.99, 0.999, 0.9999, 1.0].map(|q| v.quantile(q)),
            envelope: v.envelope(quantile, margin),
            policy_digest: show_digest(policy),
            rig_digest: show_digest(rig),
            provenance,
        }
    }
}

/// The Rust module `shipped::envelope`, beside `policy` in a crate that depends on `firmware`: the envelope, the digest of the policy it was
/// measured for, the fallback's gain for `rig`, and the monitor's whole configuration,
/// checked as it is compiled. `provenance` lines go into its header, escaped.
pub fn rust_module(envelope: [f32; 4], digest: u64, rig: &Rig, provenance: &[String]) -> String {
    let gain = balance_gain(&rig.params).map(|k| k as f32);
    // A Rust literal as the report writes it, so that the two read alike.
    let digest = show_digest(digest);
    let mut s = String::from(
        "//! The shipped policy's envelope: where the runtime monitor\n\
         //! ([`firmware::controller::monitor`]) lets it drive, and the monitor's configuration.\n\
         //! Generated by `host-sim envelope`; do not edit.\n//!\n",
    );
    for line in provenance {
        let _ = writeln!(s, "//! - {}", comment_text(line));
    }
    let _ = write!(
        s,
        "\nuse ::firmware::controller::{{Assurance, Limits}};\n\nuse super::policy::RIG;\n\n\
         /// FNV-1a 64 digest of the policy the envelope was measured for, as the link's\n\
         /// handshake names it ([`firmware::link::digest::policy`] of\n\
         /// [`super::policy::POLICY`] and [`super::policy::LEVELS`]).\n\
         pub const POLICY_DIGEST: u64 = {digest};\n\n\
         /// Per-channel bound on `|reading|`, `[x, x_dot, theta, theta_dot]`.\n\
         pub const ENVELOPE: Limits = match Limits::new({envelope:?}) {{\n    \
         Ok(l) => l,\n    Err(_) => panic!(\"the envelope is no limits\"),\n}};\n\n\
         /// The fallback's LQR gain for [`RIG`] ([`firmware::linear::balance_gain`]).\n\
         pub const FALLBACK_GAIN: [f32; 4] = {gain:?};\n\n\
         /// The monitor's configuration for the shipped policy on [`RIG`].\n\
         pub const ASSURANCE: Assurance = match RIG.assurance(ENVELOPE, FALLBACK_GAIN) {{\n    \
         Ok(a) => a,\n    Err(_) => panic!(\"the assurance is refused\"),\n}};\n"
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_are_bin_edges_counted_by_hand() {
        let mut v = Visited::empty();
        // 1,000 readings of x: 990 at 0.1 m, 9 at 0.5 m, one at 1.2 m.
        for i in 0..1000 {
            let x = match i {
                0..990 => 0.1,
                990..999 => -0.5,
                _ => 1.2,
            };
            v.add(&[x, 0.0, 0.0, 0.0]);
        }
        let edge = |x: f32| ((x / 2.4 * 4096.0).floor() + 1.0) * 2.4 / 4096.0;
        assert_eq!(v.quantile(0.99)[0], edge(0.1));
        assert_eq!(v.quantile(0.999)[0], edge(0.5));
        assert_eq!(v.quantile(1.0)[0], edge(1.2));
        assert_eq!(v.quantile(0.5)[1], 20.0 / 4096.0);
        assert_eq!(v.envelope(0.999, 10.0)[0], 2.4);
    }

    #[test]
    fn a_hostile_envelope_file_is_quoted_escaped_and_short() {
        let path = std::env::temp_dir().join(format!("envelope-{}.json", std::process::id()));
        let junk = "\\u001b[2J\\u0007".repeat(3_000);
        std::fs::write(&path, format!("{{\"envelope\": \"{junk}\"}}")).unwrap();
        let e = read_for(&path, None).unwrap_err().to_string();
        std::fs::remove_file(&path).unwrap();
        assert!(e.contains("expected the JSON"), "{e}");
        assert!(e.len() < 600 && !e.chars().any(char::is_control), "{e}");
    }
}
