//! Runtime assurance: a monitor that lets the learned policy drive only where it is known to
//! do well, and hands the loop to a verified fallback elsewhere.
//!
//! The design is the Simplex architecture (Sha, "Using Simplicity to Control Complexity",
//! IEEE Software 18(4), 2001; Seto, Krogh, Sha and Chutinan, "The Simplex Architecture for
//! Safe Online Control System Upgrades", ACC 1998): a high-performance controller (the
//! policy) runs while the state stays inside an envelope where it has been verified, a
//! simple controller whose behaviour is understood (LQR on the same estimate) takes over
//! when the state leaves it, and a decision module between them switches. Here:
//!
//! - **Policy** while the reading lies inside the *envelope* (the
//!   states the policy visited in the evaluation it passed, with a margin, generated beside
//!   the policy by `host-sim envelope`), its readings are sound, and its scores are finite.
//! - **Fallback** (LQR, `u = -K s`, on the state the command will meet, its force as the
//!   nearest of the policy's duty levels and full duty either way: bang-bang with the
//!   paper's two, a duty near the linear controller's with a rig's finer levels) when the
//!   reading leaves the envelope, when [`Assurance::FAULT_RUN`] readings in a row were
//!   rejected or came from the model alone (a frozen encoder), or when the policy's scores
//!   are not finite. Back to the policy only after [`Assurance::DWELL`] sound periods in a
//!   row inside the envelope shrunk by [`HYSTERESIS`], so that a state on the envelope's edge
//!   does not switch every period.
//! - **Stopped** (duty off, latched) when [`Assurance::FAULT_RUN`] readings in a row lie
//!   beyond what the fallback can still recover (the pole past
//!   the rig's failure angle, or the cart at the end of its accepted track, where the
//!   controller's limits already coast each period); one such reading is more likely a
//!   glitch than a state. A stopped controller stays stopped; a board re-arms it by building
//!   it again.
//!
//! Every switch is counted in the controller's
//! [`FaultCounters`] and every period flagged in its telemetry
//! ([`FaultFlags::FALLBACK`], [`FaultFlags::STOPPED`]). The monitor is fixed-size and
//! allocation-free, and runs on the reading's own format: the envelope checks of an integer
//! reading are integer compares.

use super::faults::{FaultCounters, FaultFlags, Limits};
use super::levels::{Command, Duty, nearest};
use super::policy::{Answer, Policy, Scores};
use super::reading::Reading;
use crate::config::{ConfigError, check, positive};

/// The fraction of the envelope a reading must lie within, channel by channel, for the
/// fallback to hand the loop back.
pub const HYSTERESIS: f32 = 0.8;

/// Which controller drives.
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Mode {
    /// The learned policy.
    Policy,
    /// The LQR fallback.
    Fallback,
    /// Duty off, until the controller is built again.
    Stopped,
}

/// What the monitor holds: where the policy may drive, where the fallback can recover, the
/// fallback's gain, and its timing. Built once ([`Assurance::new`] is a `const fn`, so a
/// board's configuration is checked as it is compiled).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Assurance {
    envelope: Limits,
    calm: Limits,
    recoverable: Limits,
    gain: [f32; 4],
    full_force: f32,
}

impl Assurance {
    /// Sound periods inside the shrunk envelope before the policy drives again: half a
    /// second at 50 Hz.
    pub const DWELL: u16 = 25;
    /// Rejected or model-only readings in a row that hand the loop to the fallback.
    pub const FAULT_RUN: u16 = 3;

    /// The assurance of a policy whose `envelope` was measured, with the fallback's LQR
    /// `gain` (`u = -K s`, in newtons per unit of each channel;
    /// [`crate::linear::balance_gain`] designs it) on a motor whose full duty pushes with
    /// `full_force` newtons, which can recover a reading within `recoverable` (the rig's,
    /// [`Rig::assurance`](crate::rig::Rig::assurance)). Refused: a gain that is not finite,
    /// a full force that is not positive.
    pub const fn new(
        envelope: Limits,
        recoverable: Limits,
        gain: [f32; 4],
        full_force: f32,
    ) -> Result<Assurance, ConfigError> {
        check!(positive(full_force as f64, "assurance.full_force"));
        let mut i = 0;
        while i < 4 {
            if !gain[i].is_finite() {
                return Err(ConfigError::NotFinite("assurance.gain"));
            }
            i += 1;
        }
        let e = envelope.max_abs();
        let calm = check!(Limits::new([
            e[0] * HYSTERESIS,
            e[1] * HYSTERESIS,
            e[2] * HYSTERESIS,
            e[3] * HYSTERESIS,
        ]));
        Ok(Assurance {
            envelope,
            calm,
            recoverable,
            gain,
            full_force,
        })
    }
}

/// The decision module: which controller drives this period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Monitor {
    assurance: Assurance,
    mode: Mode,
    /// Sound periods in a row inside the shrunk envelope, while in the fallback.
    calm: u16,
    /// Faulty readings in a row.
    faulty: u16,
    /// Readings in a row beyond what the fallback can recover.
    lost: u16,
}

impl Monitor {
    /// A monitor that starts with the policy driving.
    pub const fn new(assurance: Assurance) -> Monitor {
        Monitor {
            assurance,
            mode: Mode::Policy,
            calm: 0,
            faulty: 0,
            lost: 0,
        }
    }

    /// What it was built with.
    pub fn assurance(&self) -> Assurance {
        self.assurance
    }

    /// Who drives now.
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// A period whose reading was rejected with `flags` (the controller coasts): one more
    /// faulty reading, and, if the cart's or the pole's channel was out of range, one more
    /// beyond what the fallback can recover.
    pub fn rejected(&mut self, flags: FaultFlags, counters: &mut FaultCounters) {
        let beyond = [0, 2]
            .iter()
            .any(|&c| flags.contains(FaultFlags::out_of_range(c)));
        self.beyond(beyond, counters);
        if self.mode != Mode::Stopped {
            self.fault(counters);
        }
    }

    /// A period with reading `obs`, `seen` the state the command will meet (`obs` itself
    /// without a predictor), `model_only` when the reading came from the model alone:
    /// `decide` asked for `policy`'s scores and decision where the policy drives (its
    /// decision `None` when its scores are not finite), the fallback's force driven as the
    /// nearest of `policy`'s levels and full duty either way elsewhere; then the scores recorded, the command, and
    /// the flags of who decided.
    pub fn decide<O: Reading, P: Policy<O>>(
        &mut self,
        obs: &O,
        seen: &O,
        model_only: bool,
        policy: &mut P,
        decide: impl FnOnce(&mut P, &O) -> Answer<P::Scores>,
        counters: &mut FaultCounters,
    ) -> (P::Scores, Command, FaultFlags) {
        let beyond = !obs.flags(&self.assurance.recoverable).is_empty();
        self.beyond(beyond, counters);
        if self.mode == Mode::Stopped {
            return (P::Scores::UNSCORED, Command::Coast, FaultFlags::STOPPED);
        }
        if model_only {
            self.fault(counters);
        } else {
            self.faulty = 0;
        }
        if self.mode == Mode::Policy && !obs.flags(&self.assurance.envelope).is_empty() {
            self.fall_back(counters);
        }
        if self.mode == Mode::Fallback {
            let calm = !model_only && obs.flags(&self.assurance.calm).is_empty();
            self.calm = if calm { self.calm.saturating_add(1) } else { 0 };
            if self.calm >= Assurance::DWELL {
                self.mode = Mode::Policy;
                counters.recoveries = counters.recoveries.saturating_add(1);
            }
        }
        let mut q = P::Scores::UNSCORED;
        if self.mode == Mode::Policy {
            let duty;
            (q, duty) = decide(policy, seen);
            if let Some(d) = duty {
                return (q, Command::Drive(d), FaultFlags::default());
            }
            counters.count_undecided();
            self.fall_back(counters);
        }
        counters.fallback_periods = counters.fallback_periods.saturating_add(1);
        let force = seen.lqr(&self.assurance.gain);
        // Full duty either side of the policy's levels: levels that stop short of it
        // (`-0.5,0.5`) must not take force from what recovers the pole.
        let duty = |i: usize| match i.checked_sub(1) {
            None => Some(Duty::LEFT),
            Some(k) => policy
                .duty(k)
                .or_else(|| (k > 0 && policy.duty(k - 1).is_some()).then_some(Duty::RIGHT)),
        };
        let level = nearest(duty, force, self.assurance.full_force);
        let command = match level.and_then(duty) {
            Some(duty) => Command::Drive(duty),
            None => Command::Coast,
        };
        (q, command, FaultFlags::FALLBACK)
    }

    /// One more faulty reading; a run of them hands the loop to the fallback.
    fn fault(&mut self, counters: &mut FaultCounters) {
        self.faulty = self.faulty.saturating_add(1);
        self.calm = 0;
        if self.mode == Mode::Policy && self.faulty >= Assurance::FAULT_RUN {
            self.fall_back(counters);
        }
    }

    /// One more reading beyond what the fallback can recover, or the end of a run of them;
    /// a run stops the controller.
    fn beyond(&mut self, beyond: bool, counters: &mut FaultCounters) {
        self.lost = if beyond {
            self.lost.saturating_add(1)
        } else {
            0
        };
        if self.mode != Mode::Stopped && self.lost >= Assurance::FAULT_RUN {
            self.mode = Mode::Stopped;
            counters.safe_stops = counters.safe_stops.saturating_add(1);
        }
    }

    fn fall_back(&mut self, counters: &mut FaultCounters) {
        self.mode = Mode::Fallback;
        self.calm = 0;
        counters.fallbacks = counters.fallbacks.saturating_add(1);
    }
}

#[cfg(test)]
mod tests;
