//! Episodes from power-on: the pole hanging (or lifted by a hand) and the board's start-up
//! ([`firmware::startup`]) taking it to balance, on a machine's continuous world through its
//! encoders and dead time, the cart stopped by the track's end stops.
//!
//! The board counts from zero at power-on, wherever the cart and pole are: its zero is the
//! start-up's to find. An end stop is inelastic: the cart stops against it (its speed goes
//! to zero, the pole's motion is left as it was) and the contact is counted.

use core::cell::Cell;

use firmware::ConfigError;
use firmware::cartpole::{Plant, State, unit_f64};
use firmware::controller::predict::DeadTime;
use firmware::controller::{FaultCounters, Policy};
use firmware::estimator::{Estimate, ObserverSensor};
use firmware::loopback::{duty, pins};
use firmware::rig::{Options, Rig};
use firmware::startup::{Phase, Sequencer, Startup, Transitions};
use rand_core::Rng;

use crate::machine::{self, Integration, Machine};
use crate::run::Frame;

/// A hand lifting the pole from where it hangs along a smooth path, and letting go. The
/// hand steadies the cart while it lifts: the cart stays where it was taken, at rest.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lift {
    /// The period the hand takes the pole.
    pub from: u32,
    /// Periods it takes to lift it.
    pub periods: u32,
    /// Where it lets go: the angle from upright (rad) and the pole's rate then (rad/s).
    pub release: (f64, f64),
}

impl Lift {
    /// The pole's angle and rate `k` periods into the lift from `start` (the angle it was
    /// taken at): a half cosine in the angle, from rest, arriving at the release rate by a
    /// last stretch of constant rate.
    fn at(&self, start: f64, k: u32, tau: f64) -> (f64, f64) {
        let (to, rate) = self.release;
        let t = f64::from(self.periods) * tau;
        // The release angle less the stretch the release rate covers in a tenth of the lift.
        let tail = rate * t / 10.0;
        let goal = nearest_turn(start, to - tail);
        let u = (f64::from(k) * tau / (0.9 * t)).min(1.0);
        if u < 1.0 {
            let w = 0.5 - 0.5 * (std::f64::consts::PI * u).cos();
            let dw = 0.5 * std::f64::consts::PI * (std::f64::consts::PI * u).sin() / (0.9 * t);
            (start + (goal - start) * w, (goal - start) * dw)
        } else {
            (goal + rate * (f64::from(k) * tau - 0.9 * t), rate)
        }
    }
}

/// `angle` moved by whole turns to the one nearest `near`.
fn nearest_turn(near: f64, angle: f64) -> f64 {
    let turn = std::f64::consts::TAU;
    angle + turn * ((near - angle) / turn).round()
}

/// How an episode from power-on begins.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Begin {
    /// The pole hanging nearly at rest: within 0.02 rad and 0.05 rad/s of it, the cart
    /// within a centimetre of the centre.
    Hanging,
    /// The pole swinging by up to 30 degrees.
    Swinging,
    /// Hanging nearly at rest, then lifted by a hand (from 5 to 7 s, over 0.5 to 2 s) into
    /// the catch region (0.8 of its angle, half its rate) and let go.
    Lifted,
}

impl Begin {
    /// A start of this kind drawn from `rng`, for a rig run at `tau` seconds a period and
    /// started by `startup`: the state at power-on, and the lift.
    pub fn draw(self, rng: &mut impl Rng, startup: &Startup, tau: f64) -> (State, Option<Lift>) {
        let state = self.state(rng);
        let mut u = || 2.0 * unit_f64(rng) - 1.0;
        let lift = (self == Begin::Lifted).then(|| {
            let seconds = |s: f64| (s / tau).round() as u32;
            Lift {
                from: seconds(6.0 + u()),
                periods: seconds(1.25 + 0.75 * u()),
                release: (
                    0.8 * f64::from(startup.catch_angle) * u(),
                    0.5 * f64::from(startup.catch_rate) * u(),
                ),
            }
        });
        (state, lift)
    }

    /// The state at power-on of a start of this kind drawn from `rng` (the first draws of
    /// [`Begin::draw`]).
    pub fn state(self, rng: &mut impl Rng) -> State {
        let mut u = || 2.0 * unit_f64(rng) - 1.0;
        let swing = match self {
            Begin::Swinging => 30f64.to_radians(),
            Begin::Hanging | Begin::Lifted => 0.02,
        };
        let (x, theta, theta_dot) = (0.01 * u(), std::f64::consts::PI + swing * u(), 0.05 * u());
        State::from_array([x, 0.0, theta, theta_dot])
    }
}

impl Lift {
    /// The hand's hold on `s` after period `period`: it takes the pole as it is in period
    /// `from` (kept in `grip`), then sets its angle and rate on the path and keeps the cart
    /// where it was, at rest.
    fn hold(&self, period: u32, s: &mut State, grip: &mut State, tau: f64) {
        match period.checked_sub(self.from) {
            Some(0) => *grip = *s,
            Some(k) if k <= self.periods => {
                (s.theta, s.theta_dot) = self.at(grip.theta, k, tau);
                (s.x, s.x_dot) = (grip.x, 0.0);
            }
            _ => {}
        }
    }
}

/// An external push on the cart: its force (N) held over one period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Knock {
    /// The period it acts over.
    pub period: u32,
    /// Its force, N (positive towards +x).
    pub force: f64,
}

/// What an episode from power-on came to.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Outcome {
    /// The first period of the balance that lasted to the end, if one did.
    pub balanced_from: Option<u32>,
    /// The start-up's upright zero less the true one, in pole counts, once taken.
    pub zero_error: Option<i64>,
    /// The start-up's cart zero (the homed centre, or where the cart stood) less the true
    /// centre, in cart counts, once taken.
    pub centre_error: Option<i64>,
    /// The largest distance of the cart from the centre, m, homing aside.
    pub max_abs_x: f64,
    /// The largest distance of the cart from the centre while the start-up drove it, m.
    pub max_abs_x_swinging: f64,
    /// Periods the cart spent against an end stop, homing aside.
    pub end_stop_periods: u32,
    /// The start-up's transitions.
    pub transitions: Transitions,
    /// The balance controller's faults.
    pub faults: FaultCounters,
    /// The phase the episode ended in.
    pub phase: Phase,
    /// The balance over the episode's second half, if it balanced then.
    pub steady: Option<Steady>,
}

impl Outcome {
    /// Period `period` begun in `phase` with the cart at `x`.
    fn began(&mut self, period: u32, phase: Phase, x: f64) {
        if phase != Phase::Balancing {
            self.balanced_from = None;
            self.max_abs_x_swinging = self.max_abs_x_swinging.max(x.abs());
        } else if self.balanced_from.is_none() {
            self.balanced_from = Some(period);
        }
    }

    /// A period run in `phase` ended with the cart at `x`, `stopped` at an end stop: homing
    /// drives it there on purpose.
    fn ended(&mut self, phase: Phase, x: f64, stopped: bool) {
        if phase != Phase::Homing {
            self.end_stop_periods += u32::from(stopped);
            self.max_abs_x = self.max_abs_x.max(x.abs());
        }
    }
}

/// The balance at rest: the periods of an episode's second half that the balance
/// controller drove, as a rig runs once it has settled.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Steady {
    /// The cart's RMS distance from the centre, m.
    pub rms_x: f64,
    /// The mean |duty|, a fraction of full.
    pub mean_abs_duty: f64,
}

/// Sums over the second half's balanced periods: `[x^2, |duty|, periods]`.
#[derive(Default)]
struct Sums([f64; 3]);

impl Sums {
    fn add(&mut self, x: f64, duty: f64) {
        self.0[0] += x * x;
        self.0[1] += duty.abs();
        self.0[2] += 1.0;
    }
    fn steady(&self) -> Option<Steady> {
        let [x2, duty, n] = self.0;
        (n > 0.0).then(|| Steady {
            rms_x: (x2 / n).sqrt(),
            mean_abs_duty: duty / n,
        })
    }
}

/// What happens to an episode from power-on: how long it runs, a hand's lift, pushes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Events<'a> {
    /// Periods run.
    pub periods: u32,
    /// A hand lifting the pole, if one does.
    pub lift: Option<Lift>,
    /// Pushes on the cart.
    pub knocks: &'a [Knock],
    /// Pole counts the board reads off from the period after it took its zero on: a zero
    /// that gravity did not give exactly (an encoder that slipped on its shaft, a bent
    /// mount). 0 for none.
    pub zero_off: i32,
}

/// Runs `events.periods` of `world`'s true physics from `start`, read through its encoders,
/// its board (`board`, the rig it was told: `policy` behind the observer and predictor, on
/// readings in the format `O`, f32 or the integer network's Q3.12) started by `startup`.
/// `each` is shown every period's frame (the true state after it and the command; no
/// reading) and the phase it ran in.
pub fn power_on<O: Estimate, P: Policy<O>>(
    world: &Machine,
    board: &Rig,
    startup: Startup,
    (policy, start): (P, State),
    events: Events<'_>,
    mut each: impl FnMut(&Frame, Phase),
) -> Result<Outcome, ConfigError> {
    let (rig, truth) = (board, world.rig);
    let counts = |s: &State| truth.encoders.counts(s.x, s.theta);
    let origin = counts(&start);
    let latest = Cell::new((0, 0));
    let sensor = ObserverSensor::<_, O>::new(rig.observer()?, || latest.get());
    let options = Options {
        predict: true,
        monitor: None,
    };
    let mut controller = rig.controller(policy, sensor, pins(), options)?;
    let mut sequencer = Sequencer::new(startup, rig)?;
    let mut circle = FullCircle::new(world, start);
    let mut out = Outcome {
        balanced_from: None,
        zero_error: None,
        centre_error: None,
        max_abs_x: 0.0,
        max_abs_x_swinging: 0.0,
        end_stop_periods: 0,
        transitions: Transitions::default(),
        faults: FaultCounters::default(),
        phase: Phase::Zeroing,
        steady: None,
    };
    let mut sums = Sums::default();
    let mut grip = start;
    for period in 0..events.periods {
        let command = sequencer.run(latest.get(), &mut controller);
        let phase = sequencer.phase();
        out.began(period, phase, circle.state().x);
        let commanded = duty(controller.actuator());
        if phase == Phase::Balancing && period >= events.periods / 2 {
            sums.add(circle.state().x, commanded);
        }
        let stopped = circle.step(commanded, events.push(period), |s| {
            if let Some(lift) = &events.lift {
                lift.hold(period, s, &mut grip, truth.params.tau);
            }
        });
        let s = circle.state();
        out.ended(phase, s.x, stopped);
        let reading = [0.0; 4];
        each(
            &Frame {
                state: s,
                command,
                reading,
            },
            phase,
        );
        // The board's counter started at `origin`; the pole's zero is read off once taken.
        let (cart, pole) = counts(&s);
        let off = sequencer.zero().map_or(0, |_| events.zero_off);
        latest.set((
            cart.wrapping_sub(origin.0),
            pole.wrapping_sub(origin.1).wrapping_add(off),
        ));
    }
    (out.zero_error, out.centre_error) = zero_errors(sequencer.zero(), origin, &truth);
    out.transitions = sequencer.transitions();
    out.faults = controller.faults();
    out.phase = sequencer.phase();
    out.steady = sums.steady();
    Ok(out)
}

impl Events<'_> {
    /// The knocks' force in period `period`, N.
    fn push(&self, period: u32) -> f64 {
        let now = self.knocks.iter().filter(|k| k.period == period);
        now.map(|k| k.force).sum()
    }
}

/// A machine's true world over the full circle, as an episode from power-on runs it: its
/// physics, the dead time between a command and the motor, and the track's end stops (see
/// [the module](self)).
#[derive(Clone, Debug)]
pub struct FullCircle {
    plant: Plant<f64>,
    integration: Integration,
    end: f64,
    line: DeadTime<f64>,
    state: State,
}

impl FullCircle {
    /// `world`'s physics from `start`, the motor off until a command has crossed the dead time.
    pub fn new(world: &Machine, start: State) -> FullCircle {
        let truth = &world.rig;
        FullCircle {
            plant: Plant::new(&truth.params),
            integration: world.integration,
            end: truth.params.x_threshold,
            line: DeadTime::new(truth.dead_time as usize),
            state: start,
        }
    }

    /// The true state.
    pub fn state(&self) -> State {
        self.state
    }

    /// One period: `duty` sent to the motor (the command of the dead time ago acts), a
    /// force of `push` N on the cart, then `hold` (a hand on the pole, if one is) and the end
    /// stops. Whether the cart ended the period against one.
    pub fn step(&mut self, duty: f64, push: f64, hold: impl FnOnce(&mut State)) -> bool {
        let acting = self.line.send(duty);
        self.state = machine::advance(&self.plant, self.integration, &self.state, acting, push);
        hold(&mut self.state);
        stopped_at_ends(&mut self.state, self.end)
    }
}

/// Whether the cart in `s` is at an end stop `end` from the centre; one stops it there.
fn stopped_at_ends(s: &mut State, end: f64) -> bool {
    let at = s.x.abs() >= end;
    if at {
        s.x = s.x.clamp(-end, end);
        s.x_dot = 0.0;
    }
    at
}

/// The errors of the start-up's zero `zero` (raw counts of the cart's centre and the pole
/// upright, the board's counter started at `origin` of `truth`'s encoders): pole counts off
/// upright, and cart counts off the centre.
fn zero_errors(
    zero: Option<(i32, i32)>,
    origin: (i32, i32),
    truth: &Rig,
) -> (Option<i64>, Option<i64>) {
    let Some((cart0, upright)) = zero else {
        return (None, None);
    };
    let upright_true = i64::from(origin.1.wrapping_neg());
    let pole = wrapped(
        i64::from(upright) - upright_true,
        truth.encoders.pole_counts_per_rev,
    );
    let centre_true = truth.encoders.counts(0.0, 0.0).0.wrapping_sub(origin.0);
    (Some(pole), Some(i64::from(cart0.wrapping_sub(centre_true))))
}

/// `c` counts moved by whole revolutions of `rev` counts to the nearest zero.
fn wrapped(c: i64, rev: u32) -> i64 {
    let rev = i64::from(rev);
    (c + rev / 2).rem_euclid(rev) - rev / 2
}
