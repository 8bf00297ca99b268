//! Whether a fit can be trusted: each encoder's residuals (measured less simulated counts)
//! against what an encoder's rounding alone leaves, and their correlation from one period
//! to the next. A model that holds leaves residuals of about the rounding's `1/sqrt(12)`
//! count, nearly independent; a machine outside the model's class (a motor's electrical
//! lag, a pole that is not a uniform rod, readings taken at uneven times) or a log read the
//! wrong way round leaves residuals far larger, which the multiple shooting's pieces turn
//! into slow swings, each period's like the one before.

use firmware::identify::Experiment;

use super::channel::{Channel, ROUNDING_SD};
use super::fit::{Fit, Trace};
use super::log::Log;

/// The most RMS residual a channel of a fit that holds may have, counts. Logs of machines
/// inside the model's class stay far below it even with a count of jitter on every
/// reading, and logs taken at uneven times, or of machines outside the class, go far above
/// (`docs/RIGS.md`).
pub const MAX_RMS_COUNTS: f64 = 2.5;
/// The most RMS the slowly varying part of a channel's residuals may have, counts
/// ([`Channel::slow`]): a count of error that persists from period to period is a model
/// that does not describe the machine (`docs/RIGS.md`).
pub const MAX_SLOW_COUNTS: f64 = 1.0;
/// How many times smaller a cart log's largest RMS residual must be with the pole's counts
/// negated for the pole to read as wired the other way.
pub const INVERTED_RATIO: f64 = 10.0;

impl Channel {
    /// The RMS of the residuals' slowly varying part, counts: `rms sqrt(r1)` for a lag-1
    /// autocorrelation `r1`, which white noise of variance `w^2` on a part of variance `s^2`
    /// that barely changes from one period to the next makes `s^2 / (s^2 + w^2)`. Less the
    /// scatter of `n` independent residuals' autocorrelation, three times `1/sqrt(n)`, so
    /// that loud white noise does not read as slow.
    pub fn slow(&self) -> f64 {
        let n = self.measured.len().max(1) as f64;
        self.rms * (self.autocorrelation - 3.0 / n.sqrt()).max(0.0).sqrt()
    }

    /// Whether its residuals are those of a model that holds: neither large nor slow.
    pub fn fits(&self) -> bool {
        self.rms <= MAX_RMS_COUNTS && self.slow() <= MAX_SLOW_COUNTS
    }
}

/// Each channel of `fit` that does not fit, with the trace it belongs to.
pub fn findings(fit: &Fit) -> Vec<(&Trace, &Channel)> {
    fit.traces
        .iter()
        .flat_map(|t| t.channels.iter().map(move |c| (t, c)))
        .filter(|(_, c)| !c.fits())
        .collect()
}

/// The warning for `channel` of `trace`, a trace of `log`.
pub fn warning(log: &Log, trace: &Trace, channel: &Channel) -> String {
    let (worst, rms) = &channel.worst;
    format!(
        "{} (line {}, {}): the fit does not explain the {} counts: RMS residual {:.2} counts \
         against {:.2} from an encoder's rounding alone (at most {MAX_RMS_COUNTS} for a fit \
         that holds), lag-1 autocorrelation {:.2}, a slowly varying part of {:.2} counts (at \
         most {MAX_SLOW_COUNTS}); largest, {:.2} counts RMS, in periods {} to {}. {}",
        log.origin,
        log.line,
        log.experiment.name(),
        channel.name,
        channel.rms,
        ROUNDING_SD,
        channel.autocorrelation,
        channel.slow(),
        rms,
        trace.start + worst.start,
        trace.start + worst.end,
        if channel.slow() > MAX_SLOW_COUNTS {
            "The machine does things the model does not (a motor whose force lags its duty, a \
             pole that is not a uniform rod, a dead time that is not a whole number of \
             periods): the estimates and their intervals are not to be trusted"
        } else {
            "The readings are noisy or taken at uneven times: the estimates may hold, their \
             intervals are too narrow"
        }
    )
}

/// What the identified rig file records of `fit`'s channels that do not fit, if any.
pub fn record(fit: &Fit) -> Option<twin::rigfile::Misfit> {
    let found = findings(fit);
    let largest = |name: &str| {
        fit.traces
            .iter()
            .flat_map(|t| &t.channels)
            .filter(|c| c.name == name)
            .map(|c| c.rms)
            .fold(0.0, f64::max)
    };
    (!found.is_empty()).then(|| twin::rigfile::Misfit {
        cart_rms_counts: largest("cart"),
        pole_rms_counts: largest("pole"),
        autocorrelation: found
            .iter()
            .map(|(_, c)| c.autocorrelation)
            .fold(-1.0, f64::max),
    })
}

/// The largest RMS residual of a cart log's channels in `fit`, counts.
pub fn worst_cart(fit: &Fit, logs: &[Log]) -> f64 {
    fit.traces
        .iter()
        .filter(|t| logs[t.log].experiment == Experiment::Cart)
        .flat_map(|t| &t.channels)
        .map(|c| c.rms)
        .fold(0.0, f64::max)
}

/// `logs` as a pole encoder wired the other way reads them: each count `c` becomes `-c - 1`,
/// the count below the negated angle.
pub fn inverted(logs: &[Log]) -> Vec<Log> {
    logs.iter()
        .map(|l| Log {
            pole: l.pole.iter().map(|&c| !c).collect(),
            ..l.clone()
        })
        .collect()
}

/// The refusal of `logs` whose pole reads inverted: `fit` as they are, `flipped` with the
/// pole's counts negated.
pub fn inverted_refusal(logs: &[Log], fit: &Fit, flipped: &Fit) -> weights::Error {
    let mut carts: Vec<&str> = logs
        .iter()
        .filter(|l| l.experiment == Experiment::Cart)
        .map(|l| l.origin.as_str())
        .collect();
    carts.dedup();
    weights::Error::Input(format!(
        "{}: the pole's counts appear inverted: negated, the cart logs fit with RMS residuals \
         of at most {:.2} counts, as logged {:.2}. The log format counts the pole's angle \
         growing as the pole turns the way that carries a hanging pole's tip towards -x (an \
         upright pole's towards +x: firmware::identify); swap the pole encoder's A and B \
         and run the experiments again",
        carts.join(", "),
        worst_cart(flipped, logs),
        worst_cart(fit, logs)
    ))
}
