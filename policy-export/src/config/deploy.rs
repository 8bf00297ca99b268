//! The deploy preset's worlds, on any machine: what it trains, selects and tries its
//! finalists in; and, for a rig, how it drives the motor.

use super::Config;

/// The duty levels the recipe trains for a rig: fine steps near zero, where a balanced pole
/// needs only small corrections, and full duty kept for pushes. With two levels a policy
/// can only balance by full pushes reversed every few periods (`docs/RIGS.md`).
pub const RIG_LEVELS: &str = "-1,-0.4,-0.15,-0.05,0,0.05,0.15,0.4,1";

/// What the recipe's learner pays for driving a rig's motor (`reward::Reward`), beside the
/// pole's lean and the cart's distance: the duty squared and its change from the previous
/// period, priced for a rig run `rate` times as fast as Gymnasium's 50 Hz. Every other part
/// is paid each period, so it adds up `rate` times as often in a second; a change of duty is
/// paid once however many periods it is spread over, so its weight grows by `rate` to keep
/// its price beside the others: `effort=1+smooth=20` at 50 Hz, `smooth=40` at 100 Hz.
/// Priced at 2, the seeds' snapshots reversed the motor up to 9 times a second; at 10, the
/// desk policy let its cart drift into the end stops after a swing-up (`docs/RIGS.md`).
pub fn rig_effort(rate: f64) -> String {
    format!("effort=1+smooth={}", 20.0 * rate)
}

/// The plant's physics a deploy domain draws: the pole's length and mass, the cart's mass
/// and the motor's stall force (and its damping, on a machine that has some) each within
/// `1 +- width` of the machine's, or wider where identification left a value more uncertain
/// than that ([`twin::machine::Uncertainty`]).
fn physics(width: f64, machine: &twin::Machine) -> String {
    let u = &machine.uncertainty;
    let range = |key: &str, u: f64| {
        let w = width.max(u);
        format!("{key}={}..{}", 1.0 - w, 1.0 + w)
    };
    let mut s = [
        range("length", u.pole_com),
        range("polemass", 0.0),
        range("cartmass", 0.0),
        range("force", u.stall_force),
    ]
    .join("+");
    if machine.rig.params.motor_damping > 0.0 {
        s = s + "+" + &range("damping", u.damping);
    }
    s
}

/// The worlds the deploy preset trains in, but for the pushes ([`Config::deploy_on`] adds
/// them: on Gymnasium's machine 0.8 to 1.2 N s every second, where the default set has
/// 0.5 N s every two): physics, noise and dead time wider than the default evaluation set's
/// +-20%, noise 1 and one period; friction, and encoders read through the observer.
pub fn deploy_domain(machine: &twin::Machine) -> String {
    physics(0.25, machine)
        + "+friction=0..0.1/0..0.002@0.3+noise=0..1.2@0.3+encoder=256..8192@0.3+jitter=0..0.1@0.3\
           +delay=0..4@0.5"
}

/// The worlds its snapshots are chosen on, like the default evaluation set's (with its push,
/// in half of them), read through the rig's own encoders and observer as its board reads
/// them: a snapshot that holds only on the exact state is not the one to ship.
pub fn deploy_eval_domain(machine: &twin::Machine) -> String {
    physics(0.25, machine) + "+noise=0..1@0.5+delay=0..1+encoder"
}

/// The worlds its finalists are tried in for 10,000 steps, but for the pushes
/// ([`Config::deploy_on`] adds them): plants drawn like the default set's, half of them with
/// its noise, through the rig's encoders.
pub fn deploy_finalist_domain(machine: &twin::Machine) -> String {
    physics(0.2, machine) + "+noise=0..1@0.5+encoder"
}

impl Config {
    /// The shipped recipe for `machine`: the same worlds around its rig (physics drawn at
    /// least as wide as its identification's intervals, and its motor's damping too), with
    /// the pushes scaled to its motor (a push that takes Gymnasium's motor five periods to
    /// answer takes this motor as long in seconds) and every count of periods to its control
    /// rate (the same seconds of pushes and episodes); on a rig, nine duty levels and a
    /// learner that pays for the motor's effort ([`RIG_LEVELS`], [`rig_effort`]), where
    /// Gymnasium's machine keeps the paper's two; the discount per period keeps the same
    /// horizon in seconds; dead times stay in periods, a board's own unit. On Gymnasium's
    /// machine it is the shipped recipe exactly.
    pub fn deploy_on(machine: &twin::Machine) -> Config {
        let (p, gym) = (&machine.rig.params, &twin::Machine::GYMNASIUM.rig.params);
        let (force, rate) = (p.force_mag / gym.force_mag, gym.tau / p.tau);
        let periods = |n: f64| (n * rate).round().max(1.0);
        let steps = |n: f64| periods(n) as u32;
        let push = |lo: f64, hi: f64, every: f64| {
            let (lo, hi) = (lo * force, hi * force);
            if lo == hi {
                format!("push={lo}/{}", periods(every))
            } else {
                format!("push={lo}..{hi}/{}", periods(every))
            }
        };
        let rig = *machine != twin::Machine::GYMNASIUM;
        let reward = "upright=20+centre=5";
        let robust = Config::robust();
        Config {
            // The same horizon in seconds: at twice the rate, a period's discount is
            // taken twice as often.
            gamma: robust.gamma.powf(1.0 / rate),
            domain: format!("{}+{}", deploy_domain(machine), push(0.8, 1.2, 50.0)),
            eval_domain: format!(
                "{}+{}@0.5",
                deploy_eval_domain(machine),
                push(0.5, 0.5, 100.0)
            ),
            // On a rig, pushes its balanced pole survives, so that the trial's cost can
            // choose among the survivors (`trial_margin`); Gymnasium's machine keeps the
            // shipped policy's harder ones, which every finalist falls to.
            finalist_domain: format!(
                "{}+{}",
                deploy_finalist_domain(machine),
                if rig {
                    push(0.5, 0.5, 100.0)
                } else {
                    push(1.1, 1.1, 50.0)
                }
            ),
            compensate: true,
            reward: if rig {
                format!("{reward}+{}", rig_effort(rate))
            } else {
                reward.into()
            },
            levels: if rig {
                RIG_LEVELS.into()
            } else {
                String::new()
            },
            episodes: 5000,
            max_steps: steps(500.0),
            eval_every: 10,
            eval_episodes: 50,
            eval_max_steps: steps(500.0),
            stop_when_perfect: false,
            patience: 50,
            // A rig's run also stops once five periodic evaluations in a row held every
            // episode, and tries fewer finalists on fewer episodes, so that a rig trains in
            // seconds (`docs/RIGS.md`); Gymnasium's machine keeps the shipped selection.
            settle: if rig { 5 } else { 0 },
            finalists: if rig { 8 } else { 20 },
            finalist_episodes: if rig { 25 } else { 50 },
            finalist_max_steps: steps(10_000.0),
            board_int8: rig,
            trial_margin: if rig { 0.05 } else { 0.0 },
            rig: if rig {
                twin::rigfile::to_toml(machine)
            } else {
                String::new()
            },
            ..robust
        }
    }
}
