use super::*;
use crate::nn::{Loss, Scratch, reference};
use firmware::cartpole::{Action, unit_f64};
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

/// A buffer of random transitions.
fn filled(capacity: usize, n: usize, seed: u64) -> ReplayBuffer {
    let mut r = rng(seed, Stream::Env);
    let mut state = || [0; OBS_DIM].map(|_| (unit_f64(&mut r) as f32 - 0.5) * 4.0);
    let mut buf = ReplayBuffer::new(capacity);
    for step in 0..n {
        let (s, s2) = (state(), state());
        buf.push(
            s,
            Action::from_index(step % 2),
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
    let mut learner = Learner::<64>::new(&cfg, kernel, 7);
    let mut buf = ReplayBuffer::new(cfg.buffer_size);
    let mut sample = rng(7, Stream::Sample);
    let mut fresh = Scratch::<64>::new(cfg.batch_size);
    let (mut rows, mut misses) = (0, 0);
    for step in 0..400u64 {
        let more = filled(1, 1, step);
        let (s, a, r, s2, t) = more.get(0);
        buf.push(s, Action::from_index(usize::from(a)), r, s2, t);
        if buf.len() < cfg.batch_size {
            continue;
        }
        let target = learner.target.clone();
        learner.update(&cfg, &buf, &mut sample);
        for h in &learner.halves {
            nn::forward_batch(
                kernel,
                &target,
                &Packed::new(&target),
                h.x_next(),
                &mut fresh,
            );
            let bits = |q: &[[f32; 2]]| q.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();
            let n = h.x_next().len();
            assert_eq!(bits(h.q_target()), bits(&fresh.q[..n]), "step {step}");
            rows += n;
            misses += h.misses();
        }
        if step % 100 == 99 {
            learner.sync_target();
        }
    }
    // Most rows come from the cache, but new and overwritten slots do not.
    assert!(misses > 0 && misses * 4 < rows, "{misses} of {rows}");
}

/// One update, recomputed from the definition: the same sampled rows in two halves, each
/// half's gradient by the plain-loop rendering of the arithmetic, summed, clipped as defined,
/// one Adam step. The learner must give its bits on one thread and on two.
#[test]
fn an_update_is_the_sum_of_its_halves_gradients_on_any_number_of_threads() {
    let cfg = Config {
        batch_size: 13,
        grad_clip: 0.05,
        loss: Loss::Huber,
        ..Config::paper()
    };
    let buf = filled(100, 100, 3);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let mut learner = Learner::<16>::new(&cfg, Kernel::detect(), 5);
        let mut sample = Pcg64Mcg::new(9);
        pool.install(|| learner.update(&cfg, &buf, &mut sample));
        learner
    };
    let (one, two) = (run(1), run(2));
    let bits = |m: &Mlp<16>| {
        m.tensors()
            .iter()
            .flat_map(|t| t.iter().map(|v| v.to_bits()))
            .collect::<Vec<_>>()
    };
    assert_eq!(bits(&one.online), bits(&two.online));

    let start = Learner::<16>::new(&cfg, Kernel::detect(), 5);
    let net = &start.online;
    let mut idx = Vec::new();
    buf.sample_indices(&mut Pcg64Mcg::new(9), cfg.batch_size, &mut idx);
    let scale = 1.0 / idx.len() as f32;
    let mut grad = Mlp::<16>::zeroed();
    for rows in [&idx[..7], &idx[7..]] {
        let t: Vec<_> = rows.iter().map(|&i| buf.get(i)).collect();
        let x: Vec<[f32; 4]> = t.iter().map(|t| t.0).collect();
        let actions: Vec<u8> = t.iter().map(|t| t.1).collect();
        let targets: Vec<f32> = t
            .iter()
            .map(|&(_, _, r, s2, done)| {
                let (qo, qt) = (
                    reference::forward(net, &s2).2,
                    reference::forward(net, &s2).2,
                );
                let next = qt[argmax(&qo).index()];
                r + if done { 0.0 } else { cfg.gamma as f32 * next }
            })
            .collect();
        let (g, _) = reference::backward(net, &x, &actions, &targets, (cfg.loss, scale));
        for (a, b) in grad.tensors_mut().into_iter().zip(g.tensors()) {
            for (a, b) in a.iter_mut().zip(b) {
                *a += b;
            }
        }
    }
    let norm = reference::sum_of_squares(&grad).sqrt() as f32;
    assert!(
        norm > 0.05,
        "the clip must act for the test to see it: {norm}"
    );
    let k = 0.05 / (norm + 1e-6);
    grad.tensors_mut()
        .into_iter()
        .for_each(|t| t.iter_mut().for_each(|g| *g *= k));
    let mut want = net.clone();
    let (mut m, mut v) = (Mlp::<16>::zeroed(), Mlp::<16>::zeroed());
    reference::adam(&start.adam, 1, &mut want, &grad, &mut m, &mut v);
    assert_eq!(bits(&one.online), bits(&want));
}

/// Soft updates move the target's packing elementwise: it stays the packing of the target,
/// bit for bit.
#[test]
fn the_soft_updated_targets_packing_is_its_transposes() {
    let cfg = Config::robust();
    let buf = filled(500, 500, 8);
    let mut learner = Learner::<32>::new(&cfg, Kernel::detect(), 2);
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
