//! The cart logs' pieces ([`model::SEGMENT_S`], multiple shooting) as the fit adapts them:
//! the first pieces the dead time is chosen on, so that its search costs the same however
//! long the logs are, and pieces whose simulation parts from the measurement, cut in two.
//!
//! A hanging pole pumped over the top passes the upright slowly now and then; a piece
//! holding such a passage is chaotic over its two seconds (the upright's instability grows
//! an error `exp(t sqrt(3 g / 4 l))`-fold, 10^5 over 2 s of a 0.22 m pole), and its
//! simulation from the counts' state can fall the other way and stay there, a minimum of
//! the sum of squares no step leaves, its residuals hundreds of counts that pull every
//! estimate. Halved, the passage's growth is the square root of that; halved again, less.

use std::ops::Range;

use super::model::{self, CartData, Setup};

/// How many seconds of cart logs the dead time is screened on: the first pieces, whole.
pub const SCREEN_S: f64 = 30.0;
/// How many times a piece is cut in two at most: to an eighth of [`model::SEGMENT_S`].
pub const CUTS: usize = 3;
/// How many times the median piece's RMS residual a piece's must be for it to be cut.
/// In-class pieces scatter by tens of percent about the median; a piece whose simulation
/// has fallen the other way is hundreds of times off.
pub const LOST: f64 = 10.0;
/// The least RMS residual of a piece cut, counts: a few times an encoder's rounding, so
/// that logs of exact counts never cut a piece for the rounding's own scatter.
pub const LOST_COUNTS: f64 = 3.0;

/// `carts`' first pieces, `periods` of them in all at most but at least one piece, whole
/// pieces in the order given: each log whole if it is no longer.
pub fn prefix(carts: &[CartData], periods: usize) -> Vec<CartData> {
    let mut left = periods;
    let mut out = Vec::new();
    for c in carts {
        if left == 0 {
            break;
        }
        let segments: Vec<Range<usize>> = if c.duty.len() <= left {
            c.segments.clone()
        } else {
            let whole: Vec<Range<usize>> = c
                .segments
                .iter()
                .take_while(|s| s.end <= left)
                .cloned()
                .collect();
            match (whole.is_empty(), out.is_empty()) {
                (false, _) => whole,
                (true, true) => c.segments[..1].to_vec(),
                (true, false) => break,
            }
        };
        let n = segments.last().map_or(0, |s| s.end);
        left = left.saturating_sub(n);
        out.push(CartData {
            duty: c.duty[..n].to_vec(),
            counts: c.counts[..n].to_vec(),
            pole: c.pole[..n].to_vec(),
            per_m: c.per_m,
            per_rad: c.per_rad,
            segments,
        });
    }
    out
}

/// The cart fit's vector `x` on pieces `from` (each log's; `to`'s logs, `from`'s first),
/// its shared unknowns first, as the vector of the same fit on `to`: the shared unknowns and each piece that starts where
/// one of `from` did kept, every other piece's state `start`'s (the counts').
pub fn carry(
    (from, x): (&[Vec<Range<usize>>], &[f64]),
    to: &[CartData],
    shared: usize,
    start: &[f64],
) -> Vec<f64> {
    let mut out = x[..shared].to_vec();
    let mut first = shared;
    let mut new = 0;
    for (i, c) in to.iter().enumerate() {
        let pieces = from.get(i).map_or(&[][..], Vec::as_slice);
        for s in &c.segments {
            let own = match pieces.iter().position(|p| p.start == s.start) {
                Some(i) => &x[first + i * model::CART_NUISANCE..][..model::CART_NUISANCE],
                None => &start[new..new + model::CART_NUISANCE],
            };
            out.extend_from_slice(own);
            new += model::CART_NUISANCE;
        }
        first += pieces.len() * model::CART_NUISANCE;
    }
    out
}

/// Cuts in two every piece of `carts` whose RMS residual at `x` (with `setup`, a cart fit on
/// them with unit weights) is [`LOST`] times the median piece's and at least
/// [`LOST_COUNTS`], if it is at least `shortest` periods long: each log's pieces after the
/// cuts, if there was one.
pub fn cut_lost(setup: &Setup, x: &[f64], shortest: usize) -> Option<Vec<Vec<Range<usize>>>> {
    let rms: Vec<f64> = setup
        .blocks()
        .iter()
        .enumerate()
        .map(|(b, block)| {
            let mut out = vec![0.0; block.rows.len()];
            setup.eval(x, b, &mut out, false);
            (out.iter().map(|r| r * r).sum::<f64>() / out.len().max(1) as f64).sqrt()
        })
        .collect();
    let mut sorted = rms.clone();
    sorted.sort_by(f64::total_cmp);
    let median = sorted.get(sorted.len() / 2).copied().unwrap_or(0.0);
    let limit = (LOST * median).max(LOST_COUNTS);
    let before: Vec<Vec<Range<usize>>> = setup.carts.iter().map(|c| c.segments.clone()).collect();
    let mut lost = rms.iter().map(|&r| r > limit);
    let cut: Vec<Vec<Range<usize>>> = before
        .iter()
        .map(|pieces| {
            pieces
                .iter()
                .flat_map(|s| {
                    let mid = s.start + s.len() / 2;
                    if lost.next() == Some(true) && s.len() >= 2 * shortest {
                        vec![s.start..mid, mid..s.end]
                    } else {
                        vec![s.clone()]
                    }
                })
                .collect()
        })
        .collect();
    (cut != before).then_some(cut)
}

#[cfg(test)]
mod tests;
