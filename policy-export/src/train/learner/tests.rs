use super::reference::ReferenceLearner;
use super::*;
use crate::nn::{Loss, reference};
use firmware::cartpole::unit_f64;
use rand_pcg::Pcg64Mcg;

#[test]
fn ddqn_and_dqn_targets_differ_where_they_should() {
    // Online net prefers action 0, target net rates action 1 higher.
    let qt = [[1.0, 3.0], [1.0, 3.0]];
    let qo = [[5.0, 2.0], [5.0, 2.0]];
    let r = [1.0, 1.0];
    let term = [false, true];
    let mut y = [0.0; 2];
    td_targets(Algo::Ddqn, 0.5, &r, &term, &qt, &qo, &mut y);
    assert_eq!(y, [1.0 + 0.5 * 1.0, 1.0]);
    td_targets(Algo::Dqn, 0.5, &r, &term, &qt, &qo, &mut y);
    assert_eq!(y, [1.0 + 0.5 * 3.0, 1.0]);
}

/// A buffer of random transitions over `actions` outputs.
fn filled(capacity: usize, n: usize, seed: u64, actions: usize) -> ReplayBuffer {
    let mut r = rng(seed, Stream::Env);
    let mut state = || [0; OBS_DIM].map(|_| (unit_f64(&mut r) as f32 - 0.5) * 4.0);
    let mut buf = ReplayBuffer::new(capacity);
    for step in 0..n {
        let (s, s2) = (state(), state());
        buf.push(
            s,
            step % actions,
            1.0 - (step % 3) as f32,
            s2,
            step % 7 == 0,
        );
    }
    buf
}

#[test]
fn cached_target_q_values_equal_a_fresh_forward_pass() {
    let kernel = Kernel::detect();
    // A small buffer, so slots are overwritten many times over; hard updates are cached.
    let cfg = Config {
        buffer_size: 48,
        ..Config::paper()
    };
    let mut learner = Learner::<64, 2>::new(&cfg, kernel, 7);
    let mut buf = ReplayBuffer::new(cfg.buffer_size);
    let mut sample = rng(7, Stream::Sample);
    let (mut rows, mut misses) = (0, 0);
    for step in 0..400u64 {
        let more = filled(1, 1, step, 2);
        let (s, a, r, s2, t) = more.get(0);
        buf.push(s, usize::from(a), r, s2, t);
        if buf.len() < cfg.batch_size {
            continue;
        }
        let target = learner.target.clone();
        learner.update(&cfg, &buf, &mut sample);
        let (q_target, x_next, missed) = learner.batch.targets_seen();
        let bits = |q: &[[f32; 2]]| q.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();
        let fresh: Vec<[f32; 2]> = x_next
            .iter()
            .map(|s| reference::forward(&target, s).2)
            .collect();
        assert_eq!(bits(q_target), bits(&fresh), "step {step}");
        rows += x_next.len();
        misses += missed;
        if step % 100 == 99 {
            learner.sync_target();
        }
    }
    // Most rows come from the cache, but new and overwritten slots do not.
    assert!(misses > 0 && misses * 4 < rows, "{misses} of {rows}");
}

fn bits<const H: usize, const A: usize>(m: &Mlp<H, A>) -> Vec<u32> {
    m.tensors()
        .iter()
        .flat_map(|t| t.iter().map(|v| v.to_bits()))
        .collect()
}

/// Runs `updates` steps of the fast learner (with every kernel this CPU runs) and of the reference learner from the same start, on the same batches, with
/// the target copied every 7 steps where it is copied; every step's weights and loss
/// must agree bit for bit.
fn fast_equals_reference<const H: usize, const A: usize>(cfg: &Config, updates: u64) {
    let buf = filled(300, 300, 11, A);
    for kernel in Kernel::available() {
        let mut fast = Learner::<H, A>::new(cfg, kernel, 5);
        let mut plain = ReferenceLearner::<H, A>::new(cfg, &fast.online);
        let (mut r1, mut r2) = (Pcg64Mcg::new(9), Pcg64Mcg::new(9));
        for step in 1..=updates {
            let l1 = fast.update(cfg, &buf, &mut r1);
            let l2 = plain.update(cfg, &buf, &mut r2);
            let at = format!("{kernel:?}, step {step}, width {H}");
            assert_eq!(l1.to_bits(), l2.to_bits(), "loss: {at}");
            assert_eq!(bits(&fast.online), bits(&plain.online), "weights: {at}");
            assert_eq!(bits(&fast.target), bits(&plain.target), "target: {at}");
            if cfg.target_update == TargetUpdate::Hard && step % 7 == 0 {
                fast.sync_target();
                plain.sync_target();
            }
        }
    }
}

/// The fast learner is the reference learner: parts of the batch, shares of the
/// parameters and the target cache change no bit, for Double DQN and DQN,
/// hard and soft targets, both losses, with and without the clip, batches the parts split
/// evenly and not, two outputs and more.
#[test]
fn the_fast_learner_equals_the_reference_learner_bit_for_bit() {
    let paper = Config {
        grad_clip: 0.05,
        ..Config::paper()
    };
    let odd = Config {
        batch_size: 13,
        algo: Algo::Dqn,
        loss: Loss::Mse,
        ..Config::paper()
    };
    let soft = Config {
        batch_size: 64,
        ..Config::robust()
    };
    fast_equals_reference::<64, 2>(&paper, 40);
    fast_equals_reference::<16, 2>(&odd, 30);
    fast_equals_reference::<32, 2>(&soft, 30);
    fast_equals_reference::<64, 5>(&paper, 30);
    fast_equals_reference::<32, 7>(&soft, 30);
}

/// The clip must act in the test above for it to test the clip: the first step clipped
/// differs from the same step unclipped.
#[test]
fn the_clip_acts_in_the_equality_test() {
    let clipped = Config {
        grad_clip: 0.05,
        ..Config::paper()
    };
    let free = Config {
        grad_clip: 0.0,
        ..Config::paper()
    };
    let buf = filled(300, 300, 11, 2);
    let start = Learner::<64, 2>::new(&clipped, Kernel::detect(), 5);
    let step = |cfg: &Config| {
        let mut r = ReferenceLearner::<64, 2>::new(cfg, &start.online);
        r.update(cfg, &buf, &mut Pcg64Mcg::new(9));
        bits(&r.online)
    };
    assert_ne!(step(&clipped), step(&free));
}

/// Soft updates move the target's packing elementwise: it stays the packing of the target,
/// bit for bit.
#[test]
fn the_soft_updated_targets_packing_is_its_transposes() {
    let cfg = Config::robust();
    let buf = filled(500, 500, 8, 2);
    let mut learner = Learner::<32, 2>::new(&cfg, Kernel::detect(), 2);
    let mut sample = Pcg64Mcg::new(1);
    for _ in 0..20 {
        learner.update(&cfg, &buf, &mut sample);
    }
    let fresh = Packed::new(&learner.target);
    let bits = |p: &Packed<32>| {
        p.transposes()
            .iter()
            .flat_map(|v| v.to_bits().to_le_bytes())
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&learner.target_packed), bits(&fresh));
    assert_ne!(bits(&learner.target_packed), bits(&learner.online_packed));
}
