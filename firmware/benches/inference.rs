//! Host speed of the two hot paths the firmware runs every control period: one forward pass
//! of the 4-64-64-2 network and one plant step. `cargo bench -p firmware --bench inference`.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use firmware::cartpole::{self, Action, Params, State};
use firmware::network::PolicyNet;
use rand_core::Rng;
use rand_pcg::Pcg64Mcg;

fn random_net() -> PolicyNet {
    let mut rng = Pcg64Mcg::new(1);
    let mut net = PolicyNet::zeroed();
    for t in net.tensors_mut() {
        for v in t {
            *v = (rng.next_u32() as f32 / u32::MAX as f32 - 0.5) * 0.4;
        }
    }
    net
}

fn benches(c: &mut Criterion) {
    let net = random_net();
    let obs = [0.01f32, -0.2, 0.03, 0.4];
    c.bench_function("forward 4-64-64-2", |b| {
        b.iter(|| net.forward(black_box(&obs)))
    });

    let p = Params::default();
    let s = State {
        x: 0.01,
        x_dot: -0.2,
        theta: 0.03,
        theta_dot: 0.4,
    };
    c.bench_function("plant step", |b| {
        b.iter(|| cartpole::step(black_box(&p), black_box(&s), black_box(Action::Right)))
    });
}

criterion_group!(inference, benches);
criterion_main!(inference);
