use rand_core::{Rng, SeedableRng};
use rand_pcg::Pcg32;

use super::*;
use crate::shipped::policy_int::POLICY_INT;

/// [`Requant::apply`] as its documentation states it, in i128 with divisions instead of
/// shifts: the reference the shift-and-clamp code is checked against.
fn requant_reference(r: Requant, acc: i32) -> u8 {
    let pre = i128::from(r.pre_shift % 32);
    let post = i128::from(r.post_shift % 32);
    let t = (i128::from(acc.max(0)) / (1i128 << pre)).min(32_767);
    let half = if post == 0 { 0 } else { 1i128 << (post - 1) };
    let y = (t * i128::from(r.multiplier) + half) / (1i128 << post);
    y.min(255) as u8
}

#[test]
fn requantisation_is_its_documented_formula() {
    let mut rng = Pcg32::seed_from_u64(11);
    let edges = [i32::MIN, -1, 0, 1, 32_767, 32_768, i32::MAX];
    for case in 0..200_000u32 {
        let bits = rng.next_u32();
        let r = Requant::new(
            (bits & 0xffff) as u16,
            (bits >> 16) as u8 % 40,
            (bits >> 24) as u8 % 40,
        );
        let acc = if case % 10 == 0 {
            edges[(case / 10) as usize % edges.len()]
        } else {
            rng.next_u32() as i32 >> (rng.next_u32() % 32)
        };
        assert_eq!(r.apply(acc), requant_reference(r, acc), "{r:?} {acc}");
    }
}

/// The forward pass in i64 from the documented layer formulas, with the wrap of the 32-bit
/// accumulators written out. Indexed loops on purpose: written unlike the code under test.
#[allow(clippy::needless_range_loop)]
fn forward_reference<const H: usize>(net: &QMlp<H>, obs: &[i16; 4]) -> [i32; 2] {
    let wrap = |v: i64| v as i32;
    let mut h1 = [0u8; H];
    for o in 0..H {
        let mut acc: i64 = 0;
        for i in 0..4 {
            acc += i64::from(net.fc1_weight[o][i]) * i64::from(obs[i]);
        }
        h1[o] = requant_reference(net.fc1_requant[o], wrap(acc + i64::from(net.fc1_bias[o])));
    }
    let mut h2 = [0u8; H];
    for o in 0..H {
        let mut acc: i64 = 0;
        for i in 0..H {
            acc += i64::from(net.fc2_weight[o][i]) * i64::from(h1[i]);
        }
        h2[o] = requant_reference(net.fc2_requant[o], wrap(acc + i64::from(net.fc2_bias[o])));
    }
    let mut q = [0i32; 2];
    for a in 0..2 {
        let mut acc: i64 = 0;
        for i in 0..H {
            acc += i64::from(net.fc3_weight[a][i]) * i64::from(h2[i]);
        }
        q[a] = wrap(acc + i64::from(net.fc3_bias[a]));
    }
    q
}

fn random_net<const H: usize>(rng: &mut Pcg32, extreme: bool) -> QMlp<H> {
    let mut n = QMlp::<H>::zeroed();
    let byte = |rng: &mut Pcg32| {
        if extreme {
            [-128, 127][(rng.next_u32() % 2) as usize]
        } else {
            rng.next_u32() as i8
        }
    };
    for w in n.fc1_weight.as_flattened_mut() {
        *w = byte(rng);
    }
    for w in n.fc2_weight.as_flattened_mut() {
        *w = byte(rng);
    }
    for w in n.fc3_weight.as_flattened_mut() {
        *w = byte(rng);
    }
    for b in n
        .fc1_bias
        .iter_mut()
        .chain(&mut n.fc2_bias)
        .chain(&mut n.fc3_bias)
    {
        let v = rng.next_u32() as i32;
        *b = if extreme {
            [i32::MIN, i32::MAX][(v & 1) as usize]
        } else {
            v >> 12
        };
    }
    for r in n.fc1_requant.iter_mut().chain(&mut n.fc2_requant) {
        let bits = rng.next_u32();
        *r = if extreme {
            Requant::new(u16::MAX, (bits >> 16) as u8, (bits >> 24) as u8)
        } else {
            Requant::new(
                (bits & 0xffff) as u16,
                (bits >> 16) as u8 % 12,
                8 + (bits >> 24) as u8 % 16,
            )
        };
    }
    n
}

#[test]
fn the_forward_pass_is_the_layer_formulas_for_any_weights_and_input() {
    let mut rng = Pcg32::seed_from_u64(5);
    for case in 0..60 {
        let extreme = case % 3 == 0;
        let n16 = random_net::<16>(&mut rng, extreme);
        let n24 = random_net::<24>(&mut rng, extreme);
        for _ in 0..20 {
            let obs: [i16; 4] = core::array::from_fn(|_| rng.next_u32() as i16);
            assert_eq!(n16.forward(&obs), forward_reference(&n16, &obs));
            assert_eq!(n24.forward(&obs), forward_reference(&n24, &obs));
        }
    }
    // The shipped network on a balanced state, a leaning one and the format's extremes.
    for obs in [
        [0, 0, 0, 0],
        [41, -82, 123, 164],
        [9830, 0, 858, 0],
        [32767, -32768, 32767, -32768],
    ] {
        assert_eq!(
            POLICY_INT.forward(&obs),
            forward_reference(&POLICY_INT, &obs)
        );
    }
}

#[test]
fn the_exported_output_is_two_opposite_advantages() {
    // As exported, the output rows are the advantage row negated and the advantage row.
    let [l, r] = &POLICY_INT.fc3_weight;
    assert!(l.iter().zip(r).all(|(a, b)| *a == -*b));
    assert_eq!(POLICY_INT.fc3_bias[0], -POLICY_INT.fc3_bias[1]);
    let q = POLICY_INT.forward(&[41, -82, 123, 164]);
    assert_eq!(q[0], -q[1]);
}

#[test]
fn float_readings_round_to_q3_12_and_saturate() {
    assert_eq!(
        crate::fixed::from_state(&[1.0 / 8192.0, -1.0 / 8192.0, 7.9999, -9.0]),
        [1, -1, 32_767, -32_768]
    );
    assert_eq!(
        crate::fixed::from_state(&[f32::NAN, f32::INFINITY, -0.0, 0.1]),
        [0, 32_767, 0, 410]
    );
    assert_eq!(flash_bytes(64, 2), core::mem::size_of::<QMlp<64>>());
    assert_eq!(flash_bytes(64, 7), core::mem::size_of::<QMlp<64, 7>>());
    assert_eq!(flash_bytes(16, 2), core::mem::size_of::<QMlp<16>>());
}
