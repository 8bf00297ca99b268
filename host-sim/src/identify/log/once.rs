//! One experiment, one log: the same measurement given twice is refused.

use weights::Result;

use super::{Log, doubled_midpoints, first_count, input};

/// Refuses an experiment given twice, in one file or across files: counted twice, it
/// narrowed every interval by the square root of two. Experiments are compared by what was
/// measured, their samples, not by their text: a copy with other line ends or another
/// comment, or a file holding them twice, is the same measurement (of one experiment, period
/// and encoders). The cart is counted from each log's first count, its zero wherever the
/// board started; the pole from the hanging position nearest its first, whole revolutions
/// on ([`doubled_midpoints`]): a pole counted from another angle is another measurement.
pub fn check_each_once(logs: &[Log]) -> Result<()> {
    use std::hash::{Hash, Hasher};
    let mut seen: std::collections::HashMap<u64, Vec<(&Log, Vec<Sample>)>> = Default::default();
    for log in logs {
        let samples = samples(log);
        let mut h = std::hash::DefaultHasher::new();
        (setting(log), &samples).hash(&mut h);
        let bucket = seen.entry(h.finish()).or_default();
        let same = |(a, s): &&(&Log, Vec<Sample>)| setting(a) == setting(log) && *s == samples;
        if let Some((first, _)) = bucket.iter().find(same) {
            let shift = |a: &[i32], b: &[i32]| first_count(b) - first_count(a);
            let (cart, pole) = (shift(&first.cart, &log.cart), shift(&first.pole, &log.pole));
            let zero = if (cart, pole) == (0, 0) {
                String::new()
            } else {
                format!(", its counts shifted by {cart} (cart) and {pole} (pole)")
            };
            return Err(input(
                &log.origin,
                log.line,
                format!(
                    "expected each experiment once, found the same samples as {}:{}{zero}",
                    first.origin, first.line
                ),
            ));
        }
        bucket.push((log, samples));
    }
    Ok(())
}

/// What a log measured with: its experiment, period (bits) and encoders' resolutions.
fn setting(log: &Log) -> (&str, u64, [u32; 2]) {
    let e = [
        log.encoders.cart_counts_per_m,
        log.encoders.pole_counts_per_rev,
    ];
    (log.experiment.name(), log.period_s.to_bits(), e)
}

/// A period as [`check_each_once`] compares it: duty bits, cart count, pole midpoint.
type Sample = (u64, i64, i64);

/// Each period's duty (its bits, zero's sign dropped), cart count less the log's first, and
/// pole count from the hanging position nearest the log's first ([`doubled_midpoints`]).
fn samples(log: &Log) -> Vec<Sample> {
    let cart = first_count(&log.cart);
    log.duty
        .iter()
        .zip(&log.cart)
        .zip(doubled_midpoints(log))
        .map(|((d, &c), p)| ((d + 0.0).to_bits(), i64::from(c) - cart, p))
        .collect()
}
