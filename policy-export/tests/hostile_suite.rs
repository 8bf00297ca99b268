//! `policy-export` against a table of hostile command lines: every path argument given every
//! kind of bad file, every output given every kind of place it must not write, bad names and
//! bad numbers. Each case must be refused by the rules of `docs/HOSTILE_INPUT.md`, checked
//! by the shared harness. And the files it accepts whose text reaches generated source: their
//! names must stay inside a comment.

use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::Command;

#[path = "../../host-common/tests/support/hostile.rs"]
mod hostile;
#[path = "hostile_suite/links.rs"]
mod links;

use hostile::{Bad, Case, Format, Scratch, run_all, uniform_policy, with_stdout_closed};

fn exe() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_policy-export"))
}

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path)
}

/// The shipped policy file.
fn policy() -> PathBuf {
    repo("shipped/policy.safetensors")
}

fn policy_format() -> Format {
    Format {
        valid: std::fs::read(policy()).unwrap(),
        cap: 64 << 20,
        malformed: &["expected", "safetensors"],
        fine: &[],
    }
}

fn rig_format() -> Format {
    Format {
        valid: std::fs::read(repo("rigs/desk.toml")).unwrap(),
        cap: 64 << 10,
        malformed: &["expected", "missing field"],
        fine: &[],
    }
}

fn config_format() -> Format {
    Format {
        valid: b"episodes = 1\nmax_steps = 10\n".to_vec(),
        cap: 1 << 20,
        malformed: &["expected", "TOML"],
        fine: &[Bad::Empty],
    }
}

fn os(args: &[&dyn AsRef<std::ffi::OsStr>]) -> Vec<OsString> {
    args.iter().map(|a| a.as_ref().to_owned()).collect()
}

/// Every path argument, given every kind of bad file.
fn bad_inputs(s: &Scratch) -> Vec<Case> {
    let (pf, rf, cf) = (policy_format(), rig_format(), config_format());
    let out = s.join("out.rs");
    type Slot<'a> = (&'a str, &'a Format, Box<dyn Fn(&Path) -> Vec<OsString>>);
    let p = policy();
    let (o1, o2, o3, o4) = (out.clone(), out.clone(), out.clone(), out.clone());
    let slots: Vec<Slot> = vec![
        (
            "export-rust",
            &pf,
            Box::new(move |b| os(&[&"export", &b, &"--out", &o1])),
        ),
        (
            "export-c",
            &pf,
            Box::new(move |b| os(&[&"export", &b, &"--format", &"c", &"--out", &o2])),
        ),
        (
            "export-int8",
            &pf,
            Box::new(move |b| os(&[&"export", &b, &"--quant", &"int8", &"--out", &o3])),
        ),
        (
            "export-rig",
            &rf,
            Box::new(move |b| os(&[&"export", &p, &"--rig", &b, &"--out", &o4])),
        ),
        (
            "train-config",
            &cf,
            Box::new(|b| os(&[&"train", &"--config", &b, &"--episodes", &"1"])),
        ),
        (
            "train-rig",
            &rf,
            Box::new(|b| os(&[&"train", &"--rig", &b, &"--episodes", &"1"])),
        ),
    ];
    hostile::bad_input_cases(&s.0, slots.iter().map(|(t, f, a)| (*t, *f, &**a as _)))
}

/// Places a file output must not write, each with the words its refusal must say.
fn bad_file_outputs(s: &Scratch, input: &Path) -> Vec<(String, PathBuf, &'static str)> {
    let fifo = s.join("out-fifo");
    hostile::mkfifo(&fifo);
    let dir = s.join("out-dir");
    std::fs::create_dir(&dir).unwrap();
    let file = s.join("out-file");
    std::fs::write(&file, b"keep").unwrap();
    let link = s.join("out-link");
    std::os::unix::fs::symlink(&file, &link).unwrap();
    vec![
        ("directory".into(), dir, "found a directory"),
        ("device".into(), "/dev/null".into(), "found a device"),
        ("fifo".into(), fifo, "found a FIFO"),
        ("link".into(), link, "found a symbolic link"),
        (
            "input".into(),
            input.to_path_buf(),
            "would overwrite the input",
        ),
        ("under-file".into(), file.join("x"), "found a regular file"),
        ("proc".into(), "/proc/cartpole/x".into(), "refuses"),
        (
            "root-name".into(),
            "/".into(),
            "expected an output file name",
        ),
        (
            "dot-name".into(),
            s.join("new/."),
            "expected an output file name",
        ),
    ]
}

/// Every output, given every place it must not write.
fn bad_outputs(s: &Scratch) -> Vec<Case> {
    let input = s.join("input.safetensors");
    std::fs::copy(policy(), &input).unwrap();
    let mut cases = Vec::new();
    for (label, out, want) in bad_file_outputs(s, &input) {
        for fmt in [
            &["--format", "rust"][..],
            &["--format", "c"],
            &["--quant", "int8"],
        ] {
            let mut args = os(&[&"export", &input, &"--out", &out]);
            args.extend(fmt.iter().map(OsString::from));
            cases.push(Case::new(
                format!("export {fmt:?} --out {label}"),
                &args,
                &[want],
            ));
        }
    }
    let foreign = s.join("photos");
    std::fs::create_dir(&foreign).unwrap();
    std::fs::write(foreign.join("summary.json"), b"{}").unwrap();
    let marked = s.join("marked");
    std::fs::create_dir(&marked).unwrap();
    std::fs::write(
        marked.join(".cartpole-run"),
        r#"{"tool":"policy-export","version":"0","kind":"train","entries":[
            {"path":"summary.json","bytes":2,"fnv1a64":"08f44b07b5901a25"}]}"#,
    )
    .unwrap();
    std::fs::write(marked.join("summary.json"), b"{}").unwrap();
    std::fs::write(marked.join("notes.txt"), b"mine").unwrap();
    let dirs: [(&str, PathBuf, &[&'static str]); 7] = [
        ("file", s.join("out-file"), &["it is a regular file"]),
        ("device", "/dev/null".into(), &["it is a device"]),
        ("fifo", s.join("out-fifo"), &["it is a FIFO"]),
        ("foreign", foreign, &["holds no .cartpole-run marker"]),
        // A train run's directory, with a file added: train names the file, reproduce the
        // kind.
        (
            "added-file",
            marked,
            &[
                "did not write (\"notes.txt\")",
                "marks an output of \"policy-export\" \"train\"",
            ],
        ),
        (
            "under-file",
            s.join("out-file").join("run"),
            &["found a regular file"],
        ),
        ("proc", "/proc/cartpole/run".into(), &["refuses"]),
    ];
    cases.extend(links::linked_with_a_slash(s));
    for (label, out, want) in dirs {
        for cmd in [
            &["train", "--episodes", "1"][..],
            &["train", "--episodes", "1", "--seeds", "0..2"],
            &["reproduce", "--seeds", "2", "--study", "table4"],
        ] {
            let mut args: Vec<OsString> = cmd.iter().map(OsString::from).collect();
            args.extend(os(&[&"--out", &out]));
            cases.push(Case::new(format!("{cmd:?} --out {label}"), &args, want));
        }
    }
    cases
}

/// Names no export can take.
fn bad_names(s: &Scratch) -> Vec<Case> {
    let p = policy();
    let out = s.join("named.h");
    let long = "N".repeat(100_000);
    let mut cases = Vec::new();
    let rust_names = [
        "policy",
        "RIG",
        "A-B",
        "",
        "2X",
        "POLICY\nfn",
        "_",
        "Self",
        &long,
    ];
    for name in rust_names {
        let args = os(&[&"export", &p, &"--name", &name, &"--out", &out]);
        cases.push(Case::new(
            format!("rust --name {name:?}"),
            &args,
            &["--name"],
        ));
    }
    let c_names = [
        "int",
        "cartpole_controller_init",
        "cartpole_controller_step",
        "CARTPOLE_DUTY_MAX",
        "cartpole_mlp64",
        "cartpole",
        "balance_rig",
        "int32_t",
        "a\nb",
        "__x",
        "a*/b",
        "class",
        "namespace",
        &long,
        // Names the standard headers beside the header define or reserve.
        "EOF",
        "stdout",
        "INFINITY",
        "round",
        "abs",
        "LLONG_MAX",
        "SIGINT",
        "FLT_MAX",
        "CLOCKS_PER_SEC",
        "I",
        "noreturn",
        "setjmp",
        "isnan",
        "M_PI",
    ];
    for name in c_names {
        for quant in [&[][..], &["--quant", "int8"]] {
            let mut args = os(&[
                &"export",
                &p,
                &"--format",
                &"c",
                &"--name",
                &name,
                &"--out",
                &out,
            ]);
            args.extend(quant.iter().map(OsString::from));
            cases.push(Case::new(
                format!("c --name {name:?} {quant:?}"),
                &args,
                &["--name"],
            ));
        }
    }
    cases
}

/// Prefixes that name no network, and a policy nobody can use.
fn bad_policies(s: &Scratch) -> Vec<Case> {
    let (p, out, long) = (policy(), s.join("named.h"), "N".repeat(100_000));
    let mut cases = Vec::new();
    for prefix in ["nope.", "fc", "\n", &long] {
        let args = os(&[&"export", &p, &"--prefix", &prefix, &"--out", &out]);
        cases.push(Case::new(
            format!("--prefix {prefix:?}"),
            &args,
            &["prefix"],
        ));
    }
    // Levels below f32's least subnormal were read as f32 first: a zero that passed.
    for (levels, found) in [
        ("-1,5e-324", "found 5e-324"),
        ("-5e-324,1", "found -5e-324"),
        ("-1,1e-46", "found 1e-46"),
        ("-1,1e-50", "found 1e-50"),
    ] {
        let flag = format!("--levels={levels}");
        let export = os(&[&"export", &p, &flag, &"--out", &out]);
        let train = os(&[&"train", &"--preset", &"fast", &"--print-config", &flag]);
        for (what, args) in [("export", export), ("train", train)] {
            cases.push(Case::new(format!("{what} {flag}"), &args, &[found]));
        }
    }
    // Every weight finite, every output infinite.
    let huge = s.join("huge.safetensors");
    uniform_policy(&huge, 1e30, "");
    for fmt in [
        &["--format", "rust"][..],
        &["--format", "c"],
        &["--quant", "int8"],
    ] {
        let mut args = os(&[&"export", &huge, &"--out", &out]);
        args.extend(fmt.iter().map(OsString::from));
        cases.push(Case::new(
            format!("infinite outputs {fmt:?}"),
            &args,
            &["expected finite Q-values"],
        ));
    }
    cases
}

/// Numbers no run can take.
fn bad_numbers() -> Vec<Case> {
    let mut cases = Vec::new();
    let flags = [
        "--episodes",
        "--max-steps",
        "--buffer-size",
        "--batch-size",
        "--lr",
        "--gamma",
        "--eps-start",
        "--tau",
        "--eval-episodes",
        "--seed",
        "--grad-clip",
        "--eps-end",
    ];
    // Subnormals were taken (a gamma of 5e-324, a clip of nothing), and shown in a message as
    // 320 decimal places.
    let values = [
        "-1", "abc", "", "1e999", "NaN", "1e39", "0x10", "5e-324", "1e-310",
    ];
    for flag in flags {
        for v in values {
            let args = os(&[&"train", &flag, &v]);
            cases.push(Case::new(
                format!("train {flag} {v:?}"),
                &args,
                &["invalid value", "must be", "expected"],
            ));
        }
    }
    // A tiny real shown as written, not as 300 decimal places.
    for flag in ["--gamma", "--lr", "--grad-clip", "--tau"] {
        let args = os(&[&"train", &format!("{flag}=-1e-300")]);
        cases.push(Case::new(
            format!("train {flag} -1e-300"),
            &args,
            &["-1e-300"],
        ));
    }
    // A share of 0 applies a part in no episode: the recorded domain claimed a randomisation
    // never drawn.
    for flag in ["--domain", "--eval-domain", "--finalist-domain"] {
        for v in ["noise=0..1@0", "length=0.5..0.5@-0"] {
            let args = os(&[&"train", &"--print-config", &flag, &v]);
            cases.push(Case::new(
                format!("train {flag} {v}"),
                &args,
                &[
                    "needs a share in (0, 1], normal, after @, found \"0\"",
                    "found \"-0\"",
                ],
            ));
        }
    }
    let args = os(&[&"export", &"--out", &"x.rs", &"-dash.safetensors"]);
    cases.push(Case::new(
        "export -dash.safetensors".into(),
        &args,
        &["unexpected argument '-dash.safetensors' found"],
    ));
    // A file's name that starts as the help flag does printed the help, exit 0.
    for name in ["-hello.pt", "-Vx.pt"] {
        let args = os(&[&"export", &"--out", &"x.rs", &name]);
        let want = format!("unexpected argument '{name}' found");
        cases.push(Case::new(format!("export {name}"), &args, &[want.leak()]));
    }
    for v in ["0", "1", "1001", "-3", "x", "99999999999999999999", "+3"] {
        let args = os(&[&"reproduce", &"--seeds", &v]);
        cases.push(Case::new(
            format!("reproduce --seeds {v}"),
            &args,
            &["--seeds", "invalid value", "unexpected argument"],
        ));
    }
    cases
}

#[test]
fn every_hostile_command_line_is_refused_by_the_rules() {
    let s = Scratch::new("pe-suite");
    let mut cases = bad_inputs(&s);
    cases.extend(bad_outputs(&s));
    cases.extend(bad_names(&s));
    cases.extend(bad_policies(&s));
    cases.extend(bad_numbers());
    let n = run_all(&exe(), &s.0, &cases);
    assert!(n >= 230, "{n} cases");
}

/// File names and tensor prefixes that would break out of a comment, exported as each
/// format: the text stays on its comment line, nothing of it becomes code, and the C
/// headers compile.
#[test]
fn hostile_names_and_prefixes_stay_inside_the_exported_comment() {
    let s = Scratch::new("pe-names");
    let mut sources = Vec::new();
    for (i, name) in ["a\nfn leaked() {}", "c\r\u{2028}d", "e\\"]
        .iter()
        .enumerate()
    {
        let src = s.join(&format!("{i}{name}"));
        std::fs::copy(policy(), &src).unwrap();
        sources.push(src);
    }
    for (i, prefix) in ["x */ int leaked; /* ", "y\nfn leaked() {} "]
        .iter()
        .enumerate()
    {
        let src = s.join(&format!("prefix{i}.safetensors"));
        uniform_policy(&src, 0.5, prefix);
        sources.push(src);
    }
    for (i, src) in sources.iter().enumerate() {
        for (fmt, ext) in [("rust", "rs"), ("c", "h")] {
            let out = s.join(&format!("out{i}.{ext}"));
            let o = Command::new(exe())
                .args(os(&[&"export", &src, &"--format", &fmt, &"--out", &out]))
                .output()
                .unwrap();
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            let text = std::fs::read_to_string(&out).unwrap();
            let line = text.lines().find(|l| l.contains("source: ")).unwrap();
            assert!(line.contains("hidden width"), "{line}");
            let leaks = text.lines().filter(|l| l.contains("leaked")).count();
            assert!(
                leaks <= 1 && (leaks == 0 || line.contains("leaked")),
                "{line}"
            );
            if ext == "h" {
                let ok = Command::new("cc")
                    .args(["-std=c99", "-fsyntax-only", "-x", "c"])
                    .arg(&out)
                    .status()
                    .unwrap();
                assert!(ok.success(), "{line}");
            }
        }
    }
}

#[test]
fn a_closed_standard_output_ends_the_command_quietly_and_the_run_is_kept() {
    let s = Scratch::new("pe-pipe");
    let out = s.join("run");
    for args in [
        os(&[&"train", &"--print-config"]),
        os(&[
            &"train",
            &"--episodes",
            &"2",
            &"--seeds",
            &"0..2",
            &"--out",
            &out,
        ]),
        os(&[&"export", &policy(), &"--out", &s.join("p.rs")]),
    ] {
        let (code, err) = with_stdout_closed(&exe(), &args, &s.0);
        assert_eq!(code, Some(0), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    assert!(out.join("aggregate.json").is_file() && out.join("seed-1/policy.rs").is_file());
}
