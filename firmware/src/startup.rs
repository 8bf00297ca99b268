//! From power-on to balance, and back after a fall: the mode machine a rig's loop runs
//! around the balance controller, once per control period, on the encoders' raw counts.
//!
//! A rig does not start balanced. At power-on the pole hangs (and may still swing), the
//! encoders count from wherever they were, and a balance controller would read an angle of
//! half a turn. A [`Sequencer`] takes the loop from there, in [`Phase`]s:
//!
//! - **Homing**, with a [`Homing`]: the cart driven gently against the track's -x end stop
//!   until it stalls, which puts the centre the track's half-length away, then to the centre.
//! - **Zeroing**, motor off: the pole's zero is the one gravity gives. A pendulum swings
//!   symmetrically about hanging, so the middle of its swing is the hanging count, whether it
//!   swings 30 degrees or rests: from the turning points of a swing, the decay cancelled,
//!   or from two windows of [`Startup::zero_periods`] at rest, once two in a row agree
//!   within a count. Upright is half a revolution from it. The cart's zero is the homed
//!   centre, or where it stands then: without homing a user centres the cart before power-on.
//! - **Waiting**, motor off, until a hand lifts the pole into the catch region; or, with a
//!   [`Swing`], **SwingingUp**: an energy-based swing-up ([`swing`]) drives instead.
//! - **Catching**: the pole inside the catch region ([`Startup::catch_angle`] and
//!   [`Startup::catch_rate`]); whoever drove before goes on driving. After
//!   [`Startup::catch_periods`] in a row inside, the balance controller takes over;
//!   leaving the region first goes back.
//! - **Balancing**: the balance controller drives, until the pole passes
//!   [`Startup::release_angle`] or the cart the track's accepted end ([`Rig::limits`]).
//! - **Fallen**: the motor off from that period until the pole is below horizontal, then
//!   waiting (or swinging up) again, with the zero kept: no reset.
//!
//! Every transition is counted ([`Transitions`]). The sequencer decides from counts alone
//! (the angle to a count, rates from the difference of consecutive counts), so it runs the
//! same beside either estimator and cannot be misled by an estimate that has not yet
//! converged; the estimator keeps following the plant through the periods it does not
//! decide ([`Controller::hold`]). [`Sequencer::run`] is a loop's whole period with it.
//! Fixed-size, allocation-free, and no input makes it panic.

use crate::config::{ConfigError, check, non_negative, positive};
use crate::controller::{Actuator, Command, Controller, Policy, StateSensor};
use crate::estimator::{Zeroed, wrap};
use crate::rig::Rig;

mod home;
pub mod swing;
mod zero;

pub use home::Homing;
use home::{Home, Homed};
use swing::Pump;
pub use swing::Swing;
use zero::Zeroing;

/// Where the loop is between power-on and balance.
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Phase {
    /// Motor off, taking the pole's hanging zero.
    Zeroing,
    /// Motor off, until the pole is lifted into the catch region.
    Waiting,
    /// The energy-based swing-up drives.
    SwingingUp,
    /// Inside the catch region, not yet for long enough.
    Catching,
    /// The balance controller drives.
    Balancing,
    /// Past the release angle or the track's end: motor off until the pole is below
    /// horizontal.
    Fallen,
    /// Before zeroing, with a [`Homing`]: the cart driven gently against the -x end stop,
    /// then to the centre.
    Homing,
}

/// A window of `seconds` in whole periods of `tau` s, rounded up: at least two (a window
/// compares periods), at most what a `u16` counts.
pub fn periods(seconds: f64, tau: f64) -> u16 {
    libm::ceil(seconds / tau).clamp(2.0, 65_535.0) as u16
}

/// [`Startup::suggested`]'s trim rate, rad per metre-second, and its bound, rad (2 degrees).
/// Most periods a reading may be asked to stay in the catch region: ten seconds at 50 Hz.
/// More would leave the pole to fall while the board waited for a catch.
pub const MAX_CATCH_PERIODS: u16 = 500;

const TRIM_RATE: f32 = 0.012;
const TRIM_MAX: f32 = 0.035;

/// How a rig starts: how long the zero is watched for, where the balance controller may take
/// over and where it must let go, and the swing-up if there is one. Checked against its rig
/// by [`Startup::check`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Startup {
    /// Periods in each of the two windows a pole at rest is watched over: long enough that a
    /// pole still swinging moves more than a count within one (half a swing).
    pub zero_periods: u16,
    /// The catch region's half-width in angle from upright, rad.
    pub catch_angle: f32,
    /// The catch region's half-width in the pole's rate, rad/s.
    pub catch_rate: f32,
    /// Periods in a row inside the catch region before the balance controller drives.
    pub catch_periods: u16,
    /// The angle from upright past which the motor turns off, rad: above the catch angle, at
    /// most the rig's failure angle.
    pub release_angle: f32,
    /// The swing-up, or `None` to wait for a hand.
    pub swing: Option<Swing>,
    /// How fast the zero is refined while balancing, rad per metre-second: the pole's
    /// reading is moved by this times the cart's distance from the centre each second
    /// (integral action), so a zero a little off, a track not level or a cable's pull
    /// leaves the cart centred rather than parked where its position term cancels the error.
    /// 0 turns it off.
    pub trim_rate: f32,
    /// The most the zero is refined by, rad.
    pub trim_max: f32,
    /// Homing the cart before the zero, or `None` for a cart centred by hand.
    pub homing: Option<Homing>,
}

impl Startup {
    /// A start-up for `rig` from its physics, swinging up: the zero watched for half a swing
    /// of the hanging pole (`pi / w` with `w = sqrt(3 g / 4 l)`, a uniform pole's angular
    /// frequency), the catch region 0.7 of the failure angle and `w / 4` in rate, three
    /// periods inside, the release at 0.95 of the failure angle. The swing-up's acceleration
    /// sways the cart by about `a / w^2` at the pendulum's frequency: it asks for the most
    /// that keeps that sway within 0.3 of the track's accepted half-length, and at most half
    /// the cart's stall acceleration (`F / (M + m)`). Its centring, a spring of
    /// `w^2 (SPRING_M / T)` and a damper of `w (DAMPER_M / T)` on the accepted half-length
    /// `T`, pulls the cart back more gently the longer its track, since part of that pull is
    /// in phase with the pump and takes energy out of the swing; its energy gain and its
    /// overshoot are the ones measured on the desk rig (`docs/STARTUP.md`). The trim refines the zero by up to 2 degrees, at 0.012 rad
    /// per metre-second: slow beside the balance (a cart parked 0.1 m off moves the reading by
    /// a count of a 2,400-count encoder in about 2 s), fast enough to centre the cart within
    /// half a minute of a zero a degree off, measured on the desk and lab rigs.
    pub fn suggested(rig: &Rig) -> Result<Startup, ConfigError> {
        // The lengths that give the centring measured on the desk rig's track; the same
        // spring and damper on the lab rig's longer track drained its slower swing
        // (docs/STARTUP.md).
        const SPRING_M: f64 = 0.063;
        const DAMPER_M: f64 = 0.24;
        let rig = check!(rig.check());
        let p = &rig.params;
        let w = libm::sqrt(3.0 * p.gravity / (4.0 * p.length));
        let track = f64::from(check!(rig.limits()).max_abs()[0]);
        let failure = p.theta_threshold_radians as f32;
        let max_accel = (0.3 * track * w * w).min(0.5 * p.force_mag / p.total_mass());
        let startup = Startup {
            zero_periods: periods(core::f64::consts::PI / w, p.tau),
            catch_angle: 0.7 * failure,
            catch_rate: (w / 4.0) as f32,
            catch_periods: 3,
            release_angle: 0.95 * failure,
            swing: Some(Swing {
                energy_gain: 3.0,
                max_accel: max_accel as f32,
                centring: [w * w * SPRING_M / track, w * DAMPER_M / track].map(|c| c as f32),
                overshoot: 0.015,
            }),
            trim_rate: TRIM_RATE,
            trim_max: TRIM_MAX,
            homing: None,
        };
        startup.check(&rig)
    }

    /// `self`, if every region is one a rig can run on `rig`: finite, non-empty, the catch
    /// region inside the release angle, the release angle at most the rig's failure angle,
    /// the windows at least a period long, the trim not negative and below the catch angle,
    /// and a swing-up as [`Swing::check`] accepts.
    pub const fn check(self, rig: &Rig) -> Result<Startup, ConfigError> {
        if self.zero_periods < 2 {
            return Err(ConfigError::TooFew("startup.zero_periods"));
        }
        if self.catch_periods == 0 {
            return Err(ConfigError::NotPositive("startup.catch_periods"));
        }
        if self.catch_periods > MAX_CATCH_PERIODS {
            return Err(ConfigError::AboveLimit(
                "startup.catch_periods",
                "at most MAX_CATCH_PERIODS periods",
            ));
        }
        check!(positive(self.catch_angle as f64, "startup.catch_angle"));
        check!(positive(self.catch_rate as f64, "startup.catch_rate"));
        check!(positive(self.release_angle as f64, "startup.release_angle"));
        if self.catch_angle >= self.release_angle {
            return Err(ConfigError::AboveLimit(
                "startup.catch_angle",
                "below startup.release_angle",
            ));
        }
        if self.release_angle as f64 > rig.params.theta_threshold_radians {
            return Err(ConfigError::AboveLimit(
                "startup.release_angle",
                "at most params.theta_threshold_radians",
            ));
        }
        check!(non_negative(self.trim_rate as f64, "startup.trim_rate"));
        check!(non_negative(self.trim_max as f64, "startup.trim_max"));
        if self.trim_max >= self.catch_angle {
            return Err(ConfigError::AboveLimit(
                "startup.trim_max",
                "below startup.catch_angle",
            ));
        }
        if let Some(s) = self.swing {
            check!(s.check());
        }
        if let Some(h) = self.homing {
            check!(h.check());
        }
        Ok(self)
    }
}

/// Every transition so far, by kind.
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Transitions {
    /// Zeros taken (one per power-on).
    pub zeroed: u32,
    /// Entries into the catch region.
    pub entered: u32,
    /// Hand-overs to the balance controller.
    pub caught: u32,
    /// Catches abandoned: the pole left the region before the hand-over.
    pub missed: u32,
    /// Falls: past the release angle or the track's end while balancing.
    pub fell: u32,
    /// Centres found by homing.
    pub homed: u32,
}

/// What the loop does this period.
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Act {
    /// Drive this command without asking the balance controller
    /// ([`Controller::hold`](crate::controller::Controller::hold)).
    Hold(Command),
    /// Run the balance controller's period. `engaged` in its first period: rearm it
    /// ([`Controller::rearm`](crate::controller::Controller::rearm)).
    Balance {
        /// The first period of this catch.
        engaged: bool,
    },
}

/// The mode machine, from power-on ([`Sequencer::new`]) on.
#[derive(Clone, Copy, Debug)]
pub struct Sequencer {
    startup: Startup,
    /// Radians per pole count, metres per cart count.
    per_count: [f32; 2],
    half_rev: i32,
    rev: u32,
    tau: f32,
    track: f32,
    pump: Option<Pump>,
    /// Homing, if the start-up homes: under way, or the centre it found.
    home: Option<Home>,
    phase: Phase,
    zeroing: Zeroing,
    /// The counts at the cart's centre and the pole upright, once zeroed.
    zero: Option<(i32, i32)>,
    last: Option<(i32, i32)>,
    inside: u16,
    /// The zero's refinement so far, rad.
    trim: f32,
    transitions: Transitions,
}

impl Sequencer {
    /// The machine at power-on, zeroing, for `rig` run as `startup` says; refused as
    /// [`Startup::check`] and [`Rig::check`] refuse.
    pub fn new(startup: Startup, rig: &Rig) -> Result<Sequencer, ConfigError> {
        let rig = check!(rig.check());
        let startup = check!(startup.check(&rig));
        let [per_m, per_rad] = rig.encoders.per_count();
        let rev = rig.encoders.pole_counts_per_rev;
        let track = check!(rig.limits()).max_abs()[0];
        Ok(Sequencer {
            startup,
            per_count: [per_rad as f32, per_m as f32],
            half_rev: (rev / 2) as i32,
            rev,
            tau: rig.params.tau as f32,
            track,
            pump: startup.swing.map(|s| Pump::new(s, &rig.params, track)),
            home: startup
                .homing
                .map(|h| Home::new(h, &rig.params, f64::from(rig.encoders.cart_counts_per_m))),
            phase: match startup.homing {
                Some(_) => Phase::Homing,
                None => Phase::Zeroing,
            },
            zeroing: Zeroing::new(startup.zero_periods),
            zero: None,
            last: None,
            inside: 0,
            trim: 0.0,
            transitions: Transitions::default(),
        })
    }

    /// One period on the encoders' raw counts `(cart, pole)`: the phase moves on, and what
    /// the loop does is returned.
    pub fn period(&mut self, cart: i32, pole: i32) -> Act {
        let centre = match &mut self.home {
            Some(home) if home.arrived().is_none() => match home.period(cart) {
                Homed::Drive(command) => return Act::Hold(command),
                Homed::Centre(centre) => {
                    self.transitions.homed = self.transitions.homed.saturating_add(1);
                    self.phase = Phase::Zeroing;
                    Some(centre)
                }
            },
            home => home.as_ref().and_then(Home::arrived),
        };
        let Some(zero) = self.zero else {
            if let Some(hanging) = self.zeroing.count(pole) {
                let upright = hanging.wrapping_add(self.half_rev);
                self.zero = Some((centre.unwrap_or(cart), upright));
                self.transitions.zeroed = self.transitions.zeroed.saturating_add(1);
                self.phase = self.idle();
                self.last = Some((cart, pole));
            }
            return Act::Hold(Command::Coast);
        };
        let state = self.state(zero, (cart, pole));
        self.last = Some((cart, pole));
        self.advance(&state)
    }

    /// The phase after this period's state `s` (`[x, x_dot, theta, theta_dot]` from counts).
    fn advance(&mut self, s: &[f32; 4]) -> Act {
        let inside = libm::fabsf(s[2]) <= self.startup.catch_angle
            && libm::fabsf(s[3]) <= self.startup.catch_rate;
        match self.phase {
            Phase::Zeroing => self.phase = self.idle(),
            // Motor off until the pole is down: a pole let go at the track's end is still up,
            // and catching it again there would run the cart into the end stop.
            Phase::Fallen if libm::fabsf(s[2]) < core::f32::consts::FRAC_PI_2 => {
                return Act::Hold(Command::Coast);
            }
            Phase::Fallen => self.phase = self.idle(),
            Phase::Waiting | Phase::SwingingUp if inside => {
                self.transitions.entered = self.transitions.entered.saturating_add(1);
                self.inside = 0;
                self.phase = Phase::Catching;
            }
            Phase::Catching if !inside => {
                self.transitions.missed = self.transitions.missed.saturating_add(1);
                self.phase = self.idle();
            }
            Phase::Balancing => {
                if libm::fabsf(s[2]) > self.startup.release_angle || libm::fabsf(s[0]) > self.track
                {
                    self.transitions.fell = self.transitions.fell.saturating_add(1);
                    self.phase = Phase::Fallen;
                    return Act::Hold(Command::Coast);
                }
                let max = self.startup.trim_max;
                self.trim = (self.trim + self.startup.trim_rate * s[0] * self.tau).clamp(-max, max);
                return Act::Balance { engaged: false };
            }
            _ => {}
        }
        if self.phase == Phase::Catching {
            self.inside = self.inside.saturating_add(1);
            if self.inside >= self.startup.catch_periods {
                self.transitions.caught = self.transitions.caught.saturating_add(1);
                self.phase = Phase::Balancing;
                return Act::Balance { engaged: true };
            }
        }
        Act::Hold(match &self.pump {
            Some(pump) if self.phase != Phase::Waiting => pump.command(s),
            _ => Command::Coast,
        })
    }

    /// Where the machine goes when nothing holds the pole: swinging it up, or waiting.
    fn idle(&self) -> Phase {
        if self.pump.is_some() {
            Phase::SwingingUp
        } else {
            Phase::Waiting
        }
    }

    /// `[x, x_dot, theta, theta_dot]` from the counts about the zero, the angle in one
    /// revolution about upright and the rates from the last period's counts.
    fn state(&self, (cart0, upright): (i32, i32), (cart, pole): (i32, i32)) -> [f32; 4] {
        let angle = |c: i32| self.wrap(i64::from(c.wrapping_sub(upright)));
        let x = cart.wrapping_sub(cart0) as f32 * self.per_count[1];
        let (last_cart, last_pole) = self.last.unwrap_or((cart, pole));
        let dx = cart.wrapping_sub(last_cart) as f32 * self.per_count[1];
        let dtheta = self.wrap(i64::from(pole.wrapping_sub(last_pole)));
        [x, dx / self.tau, angle(pole), dtheta / self.tau]
    }

    /// Counts `c` as an angle within one revolution about zero (the estimator's wrap).
    fn wrap(&self, c: i64) -> f32 {
        wrap::count(c, self.rev) as f32 * self.per_count[0]
    }

    /// The phase this period ended in.
    pub fn phase(&self) -> Phase {
        self.phase
    }

    /// The transitions so far.
    pub fn transitions(&self) -> Transitions {
        self.transitions
    }

    /// The zero's refinement so far, rad ([`Startup::trim_rate`]): what the pole's reading
    /// is moved by.
    pub fn trim(&self) -> f32 {
        self.trim
    }

    /// The raw counts `(cart, pole)` of the cart's centre and the pole upright, once zeroed.
    pub fn zero(&self) -> Option<(i32, i32)> {
        self.zero
    }

    /// One period of a rig's loop on the raw counts `counts` (as the controller's sensor
    /// reads them this period): the phase moves on ([`Sequencer::period`]), then the
    /// controller holds the command or runs its own period. The period the zero is taken,
    /// the sensor is zeroed there ([`Zeroed::zero_at`]); the period of a catch, the
    /// controller is rearmed ([`Controller::rearm`]).
    pub fn run<P, S, A, const N: usize>(
        &mut self,
        counts: (i32, i32),
        controller: &mut Controller<P, S, A, N>,
    ) -> Command
    where
        P: Policy<S::Reading>,
        S: StateSensor + Zeroed,
        A: Actuator,
    {
        let zeroed = self.zero.is_some();
        let act = self.period(counts.0, counts.1);
        if let (false, Some(zero)) = (zeroed, self.zero) {
            controller.sensor_mut().zero_at(zero);
        }
        controller.sensor_mut().trim(self.trim);
        match act {
            Act::Hold(command) => controller.hold(command),
            Act::Balance { engaged } => {
                if engaged {
                    controller.rearm();
                }
                controller.step()
            }
        }
    }
}

#[cfg(test)]
mod tests;
