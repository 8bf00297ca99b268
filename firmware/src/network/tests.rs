use super::*;
use rand_core::Rng;
use rand_pcg::Pcg64Mcg;

fn uniform(rng: &mut Pcg64Mcg, scale: f32) -> f32 {
    ((rng.next_u32() >> 8) as f32 / (1u32 << 24) as f32 * 2.0 - 1.0) * scale
}

fn random_net<const H: usize>(rng: &mut Pcg64Mcg) -> Mlp<H> {
    let mut net = Mlp::<H>::zeroed();
    for t in net.tensors_mut() {
        for v in t {
            *v = uniform(rng, 0.5);
        }
    }
    net
}

/// The textbook forward pass in f64, one accumulator, written independently of `dot`
/// (indexed loops on purpose: it should read like the equations, not like the code).
#[allow(clippy::needless_range_loop)]
fn reference<const H: usize>(net: &Mlp<H>, obs: &[f32; 4]) -> [f64; 2] {
    let x: [f64; 4] = obs.map(f64::from);
    let mut h1 = [0.0f64; H];
    for o in 0..H {
        let mut s = f64::from(net.fc1_bias[o]);
        for i in 0..4 {
            s += f64::from(net.fc1_weight[o][i]) * x[i];
        }
        h1[o] = s.max(0.0);
    }
    let mut h2 = [0.0f64; H];
    for o in 0..H {
        let mut s = f64::from(net.fc2_bias[o]);
        for i in 0..H {
            s += f64::from(net.fc2_weight[o][i]) * h1[i];
        }
        h2[o] = s.max(0.0);
    }
    let mut q = [0.0f64; 2];
    for o in 0..2 {
        let mut s = f64::from(net.fc3_bias[o]);
        for i in 0..H {
            s += f64::from(net.fc3_weight[o][i]) * h2[i];
        }
        q[o] = s;
    }
    q
}

fn check_against_reference<const H: usize>() {
    let mut rng = Pcg64Mcg::new(0xC0FFEE + H as u128);
    for _ in 0..20 {
        let net = random_net::<H>(&mut rng);
        for _ in 0..50 {
            let obs = [2.4, 3.0, 0.21, 3.0].map(|s| uniform(&mut rng, s));
            let got = net.forward(&obs);
            let want = reference(&net, &obs);
            for a in 0..2 {
                let err = (f64::from(got[a]) - want[a]).abs();
                // Relative to the value, and to 1 where the value is near zero
                // (cancellation makes a pure relative error meaningless there).
                assert!(
                    err <= 1e-5 * want[a].abs().max(1.0),
                    "H={H} {got:?} {want:?}"
                );
            }
        }
    }
}

#[test]
fn forward_matches_f64_reference_at_every_width() {
    check_against_reference::<16>();
    check_against_reference::<64>();
    check_against_reference::<128>();
}

#[test]
fn parameter_counts_and_shapes_are_the_true_ones() {
    assert_eq!(params(16, 2), 386);
    assert_eq!(Mlp::<64>::PARAMS, 4_610);
    assert_eq!(params(128, 2), 17_410);
    // 4*64 + 64 + 64*64 + 64 + 7*64 + 7: five more output rows of 65.
    assert_eq!(Mlp::<64, 7>::PARAMS, 4_610 + 5 * 65);
    assert_eq!(core::mem::size_of::<PolicyNet>(), 18_440);
    let net = PolicyNet::zeroed();
    let lens = net.tensors().map(<[f32]>::len);
    assert_eq!(lens, PolicyNet::SHAPES.map(|s| s.len()));
    assert_eq!(lens.iter().sum::<usize>(), 4_610);
    let dims = shapes(16, 2).map(|s| (s.dims().len(), s.dims()[0]));
    assert_eq!(dims, [(2, 16), (1, 16), (2, 16), (1, 16), (2, 2), (1, 2)]);
    assert_eq!(shapes(16, 2)[2].matrix(), Some((16, 16)));
    assert_eq!(shapes(16, 2)[4].dims(), [2, 16]);
    assert_eq!(shapes(16, 5)[4].dims(), [5, 16]);
    assert_eq!(shapes(16, 2)[5].matrix(), None);
}

#[test]
fn the_mlp_has_cs_layout() {
    // `struct cartpole_mlp16` in C: the fields back to back, no padding (all f32).
    let net = Mlp::<16>::zeroed();
    let base = core::ptr::from_ref(&net).addr();
    let offsets = net.tensors().map(|t| t.as_ptr().addr() - base);
    let mut want = [0; 6];
    for i in 1..6 {
        want[i] = want[i - 1] + 4 * shapes(16, 2)[i - 1].len();
    }
    assert_eq!(offsets, want);
}

#[test]
fn lanes_take_every_eighth_product() {
    // Lane 0 gets elements 0 and 8, lane 1 gets 1 and 9, ...: 1e8 and -1e8 cancel only if
    // they share a lane, and the small values survive only if they do not meet 1e8 first.
    let mut w = [0.0f32; 16];
    let x = [1.0f32; 16];
    w[0] = 1e8;
    w[8] = -1e8;
    w[1] = 1.0;
    w[4] = 0.5;
    w[12] = 0.25;
    assert_eq!(dot(&w, &x), 1.75);
    let sequential = w.iter().fold(0.0f32, |s, w| s + w);
    assert_ne!(sequential, 1.75);
}

/// Eight lane sums for which the documented tree and each usual alternative tree give
/// different f32 results (found by search; the alternatives are listed in the test).
pub(crate) const TREE_LANES: [f32; 8] = [-3.0, 3e7, -6e7, 3e7, -1e8, 3.0, 1e8, 3.0];

/// `((l0 + l4) + (l2 + l6)) + ((l1 + l5) + (l3 + l7))`, written out.
pub(crate) fn documented_tree(l: &[f32; 8]) -> f32 {
    ((l[0] + l[4]) + (l[2] + l[6])) + ((l[1] + l[5]) + (l[3] + l[7]))
}

#[test]
fn the_tree_is_the_documented_one() {
    let l = TREE_LANES;
    // One product per lane: w holds the lane sums, x is all ones.
    let got = dot(&l, &[1.0; 8]);
    assert_eq!(got, documented_tree(&l));
    assert_eq!(got, 8.0);
    let alternatives = [
        (
            "sequential",
            ((((((l[0] + l[1]) + l[2]) + l[3]) + l[4]) + l[5]) + l[6]) + l[7],
        ),
        (
            "adjacent pairs",
            ((l[0] + l[1]) + (l[2] + l[3])) + ((l[4] + l[5]) + (l[6] + l[7])),
        ),
        (
            "pairs k, k + 2",
            ((l[0] + l[2]) + (l[1] + l[3])) + ((l[4] + l[6]) + (l[5] + l[7])),
        ),
        (
            "same pairs, other second level",
            ((l[0] + l[4]) + (l[1] + l[5])) + ((l[2] + l[6]) + (l[3] + l[7])),
        ),
        (
            "same pairs, then sequential",
            (((l[0] + l[4]) + (l[1] + l[5])) + (l[2] + l[6])) + (l[3] + l[7]),
        ),
    ];
    for (name, v) in alternatives {
        assert_ne!(
            v, got,
            "{name} gives the same result: the test would not see it"
        );
    }
}

#[test]
fn ties_and_nan_pick_the_lower_index() {
    assert_eq!(argmax(&[1.0, 1.0]), 0);
    assert_eq!(argmax(&[0.0, -0.0]), 0);
    assert_eq!(argmax(&[f32::NAN, 1.0]), 0);
    assert_eq!(argmax(&[1.0, f32::NAN]), 0);
    assert_eq!(argmax(&[1.0, 1.0 + f32::EPSILON]), 1);
    assert_eq!(argmax(&[1.0, 3.0, 2.0, 3.0, f32::NAN]), 1);
    assert_eq!(argmax(&[-1, 5, 7, 7]), 2);
    // An all-zero net outputs equal Q-values, so it always picks the first output.
    assert_eq!(PolicyNet::zeroed().greedy(&[0.1, 0.0, -0.1, 0.0]), 0);
    assert_eq!(Mlp::<16, 5>::zeroed().greedy(&[0.1, 0.0, -0.1, 0.0]), 0);
}

#[test]
fn relu_zeroes_negative_and_nan_preactivations() {
    let mut net = Mlp::<8>::zeroed();
    net.fc1_bias = [-1.0, f32::NAN, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    net.fc2_weight = [[1.0; 8]; 8];
    net.fc3_weight = [[1.0; 8]; 2];
    // Only the +2.0 unit survives layer 1; each of 8 units in layer 2 then sees 2.0.
    assert_eq!(net.forward(&[0.0; 4]), [16.0, 16.0]);
}

#[test]
fn a_policy_can_be_a_static() {
    static NET: PolicyNet = PolicyNet::zeroed();
    assert_eq!(NET.forward(&[0.0; 4]), [0.0, 0.0]);
}

#[test]
fn the_two_output_widths_are_those_of_the_shape_list() {
    assert_eq!(SUPPORTED_WIDTHS, &[16, 64, 128]);
}
