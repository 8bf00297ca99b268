//! Compiles `tests/main.c` against `include/cartpole_policy.h` and the static library with
//! the system C compiler, runs it, and compares its Q-values with Rust's bit for bit.

use std::path::PathBuf;
use std::process::Command;

use firmware::policy::POLICY;
use firmware::selftest::PROBES;

#[test]
fn a_c_program_gets_the_rust_q_values_through_the_header() {
    let manifest = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    // Cargo builds this package's static library beside this test, in target/<profile>/deps,
    // as libcartpole_policy-<hash>.a; the newest is the one of this build.
    let deps = std::env::current_exe()
        .unwrap()
        .parent()
        .unwrap()
        .to_path_buf();
    let lib = std::fs::read_dir(&deps)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            let name = p.file_name().unwrap().to_string_lossy();
            name.starts_with("libcartpole_policy-") && name.ends_with(".a")
        })
        .max_by_key(|p| p.metadata().and_then(|m| m.modified()).ok())
        .unwrap_or_else(|| panic!("no libcartpole_policy-*.a in {}", deps.display()));
    let out = std::env::temp_dir().join(format!("cartpole-c-{}", std::process::id()));
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let status = Command::new(&cc)
        .args(["-std=c99", "-Wall", "-Wextra", "-Werror", "-I"])
        .arg(manifest.join("include"))
        .arg(manifest.join("tests/main.c"))
        .arg(&lib)
        .args(["-lpthread", "-ldl", "-lm", "-o"])
        .arg(&out)
        .status()
        .unwrap_or_else(|e| panic!("running the C compiler `{cc}`: {e}"));
    assert!(status.success(), "C compile failed");
    // %.9g prints every float exactly enough to read back the same bits.
    let args: Vec<String> = PROBES
        .iter()
        .flatten()
        .map(|v| format!("{v:.9e}"))
        .collect();
    let run = Command::new(&out).args(&args).output().unwrap();
    assert!(run.status.success());
    let expected: String = PROBES
        .iter()
        .map(|o| {
            let q = POLICY.forward(o);
            format!("{:08x} {:08x}\n", q[0].to_bits(), q[1].to_bits())
        })
        .collect();
    assert_eq!(String::from_utf8(run.stdout).unwrap(), expected);
    std::fs::remove_file(&out).unwrap();
}
