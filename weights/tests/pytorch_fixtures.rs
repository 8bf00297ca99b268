//! Checkpoints written by real PyTorch and Stable-Baselines3 code (`tests/fixtures/`, made by
//! `make_fixtures.py`): safetensors, `torch.save` zips, SB3's `model.zip` and ONNX from both
//! of `torch.onnx.export`'s exporters. Each imports as its layout says, and the imported
//! network computes the Q-values PyTorch itself computed (in f64) for the same observations.

use std::path::PathBuf;

use firmware::network::Mlp;
use weights::checkpoint::{self, Format, Import};

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn expected() -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(fixture("expected.json")).unwrap()).unwrap()
}

/// The imported network's Q-values against PyTorch's: f32 arithmetic in another summation
/// order, so within f32 rounding of the values' size, and within 1e-6 absolute.
fn check_q_values(file: &str, got: &Import) {
    let doc = expected();
    let obs: Vec<[f32; 4]> = doc["observations"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| core::array::from_fn(|i| o[i].as_f64().unwrap() as f32))
        .collect();
    let want = &doc["files"][file][&got.prefix];
    assert!(
        want.is_array(),
        "{file}: no expected Q-values for {:?}",
        got.prefix
    );
    let q = |o: &[f32; 4]| -> [f32; 2] {
        match got.weights.width() {
            16 => got.weights.to_mlp::<16, 2>().unwrap().forward(o),
            64 => got.weights.to_mlp::<64, 2>().unwrap().forward(o),
            w => panic!("no fixture has width {w}"),
        }
    };
    for (k, o) in obs.iter().enumerate() {
        let q = q(o);
        for a in 0..2 {
            let w = want[k][a].as_f64().unwrap();
            let err = (f64::from(q[a]) - w).abs();
            assert!(
                err <= 1e-6 && err <= 1e-5 * w.abs().max(1.0),
                "{file} obs {k} action {a}: {} vs {w}",
                q[a]
            );
        }
    }
}

#[test]
fn pytorch_layouts_import_and_compute_pytorchs_q_values() {
    for (file, prefix, layers, width) in [
        ("fc_named.safetensors", "", ["fc1", "fc2", "fc3"], 16),
        ("sequential.safetensors", "", ["0", "2", "4"], 16),
        ("sequential64.safetensors", "", ["0", "2", "4"], 64),
        ("cleanrl.safetensors", "network.", ["0", "2", "4"], 16),
        ("sb3_q_net.safetensors", "q_net.", ["0", "2", "4"], 16),
    ] {
        let got = checkpoint::load(&fixture(file), None).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert_eq!(got.prefix, prefix, "{file}");
        assert_eq!(got.layers, layers.map(String::from), "{file}");
        assert_eq!(got.weights.width(), width, "{file}");
        check_q_values(file, &got);
    }
}

#[test]
fn an_sb3_policy_holds_two_networks_and_each_can_be_chosen() {
    let path = fixture("sb3_policy.safetensors");
    let e = checkpoint::load(&path, None).unwrap_err();
    let msg = e.to_string();
    assert!(e.is_input());
    assert!(
        msg.contains("2 networks found, under the prefixes q_net.q_net., q_net_target.q_net."),
        "{msg}"
    );
    let online = checkpoint::load(&path, Some("q_net.q_net.")).unwrap();
    let target = checkpoint::load(&path, Some("q_net_target.q_net.")).unwrap();
    assert_eq!((online.ignored, target.ignored), (6, 6));
    assert_ne!(online.weights, target.weights);
    check_q_values("sb3_policy.safetensors", &online);
    check_q_values("sb3_policy.safetensors", &target);
    // The same online network as the q_net-only file.
    let alone = checkpoint::load(&fixture("sb3_q_net.safetensors"), None).unwrap();
    assert_eq!(online.weights, alone.weights);
}

#[test]
fn cleanrls_default_widths_are_refused_with_the_reason() {
    let e = checkpoint::load(&fixture("cleanrl_default.safetensors"), None).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("cleanrl_default.safetensors")
            && msg.contains("prefix \"network.\": hidden widths 120 and 84 differ"),
        "{msg}"
    );
}

#[test]
fn a_run_directory_reads_its_policy_file() {
    let dir = std::env::temp_dir().join(format!("weights-rundir-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(
        fixture("sequential64.safetensors"),
        dir.join("policy.safetensors"),
    )
    .unwrap();
    let got = checkpoint::load(&dir, None).unwrap();
    let net: Box<Mlp<64>> = got.weights.to_mlp().unwrap();
    assert_eq!(net.fc1_weight[0][0], got.weights.tensors()[0][0]);
    std::fs::remove_dir_all(&dir).unwrap();
}

fn load(file: &str, prefix: Option<&str>) -> Import {
    checkpoint::load(&fixture(file), prefix).unwrap_or_else(|e| panic!("{file}: {e}"))
}

fn refusal(file: &str) -> String {
    let e = checkpoint::load(&fixture(file), None).unwrap_err();
    assert!(e.is_input(), "{file}: {e}");
    e.to_string()
}

#[test]
fn torch_save_zips_and_onnx_exports_import_and_compute_pytorchs_q_values() {
    for (file, format, prefix, width) in [
        ("sequential64.pth", Format::TorchZip, "", 64),
        ("sequential64_protocol4.pth", Format::TorchZip, "", 64),
        ("cleanrl.cleanrl_model", Format::TorchZip, "network.", 16),
        ("fc_named_f64.pth", Format::TorchZip, "", 16),
        ("fc_strided.pth", Format::TorchZip, "", 16),
        ("sequential64_gemm.onnx", Format::Onnx, "", 64),
        ("sequential64_matmul.onnx", Format::Onnx, "", 64),
    ] {
        let got = load(file, None);
        assert_eq!(
            (got.format, got.prefix.as_str()),
            (format, prefix),
            "{file}"
        );
        assert_eq!(got.weights.width(), width, "{file}");
        check_q_values(file, &got);
    }
    assert_eq!(
        load("fc_named_f64.pth", None).converted_from.as_deref(),
        Some("F64")
    );
}

#[test]
fn every_format_of_one_network_gives_the_same_bits() {
    let reference = load("sequential64.safetensors", None).weights;
    for file in [
        "sequential64.pth",
        "sequential64_protocol4.pth",
        "sequential64_gemm.onnx",
        "sequential64_matmul.onnx",
    ] {
        assert_eq!(load(file, None).weights, reference, "{file}");
    }
    // A state dict of transposed views reads through its strides to the module's values.
    assert_eq!(
        load("fc_strided.pth", None).weights,
        load("fc_named.safetensors", None).weights
    );
    assert_eq!(
        load("cleanrl.cleanrl_model", None).weights,
        load("cleanrl.safetensors", None).weights
    );
}

#[test]
fn an_sb3_model_zip_reads_its_policy_and_asks_which_network() {
    let msg = refusal("sb3_dqn.zip");
    assert!(
        msg.contains("2 networks found, under the prefixes q_net.q_net., q_net_target.q_net."),
        "{msg}"
    );
    for prefix in ["q_net.q_net.", "q_net_target.q_net."] {
        let got = load("sb3_dqn.zip", Some(prefix));
        assert_eq!(got.format, Format::Sb3Zip);
        check_q_values("sb3_dqn.zip", &got);
        let same = load("sb3_policy.safetensors", Some(prefix));
        assert_eq!(got.weights, same.weights, "{prefix}");
    }
}

#[test]
fn a_pickle_that_asks_for_another_global_is_refused_by_name() {
    let msg = refusal("evil.pth");
    assert!(msg.contains("refused global \"posix.system\""), "{msg}");
}

#[test]
fn an_onnx_graph_with_another_operator_is_refused_by_name() {
    let msg = refusal("tanh.onnx");
    assert!(
        msg.contains("(\"Tanh\") is not part of a 4-H-H-2 Q-network"),
        "{msg}"
    );
}
