//! A number written with a non-zero digit that reads as zero (`1e-400`, below f64's range)
//! is refused wherever it comes in on the command line: every flag's own check passes a
//! zero, which turned `--grad-clip` off and made a level of "full push" the motor off.

use std::process::Command;

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
