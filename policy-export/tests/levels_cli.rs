//! A policy file of five duty levels through `policy-export export`: float C, int8 C and
//! int8 Rust. Each names the network's shape and carries the levels; the C headers compile
//! with the system's C compiler (`CC`, else `cc`). A number that reads as zero is refused
//! wherever the command line takes one, in a level list too: `1e-400`, below f64's range,
//! passed every check as zero, which turned `--grad-clip` off and made a level the motor off.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::process::Command;

fn scratch() -> PathBuf {
    let d = std::env::temp_dir().join(format!("pe-levels-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn a_five_level_policy_exports_to_c_and_to_int8_rust_and_c() {
    let dir = scratch();
    let levels = [-1.0, -0.4, 0.0, 0.3, 1.0];
    let w = weights::feedback::state_feedback(64, &levels, [-0.5, -1.0, -20.0, -3.0]).unwrap();
    let file = dir.join("gentle.safetensors");
    let bytes = weights::checkpoint::to_safetensors(&w, &BTreeMap::new()).unwrap();
    std::fs::write(&file, bytes).unwrap();
    let cases: [(&[&str], &str, &[&str]); 3] = [
        (
            &["--format", "c"],
            "float.h",
            &[
                "struct cartpole_mlp64x5 {",
                "static const int16_t cartpole_policy_levels[5] = {-1000, -400, 0, 300, 1000};",
                "static inline int16_t cartpole_policy_duty(const float q[5])",
            ],
        ),
        (
            &["--format", "c", "--quant", "int8"],
            "int.h",
            &[
                "struct cartpole_qmlp64x5 {",
                "_levels[5] = {-1000, -400, 0, 300, 1000};",
                "_duty(const int32_t q[5])",
            ],
        ),
        (
            &["--format", "rust", "--quant", "int8"],
            "int.rs",
            &[
                "::firmware::network::int::QMlp<64, 5> =",
                "Levels::new([-1.0, -0.4, 0.0, 0.3, 1.0])",
            ],
        ),
    ];
    for (args, out, wants) in cases {
        let out = dir.join(out);
        let o = Command::new(env!("CARGO_BIN_EXE_policy-export"))
            .arg("export")
            .arg(&file)
            .args(args)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let text = std::fs::read_to_string(&out).unwrap();
        for want in wants {
            assert!(text.contains(want), "{args:?}: {want} not in\n{text}");
        }
        if args[1] == "c" {
            let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
            let o = Command::new(&cc)
                .args(["-std=c99", "-pedantic", "-Wall", "-Wextra", "-Werror"])
                .args(["-fsyntax-only", "-x", "c"])
                .arg(&out)
                .output()
                .unwrap_or_else(|e| panic!("running {cc}: {e}"));
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_number_that_reads_as_zero_is_refused_in_every_flag_and_spec() {
    let shipped = concat!(env!("CARGO_MANIFEST_DIR"), "/../shipped/policy.safetensors");
    let out = std::env::temp_dir().join(format!("pe-numbers-{}.rs", std::process::id()));
    let out = out.to_str().unwrap();
    for (args, piece) in [
        (
            &["train", "--grad-clip", "1e-400", "--print-config"][..],
            "1e-400",
        ),
        (&["train", "--gamma=-1E-999", "--print-config"], "-1E-999"),
        (
            &[
                "train",
                "--reward",
                "upright=20+scale=1e-400",
                "--print-config",
            ],
            "1e-400",
        ),
        (
            &["export", shipped, "--out", out, "--levels=-1,10e-400"],
            "10e-400",
        ),
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_policy-export"))
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains(&format!("{piece} reads as 0")),
            "{args:?}: {err}"
        );
        assert!(o.stdout.is_empty(), "{args:?}");
    }
    assert!(!std::path::Path::new(out).exists());
}
