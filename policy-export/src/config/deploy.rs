//! The deploy preset's worlds, on any machine: what it trains, selects and tries its
//! finalists in; and, for a rig, how it drives the motor.

/// The duty levels the recipe trains for a rig: fine steps near zero, where a balanced pole
/// needs only small corrections, and full duty kept for pushes. With two levels a policy
/// can only balance by full pushes reversed every few periods (`docs/RIGS.md`).
pub const RIG_LEVELS: &str = "-1,-0.4,-0.15,-0.05,0,0.05,0.15,0.4,1";

/// What the recipe's learner pays for driving a rig's motor: the duty squared and its
/// change from the previous period (`train::Reward`), beside the pole's lean and the
/// cart's distance.
pub const RIG_EFFORT: &str = "effort=1+smooth=2";

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

/// The worlds its finalists are tried in for 10,000 steps: plants drawn like the default
/// set's, half of them with its noise, all under pushes of (Gymnasium's) 1.1 N s every
/// second, through the rig's encoders.
pub fn deploy_finalist_domain(machine: &twin::Machine) -> String {
    physics(0.2, machine) + "+noise=0..1@0.5+encoder"
}
