//! Numbers on the command line that are slips, refused wherever they come in.

use std::process::Command;

/// A number below f64's range reads as zero, which every check of a part passes.
#[test]
fn a_number_that_reads_as_zero_is_refused_in_a_scenario_and_a_flag() {
    for args in [
        &[
            "eval",
            "--scenario",
            "friction=1e-400/0.1",
            "--controller",
            "lqr",
        ][..],
        &["startup", "--zero-error", "1e-400"],
    ] {
        let o = Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("1e-400 reads as 0"), "{args:?}: {err}");
    }
}
