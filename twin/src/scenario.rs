//! The digital twin: the firmware's sensor and actuator traits implemented over the
//! simulated plant, and the loop that runs the unchanged [`Controller`] against it. The pins
//! are `firmware::loopback`'s, the same the microcontroller's self-test uses; the sensor adds
//! the scenario's noise.
//!
//! A period goes: the controller reads the twin's sensor (the true state, plus noise if the
//! scenario asks), decides and writes the twin's direction pin and duty cycle; the twin turns
//! those into a force (plus any push disturbance, minus one period if the actuator is
//! delayed) and steps the plant. Every random draw comes from a stream seeded by the episode,
//! so every controller meets the same starts, noise and pushes.

use std::cell::Cell;
use std::convert::Infallible;

use firmware::cartpole::{CartPole, Params, State, unit_f64};
use firmware::controller::{Command, Controller, Limits, Policy, StateSensor};
use firmware::loopback::{CellDuty, CellPin, force as bridge_force};
use rand_distr::{Distribution, StandardNormal};
use rand_pcg::Pcg64Mcg;

/// Sensor noise standard deviations of the `noise` scenario, per channel: 1 cm, 5 cm/s,
/// 0.3 degrees, 0.05 rad/s; a cheap encoder and a finite-difference velocity.
pub const NOISE_STD: [f64; 4] = [0.01, 0.05, 0.005, 0.05];

/// The range a physical quantity of a scenario may take, as a factor on its nominal value:
/// wide enough for any robustness study, narrow enough that the plant's arithmetic stays
/// finite.
pub const FACTOR_RANGE: (f64, f64) = (1e-3, 1e3);

/// Longest scenario spec accepted.
pub const MAX_SPEC_BYTES: usize = 1000;

/// A disturbance: an extra force of `impulse / tau` for one period, every `every` periods,
/// towards a random side.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Push {
    /// Size of each push, N*s.
    pub impulse: f64,
    /// Periods between pushes.
    pub every: u32,
}

/// The world one episode runs in: the plant's physics and what goes wrong around it.
#[derive(Clone, Debug, PartialEq)]
pub struct Scenario {
    /// Row label, the spec it was parsed from.
    pub name: String,
    /// The plant's physics (the controllers are not told).
    pub params: Params,
    /// Gaussian sensor noise, standard deviation per channel (zero: none).
    pub noise_std: [f64; 4],
    /// The actuator applies the previous period's command.
    pub delay: bool,
    /// Push disturbances.
    pub push: Option<Push>,
}

impl Scenario {
    /// The nominal plant, exact sensors, no delay, no pushes.
    pub fn nominal() -> Scenario {
        Scenario {
            name: "nominal".into(),
            params: Params::default(),
            noise_std: [0.0; 4],
            delay: false,
            push: None,
        }
    }

    /// Parses a spec: `nominal`, or parts joined by `+`, each one of `noise[=SCALE]` (times
    /// [`NOISE_STD`]), `delay`, `force=F`, `length=F`, `polemass=F`, `cartmass=F` (F
    /// multiplies the nominal value), `push[=IMPULSE[/EVERY]]` (default 0.5 N*s every 100
    /// periods). Factors of one quantity multiply; every resulting quantity must lie within
    /// [`FACTOR_RANGE`] of nominal, noise scales and impulses within `[0, 1000]`.
    pub fn parse(spec: &str) -> Result<Scenario, String> {
        let shown = weights::quote(spec);
        if spec.len() > MAX_SPEC_BYTES {
            return Err(format!(
                "scenario: expected at most {MAX_SPEC_BYTES} bytes, found {} ({shown})",
                spec.len()
            ));
        }
        let mut s = Scenario::nominal();
        s.name = spec.to_string();
        if spec == "nominal" {
            return Ok(s);
        }
        for part in spec.split('+') {
            let (key, value) = match part.split_once('=') {
                Some((k, v)) => (k, Some(v)),
                None => (part, None),
            };
            let number = |v: &str| -> Result<f64, String> {
                match v.parse::<f64>() {
                    Ok(x) if x.is_finite() && (0.0..=1000.0).contains(&x) => Ok(x),
                    _ => Err(format!(
                        "scenario {shown}: {key} needs a number in [0, 1000], found {}",
                        weights::quote(v)
                    )),
                }
            };
            let factor = || -> Result<f64, String> {
                value
                    .ok_or_else(|| {
                        format!("scenario {shown}: {key} needs a factor, e.g. {key}=1.2")
                    })
                    .and_then(number)
            };
            match key {
                "noise" => {
                    let scale = value.map(number).transpose()?.unwrap_or(1.0);
                    s.noise_std = NOISE_STD.map(|v| v * scale);
                }
                "delay" if value.is_none() => s.delay = true,
                "force" => s.params.force_mag *= factor()?,
                "length" => s.params.length *= factor()?,
                "polemass" => s.params.masspole *= factor()?,
                "cartmass" => s.params.masscart *= factor()?,
                "push" => {
                    let (impulse, every) = match value {
                        None => (0.5, 100),
                        Some(v) => match v.split_once('/') {
                            None => (number(v)?, 100),
                            Some((i, k)) => (
                                number(i)?,
                                k.parse::<u32>().ok().filter(|&k| k > 0).ok_or_else(|| {
                                    format!(
                                        "scenario {shown}: push interval must be a whole number \
                                         of periods >= 1, found {}",
                                        weights::quote(k)
                                    )
                                })?,
                            ),
                        },
                    };
                    s.push = Some(Push { impulse, every });
                }
                _ => {
                    return Err(format!(
                        "scenario {shown}: unknown part {} (expected nominal, noise[=S], delay, \
                         force=F, length=F, polemass=F, cartmass=F, push[=I[/K]])",
                        weights::quote(part)
                    ));
                }
            }
        }
        let nominal = Params::default();
        for (name, v, n) in [
            ("force", s.params.force_mag, nominal.force_mag),
            ("length", s.params.length, nominal.length),
            ("polemass", s.params.masspole, nominal.masspole),
            ("cartmass", s.params.masscart, nominal.masscart),
        ] {
            let f = v / n;
            if !(FACTOR_RANGE.0..=FACTOR_RANGE.1).contains(&f) {
                return Err(format!(
                    "scenario {shown}: {name} comes to {f:e} times nominal, expected a factor \
                     in [{}, {}] (factors of one quantity multiply)",
                    FACTOR_RANGE.0, FACTOR_RANGE.1
                ));
            }
        }
        Ok(s)
    }

    /// The robustness table's rows: nominal, each perturbation alone, and all three kinds of
    /// trouble at once.
    pub fn default_set() -> Vec<Scenario> {
        [
            "nominal",
            "noise",
            "delay",
            "force=0.8",
            "force=1.2",
            "length=0.8",
            "length=1.2",
            "polemass=0.8",
            "polemass=1.2",
            "cartmass=0.8",
            "cartmass=1.2",
            "push",
            "noise+delay+push",
        ]
        .iter()
        .map(|s| Scenario::parse(s).expect("built-in scenario specs parse"))
        .collect()
    }
}

/// The sensor: the twin's true state, rounded to f32 as the plant's observation is, plus
/// noise.
pub struct TwinSensor<'a> {
    state: &'a Cell<State>,
    noise_std: [f64; 4],
    rng: Pcg64Mcg,
}

impl StateSensor for TwinSensor<'_> {
    type Error = Infallible;

    #[inline]
    fn read(&mut self) -> Result<[f32; 4], Infallible> {
        let s = self.state.get();
        if self.noise_std == [0.0; 4] {
            return Ok(s.observation());
        }
        let mut obs = s.to_array();
        for (v, sd) in obs.iter_mut().zip(self.noise_std) {
            let z: f64 = StandardNormal.sample(&mut self.rng);
            *v += sd * z;
        }
        Ok(obs.map(|v| v as f32))
    }
}

/// What one episode did, summed over its periods.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EpisodeStats {
    /// Periods survived.
    pub steps: u32,
    /// Whether it ended by reaching the horizon rather than by a fall or leaving the track.
    pub success: bool,
    /// Sum of theta^2, rad^2.
    pub sum_theta2: f64,
    /// Sum of x^2, m^2.
    pub sum_x2: f64,
    /// Sum of |x|, m.
    pub sum_abs_x: f64,
    /// Periods whose command differs from the previous period's.
    pub switches: u32,
    /// Periods that coasted on a rejected reading.
    pub faults: u32,
}

/// One period of a recorded episode (for rendering).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// The true state after the period.
    pub state: State,
    /// The command the controller gave in the period.
    pub command: Command,
}

/// Independent seeded streams of one episode: the project's one mixer.
fn episode_rng(seed: u64, episode: u64, stream: u64) -> Pcg64Mcg {
    host_common::seed::rng(seed, episode, stream)
}

/// Seeded stream for a controller's own randomness (the random baseline) in `episode`.
pub fn policy_rng(seed: u64, episode: u64) -> Pcg64Mcg {
    episode_rng(seed, episode, 4)
}

/// Runs one episode of `policy` under `scenario` for at most `horizon` periods from the
/// Gymnasium-style random start of (`seed`, `episode`). `on_frame` sees every period.
#[inline(always)]
pub fn run_episode<P: Policy>(
    policy: P,
    scenario: &Scenario,
    horizon: u32,
    seed: u64,
    episode: u64,
    mut on_frame: impl FnMut(Frame),
) -> EpisodeStats {
    let mut plant = CartPole::new(scenario.params, horizon);
    plant.reset(&mut episode_rng(seed, episode, 1));
    let state = Cell::new(plant.state());
    let direction = Cell::new(false);
    let duty = Cell::new(0u16);
    let sensor = TwinSensor {
        state: &state,
        noise_std: scenario.noise_std,
        rng: episode_rng(seed, episode, 2),
    };
    let mut pushes = episode_rng(seed, episode, 3);
    let mut controller: Controller<_, _, _, _, 1> = Controller::new(
        policy,
        sensor,
        CellPin(&direction),
        CellDuty(&duty),
        Limits::default(),
    );
    let force_mag = scenario.params.force_mag;
    let mut stats = EpisodeStats::default();
    let mut previous: Option<Command> = None;
    let mut pending = 0.0;
    loop {
        let command = controller.step();
        if previous.is_some_and(|p| p != command) {
            stats.switches += 1;
        }
        if command == Command::Coast {
            stats.faults += 1;
        }
        previous = Some(command);
        let commanded = bridge_force(direction.get(), duty.get(), force_mag);
        let mut force = if scenario.delay {
            std::mem::replace(&mut pending, commanded)
        } else {
            commanded
        };
        if let Some(push) = scenario.push
            && (plant.steps() + 1).is_multiple_of(push.every)
        {
            let side = if unit_f64(&mut pushes) < 0.5 {
                -1.0
            } else {
                1.0
            };
            force += side * push.impulse / scenario.params.tau;
        }
        let t = plant.step_force(force);
        let s = plant.state();
        state.set(s);
        stats.steps += 1;
        stats.sum_theta2 += s.theta * s.theta;
        stats.sum_x2 += s.x * s.x;
        stats.sum_abs_x += s.x.abs();
        on_frame(Frame { state: s, command });
        if t.terminated || t.truncated {
            stats.success = !t.terminated;
            return stats;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::baselines::{AngleRule, Lqr};
    use firmware::cartpole::step;
    use firmware::policy::POLICY;

    #[test]
    fn nominal_twin_is_the_plant_under_the_policy_bit_for_bit() {
        // The same episode, by hand: plant.step(greedy action) from the same start.
        for episode in 0..20 {
            let mut frames = Vec::new();
            let stats = run_episode(&POLICY, &Scenario::nominal(), 500, 7, episode, |f| {
                frames.push(f)
            });
            let mut plant = CartPole::new(Params::default(), 500);
            let mut obs = plant.reset(&mut episode_rng(7, episode, 1));
            for f in &frames {
                let action = POLICY.greedy_action(&obs);
                assert_eq!(f.command, Command::Push(action));
                let t = plant.step(action);
                obs = t.obs;
                assert_eq!(plant.state(), f.state);
            }
            assert_eq!(stats.steps as usize, frames.len());
        }
    }

    #[test]
    fn delay_applies_the_previous_command() {
        let delayed = Scenario::parse("delay").unwrap();
        let mut frames = Vec::new();
        run_episode(AngleRule, &delayed, 50, 3, 0, |f| frames.push(f));
        let p = Params::default();
        let mut s = State::from_array({
            let mut plant = CartPole::new(p, 50);
            plant.reset(&mut episode_rng(3, 0, 1));
            plant.state().to_array()
        });
        // The first period applies no force; then each applies its predecessor's command.
        s = firmware::cartpole::step_with_force(&p, &s, 0.0);
        assert_eq!(frames[0].state, s);
        for w in frames.windows(2) {
            let Command::Push(a) = w[0].command else {
                panic!("exact sensors never coast")
            };
            s = step(&p, &s, a);
            assert_eq!(w[1].state, s);
        }
    }

    #[test]
    fn perturbed_physics_and_pushes_change_the_plant() {
        let s = Scenario::parse("force=1.2+length=0.8+polemass=1.2+cartmass=0.8").unwrap();
        let d = Params::default();
        assert_eq!(s.params.force_mag, d.force_mag * 1.2);
        assert_eq!(s.params.length, d.length * 0.8);
        assert_eq!(s.params.masspole, d.masspole * 1.2);
        assert_eq!(s.params.masscart, d.masscart * 0.8);
        assert_eq!(
            Scenario::parse("push=0.3/40").unwrap().push,
            Some(Push {
                impulse: 0.3,
                every: 40
            })
        );
        // A 0.5 N s push every period overwhelms the 10 N motor: the pole falls quickly.
        let brutal = Scenario::parse("push=0.5/1").unwrap();
        let st = run_episode(Lqr::nominal(), &brutal, 500, 1, 0, |_| {});
        let calm = run_episode(Lqr::nominal(), &Scenario::nominal(), 500, 1, 0, |_| {});
        assert!(st.steps < 100 && calm.success, "{st:?} {calm:?}");
    }

    #[test]
    fn bad_specs_are_rejected_with_the_reason() {
        for (spec, needle) in [
            ("wind", "unknown part"),
            ("force", "needs a factor"),
            ("force=-1", "needs a number in [0, 1000], found \"-1\""),
            ("push=0.5/0", "whole number of periods >= 1"),
            ("noise=x", "needs a number in [0, 1000]"),
            ("force=0", "force comes to 0e0 times nominal"),
            // One quantity's factors multiply: each is fine, their product is not.
            ("length=999+length=999", "length comes to 9.98"),
            (
                "length=1e300+length=1e300",
                "needs a number in [0, 1000], found \"1e300\"",
            ),
            ("push=1e9", "needs a number in [0, 1000]"),
        ] {
            let e = Scenario::parse(spec).unwrap_err();
            assert!(e.contains(needle), "{spec}: {e}");
        }
        let long = "noise+".repeat(10_000);
        let e = Scenario::parse(&long).unwrap_err();
        assert!(
            e.contains("expected at most 1000 bytes") && e.len() < 400,
            "{e}"
        );
    }

    #[test]
    fn noise_is_seeded_and_reaches_the_controller() {
        let noisy = Scenario::parse("noise=4").unwrap();
        let run = |seed| {
            let mut v = Vec::new();
            run_episode(&POLICY, &noisy, 300, seed, 0, |f| v.push(f));
            v
        };
        assert_eq!(run(5), run(5));
        let mut exact = Vec::new();
        run_episode(&POLICY, &Scenario::nominal(), 300, 5, 0, |f| exact.push(f));
        assert_ne!(run(5), exact);
    }
}
