//! `host-sim eval --policy FILE --levels ...`: a checkpoint that records no duty levels (as
//! PyTorch, Stable-Baselines3 and ONNX exporters write them) drives the levels given, one per
//! output; without them, with another count, against the levels its file records, or as a
//! list that is no list of levels, it exits 2 naming `--levels`.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

// The shared harness: its runner of refusals.
#[allow(dead_code)]
#[path = "../../host-common/tests/support/hostile.rs"]
mod hostile;

// Checkpoints made byte by byte in the layouts real tools write.
#[path = "../../weights/tests/support/build.rs"]
mod build;

use firmware::network::shapes;
use weights::Weights;
use weights::checkpoint::to_safetensors;

const FIVE: &str = "-1,-0.2,0,0.2,1";

/// A width-64 network of five outputs whose hidden units are all 0 and whose Q-values are
/// therefore its output biases: 1 for output `pick`, 0 for the others, in every state.
fn constant(pick: usize) -> [Vec<f32>; 6] {
    let mut t = shapes(64, 5).map(|s| vec![0.0; s.len()]);
    t[5][pick] = 1.0;
    t
}

/// `torch.onnx.export` of `tensors` (`Gemm`s and `Relu`s): no levels recorded.
fn onnx(tensors: &[Vec<f32>; 6]) -> Vec<u8> {
    let outputs = tensors[5].len();
    let net: Vec<_> = tensors
        .iter()
        .zip(shapes(64, outputs))
        .map(|(v, s)| {
            let bytes = v.iter().flat_map(|x| x.to_le_bytes()).collect();
            (v.clone(), bytes, s.dims().to_vec())
        })
        .collect();
    build::onnx_model(build::onnx_fields_of(&net))
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("hs-levels-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn eval(policy: &Path, extra: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["eval", "--scenario", "nominal", "--episodes", "4"])
        .args(["--controller", "policy", "--json", "--policy"])
        .arg(policy)
        .args(extra)
        .output()
        .unwrap()
}

/// The mean |duty| of the one row of `eval`'s JSON.
fn mean_abs_duty(o: &Output) -> f64 {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    json["rows"][0]["mean_abs_duty"]["mean"].as_f64().unwrap()
}

#[test]
fn an_onnx_policy_of_five_outputs_drives_the_levels_given() {
    let dir = scratch("drives");
    let file = dir.join("policy.onnx");
    std::fs::write(&file, onnx(&constant(3))).unwrap();
    // Output 3 always scores highest: the duty is the fourth level given, in every period.
    for (levels, duty) in [
        (FIVE, 0.2),
        ("-1,-0.5,0,0.5,1", 0.5),
        ("-1,-0.9,-0.8,-0.7,1", 0.7),
    ] {
        let m = mean_abs_duty(&eval(&file, &["--levels", levels]));
        assert!((m - duty).abs() < 1e-6, "{levels}: mean |duty| {m}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The linear LQR rounded to the policy's levels drives those levels and no others: with
/// levels of at least 0.7 either way its mean |duty| is at least 0.7; with fine levels about
/// a balanced pole, far less.
#[test]
fn the_rounded_lqr_drives_the_policys_levels() {
    let dir = scratch("rounded");
    let file = dir.join("policy.onnx");
    std::fs::write(&file, onnx(&constant(3))).unwrap();
    let mean = |file: &Path, levels: &str| {
        mean_abs_duty(
            &Command::new(env!("CARGO_BIN_EXE_host-sim"))
                .args(["eval", "--scenario", "nominal", "--episodes", "4"])
                .args(["--controller", "lqr-levels", "--json", "--policy"])
                .arg(file)
                .args(["--levels", levels])
                .output()
                .unwrap(),
        )
    };
    let coarse = mean(&file, "-1,-0.9,-0.8,-0.7,1");
    assert!(coarse >= 0.7 - 1e-9, "mean |duty| {coarse}");
    let fine = mean(&file, FIVE);
    assert!(fine < 0.5, "mean |duty| {fine}");
    // Two levels of half the push are no bang-bang LQR: taken, and driven.
    let half = dir.join("half.onnx");
    std::fs::write(&half, onnx(&shapes(64, 2).map(|s| vec![0.0; s.len()]))).unwrap();
    assert_eq!(mean(&half, "-0.5,0.5"), 0.5);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A refined controller, or the LQR rounded to the levels, of a policy of two levels, both
/// ends: its rows were the unrefined (or bang-bang) ones', bit for bit, without a word.
#[test]
fn a_controller_between_two_levels_is_refused() {
    for (asked, why) in [
        (
            "policy,policy-int-refined",
            "both ends, with nothing between them to refine; found policy-int-refined, which \
             would run as policy-int (run that)",
        ),
        (
            "lqr,lqr-levels-predict",
            "the full push each way, to which rounding leaves the bang-bang LQR's duty alone; \
             found lqr-levels-predict, which would run as lqr-predict (run that)",
        ),
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args(["eval", "--controller", asked])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        let head = "error: the shipped policy: its two levels are ";
        assert_eq!(err.trim_end(), format!("{head}{why}"));
        assert!(o.stdout.is_empty());
    }
}

/// Exit 2, within the refusals' processor time, with each of `want` in a short message that
/// names --levels, and nothing on stdout.
fn refused(policy: &Path, extra: &[&str], want: &[&str]) {
    let ran = hostile::run_counted(
        Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args(["eval", "--controller", "policy", "--policy"])
            .arg(policy)
            .args(extra),
    );
    let seen = format!("{extra:?}: exit {:?}: {}", ran.code, ran.stderr);
    assert_eq!(ran.code, Some(2), "{seen}");
    assert!(
        ran.stderr.contains("--levels") && ran.stderr.len() < 1_000,
        "{seen}"
    );
    assert!(want.iter().all(|w| ran.stderr.contains(w)), "{seen}");
    assert!(ran.stdout.is_empty() && ran.late().is_none(), "{seen}");
}

#[test]
fn levels_missing_miscounted_contradicted_or_malformed_exit_2_naming_the_flag() {
    let dir = scratch("refused");
    let onnx_file = dir.join("policy.onnx");
    std::fs::write(&onnx_file, onnx(&constant(3))).unwrap();
    let recorded = dir.join("policy.safetensors");
    let five = vec![-1.0, -0.2, 0.0, 0.2, 1.0];
    let w = Weights::new(64, five, constant(3)).unwrap();
    std::fs::write(&recorded, to_safetensors(&w, &Default::default()).unwrap()).unwrap();

    refused(
        &onnx_file,
        &[],
        &["5 outputs and its file records no duty levels"],
    );
    refused(
        &onnx_file,
        &["--levels", "-1,0,1"],
        &["--levels [-1, 0, 1]: expected one level per output of the network, 5; found 3"],
    );
    refused(
        &recorded,
        &["--levels", "-1,-0.5,0,0.5,1"],
        &["the file records the duty levels [-1, -0.2, 0, 0.2, 1]; expected those or no --levels"],
    );
    for (spec, says) in [
        (
            "-1,half,1",
            "expected comma-separated numbers, found \"half\"",
        ),
        ("1,0,-1", "expected strictly increasing"),
        ("", "found none"),
        // Below f32's least subnormal: read as f32, a zero that passed.
        (
            "-1,5e-324,1",
            "expected each zero or a normal number, found 5e-324",
        ),
    ] {
        refused(&onnx_file, &["--levels", spec], &[says]);
    }
    // Repeating the recorded levels is no contradiction.
    let m = mean_abs_duty(&eval(&recorded, &["--levels", FIVE]));
    assert!((m - 0.2).abs() < 1e-6, "mean |duty| {m}");
    std::fs::remove_dir_all(&dir).unwrap();
}
