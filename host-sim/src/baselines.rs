//! Reference controllers to put the learned policy in context: discrete LQR, a hand-written
//! angle rule and coin flips.
//!
//! Each is a [`Policy`], so it runs through the very same [`Controller`] (sanitising,
//! pin sequence, telemetry) as the network; only the scores differ. [`Lqr`] acts by the
//! sign of its continuous command `u = -K s` (push right when `u > 0`), as the paper's
//! two-level actuator must; [`LinearLqr`] drives `u` itself, as a duty the bridge's PWM gives
//! in thousandths: what a control engineer would run on the rig.
//!
//! [`Controller`]: firmware::controller::Controller

use std::cell::RefCell;

use firmware::cartpole::{Params, unit_f64};
use firmware::controller::{Duty, Levels, Policy, Scores, nearest};
use firmware::linear::{Vec4, balance_gain, dot};
use firmware::rig::Rig;
use rand_pcg::Pcg64Mcg;

/// Bang-bang LQR: push right when `-K s > 0`. `K` comes from [`balance_gain`] with the rig's
/// parameters, the model its board knows (not a scenario's perturbed physics).
#[derive(Clone, Copy, Debug)]
pub struct Lqr {
    /// The gain, `u = -K s`.
    pub k: Vec4,
}

thread_local! {
    /// The last rig's gain: a table's episodes ask for one rig's thousands of times.
    static LAST: RefCell<Option<(Params, Vec4)>> = const { RefCell::new(None) };
}

impl Lqr {
    /// `Q = I`, `R = 1` on `rig`'s plant.
    pub fn of(rig: &Rig) -> Lqr {
        let p = rig.params;
        let k = LAST.with_borrow_mut(|last| match last {
            Some((q, k)) if *q == p => *k,
            _ => {
                let k = balance_gain(&p);
                *last = Some((p, k));
                k
            }
        });
        Lqr { k }
    }
}

impl Policy for Lqr {
    type Scores = [f32; 2];
    fn duty(&self, i: usize) -> Option<Duty> {
        Levels::BANG_BANG.duty(i)
    }
    fn scores(&mut self, obs: &[f32; 4]) -> [f32; 2] {
        let s = obs.map(f64::from);
        [0.0, -dot(&self.k, &s) as f32]
    }
}

/// Linear LQR: the duty `-K s / force_mag` (the gain of [`Lqr`], its force in newtons as a
/// fraction of the motor's stall force), saturated at full duty and rounded to the
/// thousandths the bridge's PWM gives.
#[derive(Clone, Copy, Debug)]
pub struct LinearLqr {
    /// The gain, `F = -K s` in newtons.
    pub k: Vec4,
    /// The motor's stall force, N: what full duty pushes with.
    pub force_mag: f64,
}

impl LinearLqr {
    /// `Q = I`, `R = 1` on `rig`'s plant, as [`Lqr::of`].
    pub fn of(rig: &Rig) -> LinearLqr {
        LinearLqr {
            k: Lqr::of(rig).k,
            force_mag: rig.params.force_mag,
        }
    }
}

/// A linear controller's command, a fraction of the full push (any number; saturated when
/// it becomes a duty).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Push(pub f32);

/// Output `i` of a linear controller drives `i - 1000` thousandths of the full push.
const CENTRE: usize = Duty::FULL as usize;

impl Scores for Push {
    const UNSCORED: Push = Push(f32::NAN);
    fn choice(&self) -> Option<usize> {
        let t = (self.0.clamp(-1.0, 1.0) * f32::from(Duty::FULL)).round();
        self.0
            .is_finite()
            .then_some((t as i32 + CENTRE as i32) as usize)
    }
}

impl Policy for LinearLqr {
    type Scores = Push;
    fn duty(&self, i: usize) -> Option<Duty> {
        let t = (i <= 2 * CENTRE).then_some(i)? as f32 - CENTRE as f32;
        Duty::from_fraction(t / f32::from(Duty::FULL)).ok()
    }
    fn scores(&mut self, obs: &[f32; 4]) -> Push {
        let s = obs.map(f64::from);
        Push((-dot(&self.k, &s) / self.force_mag) as f32)
    }
}

/// [`LinearLqr`]'s command rounded to the nearest of `levels` ([`nearest`], the lower of two
/// equally near, as the monitor's fallback rounds): the linear controller held to the
/// duties a policy of those levels may choose, so that a table shows what the levels
/// themselves cost beside what the learning does.
#[derive(Clone, Debug)]
pub struct RoundedLqr {
    lqr: LinearLqr,
    levels: Vec<Duty>,
}

impl RoundedLqr {
    /// [`LinearLqr::of`] `rig`, rounded to `levels` (in increasing order, as a policy's are).
    pub fn of(rig: &Rig, levels: &[Duty]) -> RoundedLqr {
        RoundedLqr {
            lqr: LinearLqr::of(rig),
            levels: levels.to_vec(),
        }
    }
}

impl Policy for RoundedLqr {
    type Scores = Push;
    fn duty(&self, i: usize) -> Option<Duty> {
        self.lqr.duty(i)
    }
    fn scores(&mut self, obs: &[f32; 4]) -> Push {
        let Push(u) = self.lqr.scores(obs);
        let level = nearest(|i| self.levels.get(i).copied(), u, 1.0);
        let duty = level.and_then(|i| self.levels.get(i)).map(|d| d.fraction());
        Push(duty.filter(|_| !u.is_nan()).unwrap_or(f32::NAN))
    }
}

/// The classic hand rule: push towards where the pole is falling, `theta + 0.5 theta_dot`.
#[derive(Clone, Copy, Debug, Default)]
pub struct AngleRule;

impl Policy for AngleRule {
    type Scores = [f32; 2];
    fn duty(&self, i: usize) -> Option<Duty> {
        Levels::BANG_BANG.duty(i)
    }
    fn scores(&mut self, obs: &[f32; 4]) -> [f32; 2] {
        [0.0, obs[2] + 0.5 * obs[3]]
    }
}

/// Left or right with equal probability, from a seeded stream.
#[derive(Clone, Debug)]
pub struct Random(pub Pcg64Mcg);

impl Policy for Random {
    type Scores = [f32; 2];
    fn duty(&self, i: usize) -> Option<Duty> {
        Levels::BANG_BANG.duty(i)
    }
    fn scores(&mut self, _obs: &[f32; 4]) -> [f32; 2] {
        [0.5, unit_f64(&mut self.0) as f32]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rules_push_towards_the_fall() {
        let lean_right = [0.0, 0.0, 0.05, 0.1];
        let lean_left = lean_right.map(|v: f32| -v);
        let mut lqr = Lqr::of(&Rig::GYMNASIUM);
        assert!(lqr.scores(&lean_right)[1] > 0.0);
        let mut linear = LinearLqr::of(&Rig::GYMNASIUM);
        assert!(linear.scores(&lean_right).0 > 0.0);
        assert!(linear.scores(&lean_left).0 < 0.0);
        assert!(lqr.scores(&lean_left)[1] < 0.0);
        assert!(AngleRule.scores(&lean_right)[1] > 0.0);
        assert!(AngleRule.scores(&lean_left)[1] < 0.0);
        assert_eq!(
            AngleRule.scores(&[0.0, 0.0, 0.1, -0.3])[1],
            0.1 + 0.5 * -0.3
        );
    }

    #[test]
    fn the_linear_lqr_drives_its_command_in_thousandths_saturated() {
        let lqr = LinearLqr {
            k: [0.0, 0.0, -100.0, 0.0],
            force_mag: 10.0,
        };
        // theta = 0.01: F = 1 N, a tenth of the stall force.
        let duty = |theta: f32| {
            let mut l = lqr;
            let i = l.scores(&[0.0, 0.0, theta, 0.0]).choice().unwrap();
            l.duty(i).unwrap().thousandths()
        };
        assert_eq!(duty(0.01), 100);
        assert_eq!(duty(-0.0123), -123);
        assert_eq!(duty(0.0), 0);
        assert_eq!(duty(0.5), 1000);
        assert_eq!(duty(-0.5), -1000);
        assert_eq!(Push(f32::NAN).choice(), None);
        assert_eq!(lqr.duty(2 * CENTRE + 1), None);
    }

    #[test]
    fn the_rounded_lqr_drives_the_nearest_level() {
        let levels =
            [-1.0, -0.4, -0.05, 0.0, 0.05, 0.4, 1.0].map(|f| Duty::from_fraction(f).unwrap());
        let mut lqr = RoundedLqr {
            lqr: LinearLqr {
                k: [0.0, 0.0, -100.0, 0.0],
                force_mag: 10.0,
            },
            levels: levels.to_vec(),
        };
        // The command is theta x 10 as a fraction of the full push (the test above); each
        // expected level picked by hand from the list.
        for (theta, want) in [
            (0.0, 0),
            (0.002, 0),
            (0.003, 50),
            (-0.004, -50),
            (0.02, 50),
            (0.023, 400),
            (0.07, 400),
            (0.071, 1000),
            (0.5, 1000),
            (-0.5, -1000),
            (f32::INFINITY, 1000),
        ] {
            let i = lqr.scores(&[0.0, 0.0, theta, 0.0]).choice().unwrap();
            assert_eq!(lqr.duty(i).unwrap().thousandths(), want, "theta {theta}");
        }
        assert_eq!(lqr.scores(&[0.0, 0.0, f32::NAN, 0.0]).choice(), None);
        // An exact tie: a gain of force_mag makes the command theta itself, so +-0.5 lies
        // exactly halfway between two levels, and the lower one is driven.
        let mut tied = RoundedLqr {
            lqr: LinearLqr {
                k: [0.0, 0.0, -10.0, 0.0],
                force_mag: 10.0,
            },
            levels: vec![Duty::LEFT, Duty::OFF, Duty::RIGHT],
        };
        for (theta, want) in [(0.5, 0), (-0.5, -1000), (0.5000001, 1000)] {
            let i = tied.scores(&[0.0, 0.0, theta, 0.0]).choice().unwrap();
            assert_eq!(tied.duty(i).unwrap().thousandths(), want, "theta {theta}");
        }
    }
}
