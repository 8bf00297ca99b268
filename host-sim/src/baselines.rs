//! Reference controllers to put the learned policy in context: discrete LQR, a hand-written
//! angle rule and coin flips.
//!
//! Each is a [`Policy`], so it runs through the very same [`Controller`] (sanitising,
//! pin sequence, telemetry) as the network; only the scores differ. The plant's actuator is
//! bang-bang, so LQR acts by the sign of its continuous command `u = -K s`: push right when
//! `u > 0`.
//!
//! [`Controller`]: firmware::controller::Controller

use std::cell::RefCell;

use firmware::cartpole::{Params, unit_f64};
use firmware::controller::{Duty, Levels, Policy};
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
        assert!(lqr.scores(&lean_left)[1] < 0.0);
        assert!(AngleRule.scores(&lean_right)[1] > 0.0);
        assert!(AngleRule.scores(&lean_left)[1] < 0.0);
        assert_eq!(
            AngleRule.scores(&[0.0, 0.0, 0.1, -0.3])[1],
            0.1 + 0.5 * -0.3
        );
    }
}
