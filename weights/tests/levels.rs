//! Checkpoints of networks with 5 and 7 outputs, as `torch.save`, Stable-Baselines3's
//! `model.zip` and `torch.onnx.export` lay them out, and the duty levels they drive. Such a
//! file records no levels: it imports with the levels given, one per output, and is refused
//! without them or with another count; a file that records levels refuses different ones.
//!
//! PyTorch is not installed where these tests run (its Linux wheel pulls in about 5 GB of
//! CUDA libraries), so the files are made here byte by byte (`tests/support/build.rs`) in
//! the layouts of the fixtures real tools wrote (`tests/fixtures/README.md`): the same zip
//! entries, pickle globals and persistent ids, the same ONNX `Gemm`/`Relu` chain. The
//! expected Q-values are computed in f64 from the tensors' definition.

mod support;

use std::collections::BTreeMap;

use support::build::*;
use weights::Weights;
use weights::checkpoint::{Format, Import, import, import_with, to_safetensors};
use weights::levels::GivenLevels;

const FIVE: [f32; 5] = [-1.0, -0.2, 0.0, 0.2, 1.0];
const SEVEN: [f32; 7] = [-1.0, -0.5, -0.2, 0.0, 0.2, 0.5, 1.0];

/// `torch.save(net.state_dict())` of an `nn.Sequential` of hidden width 64 and `outputs`.
fn torch_file(outputs: usize) -> Vec<u8> {
    let mut p = Pickle::new();
    p.dict();
    let storages = items_of(&mut p, "", "n", network_of(64, outputs));
    torch_zip(&p.end(), &storages)
}

/// SB3's `model.zip` of a DQN with that network: `policy.pth` holding the online net under
/// `q_net.q_net.` and the target net under `q_net_target.q_net.`.
fn sb3_file(outputs: usize) -> Vec<u8> {
    let mut p = Pickle::new();
    p.dict();
    let mut storages = items_of(&mut p, "q_net.q_net.", "a", network_of(64, outputs));
    storages.extend(items_of(
        &mut p,
        "q_net_target.q_net.",
        "b",
        network_of(64, outputs),
    ));
    let policy = torch_zip(&p.end(), &storages);
    zip(&[("data", b"{}"), ("policy.pth", &policy)])
}

/// `torch.onnx.export` of that network: `Gemm`s and `Relu`s.
fn onnx_file(outputs: usize) -> Vec<u8> {
    onnx_model(onnx_fields_of(&network_of(64, outputs)))
}

/// Each format's file of `outputs` outputs, the prefix its network is under, its format.
fn files(outputs: usize) -> [(Vec<u8>, Option<&'static str>, Format); 3] {
    [
        (torch_file(outputs), None, Format::TorchZip),
        (sb3_file(outputs), Some("q_net.q_net."), Format::Sb3Zip),
        (onnx_file(outputs), None, Format::Onnx),
    ]
}

fn given(levels: &[f32]) -> GivenLevels {
    let wide: Vec<f64> = levels.iter().copied().map(f64::from).collect();
    GivenLevels::new(&wide, "--levels").unwrap()
}

/// The network's Q-values in f64, from its tensors (weight `[out][in]`, ReLU between).
fn reference(w: &Weights, obs: [f32; 4]) -> Vec<f64> {
    let t = w.tensors();
    let layer = |x: &[f64], wt: &[f32], b: &[f32], relu: bool| -> Vec<f64> {
        b.iter()
            .enumerate()
            .map(|(o, &bo)| {
                let row = &wt[o * x.len()..(o + 1) * x.len()];
                let s = f64::from(bo)
                    + row
                        .iter()
                        .zip(x)
                        .map(|(&w, &x)| f64::from(w) * x)
                        .sum::<f64>();
                if relu { s.max(0.0) } else { s }
            })
            .collect()
    };
    let x: Vec<f64> = obs.iter().map(|&v| f64::from(v)).collect();
    let h1 = layer(&x, &t[0], &t[1], true);
    let h2 = layer(&h1, &t[2], &t[3], true);
    layer(&h2, &t[4], &t[5], false)
}

/// The firmware's forward pass of the imported network.
fn forward(w: &Weights, obs: [f32; 4]) -> Vec<f32> {
    match w.outputs() {
        5 => w.to_mlp::<64, 5>().unwrap().forward(&obs).to_vec(),
        7 => w.to_mlp::<64, 7>().unwrap().forward(&obs).to_vec(),
        a => panic!("no file here has {a} outputs"),
    }
}

fn check(got: &Import, outputs: usize, levels: &[f32], format: Format) {
    assert_eq!(got.format, format);
    assert_eq!((got.weights.width(), got.weights.outputs()), (64, outputs));
    assert_eq!(got.weights.levels(), levels);
    let want: Vec<Vec<f32>> = network_of(64, outputs).into_iter().map(|t| t.0).collect();
    assert_eq!(got.weights.tensors().to_vec(), want);
    for obs in [
        [0.0; 4],
        [0.01, -0.02, 0.03, 0.04],
        [-2.4, -1.5, -0.2, -2.0],
    ] {
        let (q, r) = (forward(&got.weights, obs), reference(&got.weights, obs));
        for (a, (q, r)) in q.iter().zip(&r).enumerate() {
            let err = (f64::from(*q) - r).abs();
            assert!(
                err <= 1e-6 * r.abs().max(1.0),
                "{format} {obs:?} {a}: {q} vs {r}"
            );
        }
    }
}

#[test]
fn checkpoints_of_more_outputs_import_with_the_levels_given() {
    for levels in [&FIVE[..], &SEVEN] {
        let n = levels.len();
        for (bytes, prefix, format) in files(n) {
            let got = import_with(&bytes, prefix, Some(&given(levels)))
                .unwrap_or_else(|e| panic!("{format} {n}: {e}"));
            check(&got, n, levels, format);
        }
    }
}

#[test]
fn without_levels_or_with_another_count_they_are_refused() {
    for levels in [&FIVE[..], &SEVEN] {
        let n = levels.len();
        for (bytes, prefix, format) in files(n) {
            let e = import(&bytes, prefix).unwrap_err();
            let m = e.to_string();
            assert!(e.is_input(), "{m}");
            assert!(
                m.contains(&format!("{n} outputs and its file records no duty levels"))
                    && m.contains("--levels"),
                "{format}: {m}"
            );
            // Read as the paper's two-level network, or with a level too few or too many:
            // refused.
            for k in [2, n - 1, n + 1] {
                let even = (0..k).map(|i| -1.0 + 2.0 * i as f32 / (k - 1) as f32);
                let g = given(&even.collect::<Vec<f32>>());
                let m = import_with(&bytes, prefix, Some(&g))
                    .unwrap_err()
                    .to_string();
                let want = format!("expected one level per output of the network, {n}; found");
                assert!(
                    m.starts_with("--levels [") && m.contains(&want),
                    "{format}: {m}"
                );
            }
        }
    }
}

#[test]
fn a_file_that_records_its_levels_refuses_others_and_takes_its_own_again() {
    let w = Weights::new(
        64,
        FIVE.to_vec(),
        network_of(64, 5)
            .into_iter()
            .map(|t| t.0)
            .collect::<Vec<_>>()
            .try_into()
            .unwrap(),
    )
    .unwrap();
    let file = to_safetensors(&w, &BTreeMap::new()).unwrap();
    assert_eq!(import(&file, None).unwrap().weights, w);
    let again = import_with(&file, None, Some(&given(&FIVE))).unwrap();
    assert_eq!(again.weights, w);
    let other = [-1.0, -0.5, 0.0, 0.5, 1.0];
    let m = import_with(&file, None, Some(&given(&other)))
        .unwrap_err()
        .to_string();
    assert_eq!(
        m,
        "--levels [-1, -0.5, 0, 0.5, 1]: the file records the duty levels \
         [-1, -0.2, 0, 0.2, 1]; expected those or no --levels"
    );
}

#[test]
fn a_two_output_checkpoint_drives_the_paper_levels_or_the_ones_given() {
    let bytes = onnx_model(onnx_network_fields());
    assert_eq!(import(&bytes, None).unwrap().weights.levels(), [-1.0, 1.0]);
    let half = import_with(&bytes, None, Some(&given(&[-0.5, 0.5]))).unwrap();
    assert_eq!(half.weights.levels(), [-0.5, 0.5]);
    let m = import_with(&bytes, None, Some(&given(&FIVE)))
        .unwrap_err()
        .to_string();
    assert!(m.contains("output of the network, 2; found 5"), "{m}");
}
