use super::*;
use crate::lockstep::{run_episode, run_episodes};
use firmware::Action;
use firmware::cartpole::{Params, advance};
use firmware::controller::{Duty, Levels};
use shipped::policy::POLICY;

/// Pushes towards `theta + 0.5 theta_dot`, never coasting.
struct Rule;
impl Policy for Rule {
    type Scores = [f32; 2];
    fn duty(&self, i: usize) -> Option<Duty> {
        Levels::BANG_BANG.duty(i)
    }
    fn scores(&mut self, o: &[f32; 4]) -> [f32; 2] {
        [0.0, o[2] + 0.5 * o[3]]
    }
}

#[test]
fn nominal_twin_is_the_plant_under_the_policy_bit_for_bit() {
    for episode in 0..20 {
        let mut frames = Vec::new();
        let stats = run_episode(&POLICY, &Scenario::nominal(), 500, 7, episode, false, |f| {
            frames.push(f)
        });
        let mut plant = CartPole::new(Params::default(), 500);
        let mut obs = plant.reset(&mut episode_rng(7, episode, Stream::Start));
        assert_eq!(plant.state(), start_state(7, episode));
        for f in &frames {
            let action = Action::from_index(POLICY.greedy(&obs));
            let duty = Levels::BANG_BANG.duty(action.index()).unwrap();
            assert_eq!(f.command, Command::Drive(duty));
            obs = plant.step(action).obs;
            assert_eq!(plant.state(), f.state);
        }
        assert_eq!(stats.steps as usize, frames.len());
    }
}

#[test]
fn delay_applies_the_previous_command() {
    let delayed = Scenario::parse("delay").unwrap();
    let mut frames = Vec::new();
    run_episode(Rule, &delayed, 50, 3, 0, false, |f| frames.push(f));
    let p = Params::default();
    let mut s = start_state(3, 0);
    // The first period applies no force; then each applies its predecessor's command.
    s = advance(&p, &s, 0.0, 0.0);
    assert_eq!(frames[0].state, s);
    for w in frames.windows(2) {
        let Command::Drive(d) = w[0].command else {
            panic!("exact sensors never coast")
        };
        s = advance(&p, &s, f64::from(d.fraction()), 0.0);
        assert_eq!(w[1].state, s);
    }
}

#[test]
fn prediction_bridges_a_long_dead_time() {
    // Six periods of dead time topple the shipped policy; told of them, it balances.
    let late = Scenario::parse("delay=6").unwrap();
    let blind = run_episode(&POLICY, &late, 500, 2, 0, false, |_| {});
    let told = run_episode(&POLICY, &late, 500, 2, 0, true, |_| {});
    assert!(!blind.success && told.success, "{blind:?} {told:?}");
}

#[test]
fn pushes_topple_and_noise_is_seeded() {
    // A 0.5 N s push every period overwhelms the 10 N motor: the pole falls quickly.
    let brutal = Scenario::parse("push=0.5/1").unwrap();
    let st = run_episode(&POLICY, &brutal, 500, 1, 0, false, |_| {});
    let calm = run_episode(&POLICY, &Scenario::nominal(), 500, 1, 0, false, |_| {});
    assert!(st.steps < 100 && calm.success, "{st:?} {calm:?}");
    let noisy = Scenario::parse("noise=4").unwrap();
    let run = |seed| {
        let mut v = Vec::new();
        run_episode(&POLICY, &noisy, 300, seed, 0, false, |f| v.push(f));
        v
    };
    assert_eq!(run(5), run(5));
    let mut exact = Vec::new();
    run_episode(&POLICY, &Scenario::nominal(), 300, 5, 0, false, |f| {
        exact.push(f)
    });
    assert_ne!(run(5), exact);
}

/// The records of an episode of the bang-bang rule on the true state: each period's
/// true state before the reading, and what the controller received and sent.
fn rule_episode(spec: &str, periods: usize) -> (Scenario, Vec<(State, [f32; 4], Command)>) {
    struct Truth;
    impl Policy for Truth {
        type Scores = [f32; 2];
        fn duty(&self, i: usize) -> Option<Duty> {
            Levels::BANG_BANG.duty(i)
        }
        fn scores(&mut self, o: &[f32; 4]) -> [f32; 2] {
            [0.0, o[2] + 0.5 * o[3]]
        }
    }
    let s = Scenario::parse(spec).unwrap();
    let streams = (Pcg64Mcg::new(2), Pcg64Mcg::new(3));
    let mut ep = Episode::start(Truth, &s, 500, &mut Pcg64Mcg::new(1), streams, false);
    let mut out = Vec::new();
    for _ in 0..periods {
        let truth = ep.world().state();
        let command = ep.decide();
        out.push((truth, ep.controller().last().unwrap().obs, command));
        ep.apply();
    }
    (s, out)
}

#[test]
fn encoders_quantise_and_the_observer_recovers_the_velocities() {
    let (_, periods) = rule_episode("encoder=4096", 200);
    let (mut worst_x, mut worst_w) = (0.0f64, 0.0f64);
    for (truth, obs, _) in &periods[10..] {
        worst_x = worst_x.max((f64::from(obs[0]) - truth.x).abs());
        worst_w = worst_w.max((f64::from(obs[3]) - truth.theta_dot).abs());
    }
    // A cart count is 1 / 20480 m = 49 um, a pole count 1.5 mrad. The observer predicts
    // with the plant and the command, so its position stays within one count and its
    // rate within 0.1 rad/s, where differencing the counts would be off by 0.08 rad/s
    // per count.
    assert!(worst_x < 4.9e-5, "{worst_x}");
    assert!(worst_w < 0.1, "{worst_w}");
}

/// The twin's observer is the board's: built for the rig (Gymnasium's machine, whatever
/// the scenario's physics), told the dead time and each command the controller sends,
/// fed the true state's counts. An observer built by hand that way gives the readings
/// the controller received, bit for bit; one that ignores the dead time is worse.
#[test]
fn the_observer_is_told_the_dead_time_and_the_commands() {
    use firmware::estimator::{Observer, Tuning};
    let (s, periods) = rule_episode("encoder=512+delay=3+force=0.8+length=0.7", 300);
    let enc = s.rig.encoders;
    let make = |delay| Observer::new(enc, &Params::default(), Tuning::DEFAULT, delay).unwrap();
    let (mut board, mut blind) = (make(3), make(0));
    let (mut err_board, mut err_blind) = (0.0f64, 0.0f64);
    for (k, (truth, obs, command)) in periods.iter().enumerate() {
        let (cart, pole) = enc.counts(truth.x, truth.theta);
        assert_eq!(*obs, board.update(cart, pole), "period {k}");
        let b = blind.update(cart, pole);
        if k > 10 {
            err_board += (f64::from(obs[3]) - truth.theta_dot).powi(2);
            err_blind += (f64::from(b[3]) - truth.theta_dot).powi(2);
        }
        board.command(command.level());
        blind.command(command.level());
    }
    // The plant is not the rig's, so neither observer is exact; the blind one is clearly
    // worse.
    assert!(err_board * 3.0 < err_blind, "{err_board} vs {err_blind}");
}

/// Episodes side by side are the episodes alone: on a continuous-time rig (their worlds
/// integrated in blocks of lanes) with noise, pushes, encoders and dead time, and with
/// episodes ending at different periods so that slots refill mid-run.
#[test]
fn episodes_side_by_side_are_the_episodes_alone() {
    let desk = crate::rigfile::parse(include_str!("../../../rigs/desk.toml"), "desk").unwrap();
    for spec in ["noise+push=0.15/37+delay=2", "encoder+push=0.4/23"] {
        let s = Scenario::parse_on(spec, &desk).unwrap();
        assert!(matches!(s.integration, crate::Integration::Rk4 { .. }));
        let together = run_episodes(|_| Rule, &s, 400, 11, 3..22, true);
        assert_eq!(together.len(), 19);
        for (e, got) in (3..22).zip(&together) {
            let alone = run_episode(Rule, &s, 400, 11, e, true, |_| {});
            assert_eq!(*got, alone, "{spec}, episode {e}");
        }
        let lengths: std::collections::BTreeSet<u32> = together.iter().map(|t| t.steps).collect();
        assert!(
            lengths.len() > 3,
            "{spec}: episodes of different lengths {lengths:?}"
        );
    }
}

#[test]
fn the_motor_tally_counts_reversals_duty_and_heat_by_hand() {
    let p = Params {
        motor_damping: 5.0,
        ..Params::default()
    };
    let (right, left) = (Command::Drive(Duty::RIGHT), Command::Drive(Duty::LEFT));
    let mut tally = Tally::default();
    let t = Transition {
        obs: [0.0; 4],
        reward: 1.0,
        terminated: false,
        truncated: false,
    };
    // The cart moves at 1 m/s after every period.
    let s = State {
        x_dot: 1.0,
        ..State::default()
    };
    let tiny = |t: f32| Command::Drive(Duty::from_fraction(t).unwrap());
    for c in [right, left, Command::Coast, tiny(0.05), left, right] {
        tally.period(&p, (c, false), &s, &t);
    }
    let e = tally.stats();
    // right->left, then left (across the coast and the push too small to count) ->right.
    assert_eq!(e.reversals, 2);
    assert!((e.sum_abs_duty - 4.05).abs() < 1e-6);
    // |1-0| + |-1-1| + |0+1| + |0.05-0| + |-1-0.05| + |1+1|
    assert!((e.sum_duty_change - 7.1).abs() < 1e-6);
    // Current = duty - 5 * 1 / 10 = duty - 0.5; the first period's speed is the state's.
    let heat: f64 = [0.5f64, -1.5, -0.5, -0.45, -1.5, 0.5]
        .iter()
        .map(|c| c * c)
        .sum();
    assert!((e.sum_heat - heat).abs() < 1e-6, "{}", e.sum_heat);
}
