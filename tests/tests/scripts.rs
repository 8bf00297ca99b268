//! The Python scripts (`scripts/gymnasium_check.py`, `scripts/count_insns.py`) against
//! hostile input: each refusal exits 2 within seconds of processor time with one line naming
//! what was expected, and no traceback. Every check here comes before the scripts import
//! NumPy, Gymnasium or Unicorn (the test makes those imports fail), so it runs with Python
//! alone. The emulator's instruction cap needs Unicorn, Capstone and pyelftools
//! (scripts/requirements-dev.txt), and so do the budgets the counter holds the self-test's
//! forward passes to.
//!
//! The Python is `CARTPOLE_PYTHON`, else `python3`; scripts/test.sh makes an environment with
//! the requirements and names it. A missing Python or module fails, naming what to install;
//! `CARTPOLE_SKIP_PYTHON=1` skips every test here and `CARTPOLE_SKIP_UNICORN=1` the cap's,
//! loudly.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use e2e::repo;

// The shared harness's runner of refusals.
#[allow(dead_code)]
#[path = "../../host-common/tests/support/hostile.rs"]
mod hostile;

/// The Python the scripts run on: `CARTPOLE_PYTHON` (scripts/test.sh sets it to an
/// environment with scripts/requirements-dev.txt), else `python3`. `None` only where
/// `CARTPOLE_SKIP_PYTHON=1` says to skip, which it says loudly; a Python that is missing
/// fails, naming what to install.
fn python() -> Option<String> {
    if skip("CARTPOLE_SKIP_PYTHON", "the Python scripts' tests") {
        return None;
    }
    let py = std::env::var("CARTPOLE_PYTHON").unwrap_or_else(|_| "python3".into());
    let found = Command::new(&py)
        .arg("--version")
        .stdout(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    assert!(
        found,
        "{py} not found: install Python 3 (apt-get install python3) or name one in \
         CARTPOLE_PYTHON; CARTPOLE_SKIP_PYTHON=1 skips these tests"
    );
    Some(py)
}

/// Whether `var=1` asks to skip `what`; said on standard error when it does.
fn skip(var: &str, what: &str) -> bool {
    let skip = std::env::var_os(var).is_some_and(|v| v == "1");
    if skip {
        eprintln!("SKIPPED: {var}=1, {what} not run");
    }
    skip
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("scripts-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// The modules the scripts import only once their input is checked. A refusal runs with a
/// directory first on `PYTHONPATH` where each of them ends the script saying it was
/// imported, so a check that came after the work fails, whatever the host has installed.
const LATE_IMPORTS: [&str; 5] = ["numpy", "gymnasium", "unicorn", "capstone", "elftools"];

fn poisoned_imports(dir: &Path) -> PathBuf {
    let poison = dir.join("late-imports");
    std::fs::create_dir_all(&poison).unwrap();
    for m in LATE_IMPORTS {
        let body = format!("import sys\nsys.exit('imported {m} before the check')\n");
        std::fs::write(poison.join(format!("{m}.py")), body).unwrap();
    }
    poison
}

/// Exit 2 before any of the late imports, within the refusals' processor time, one line
/// with `want`, no traceback.
fn refused(py: &str, script: &str, args: &[&str], cwd: &Path, want: &str) {
    refused_as(py, script, args, cwd, want, true);
}

/// As [`refused`], the late imports poisoned or not.
fn refused_as(py: &str, script: &str, args: &[&str], cwd: &Path, want: &str, poison: bool) {
    let mut c = Command::new(py);
    c.arg(repo().join("scripts").join(script))
        .args(args)
        .current_dir(cwd);
    if poison {
        c.env("PYTHONPATH", poisoned_imports(cwd));
    }
    let ran = hostile::run_counted(&mut c);
    let (code, err) = (ran.code, &ran.stderr);
    let seen = format!(
        "{script} {args:?}: exit {code:?} after {:?} of processor time: {err}",
        ran.cpu
    );
    assert_eq!(code, Some(2), "{seen}");
    assert!(ran.late().is_none(), "{seen}");
    assert!(err.contains(want) && !err.contains("Traceback"), "{seen}");
    assert_eq!(err.trim_end().lines().count(), 1, "{seen}");
}

/// Files no script may read as they are: a FIFO (which blocked), a device (read until
/// memory ran out), a missing file, a directory.
fn bad_files(dir: &Path) -> [(String, &'static str); 4] {
    let fifo = dir.join("fifo");
    assert!(
        Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success()
    );
    [
        (
            fifo.display().to_string(),
            "expected a regular file, found a FIFO",
        ),
        (
            "/dev/zero".into(),
            "expected a regular file, found a device",
        ),
        (dir.join("missing").display().to_string(), "No such file"),
        (dir.display().to_string(), "found a directory"),
    ]
}

#[test]
fn gymnasium_check_refuses_bad_files_counts_and_headers() {
    let Some(py) = python() else {
        return;
    };
    let dir = scratch("gym");
    let script = "gymnasium_check.py";
    for (path, want) in bad_files(&dir) {
        refused(&py, script, &["--policy", &path], &dir, want);
    }
    let counts: [(&[&str], &str); 6] = [
        (
            &["--episodes", "1000000000000"],
            "expected an integer in [1, 1000000]",
        ),
        (&["--episodes", "0"], "expected an integer in [1, 1000000]"),
        (&["--max-steps", "x"], "expected an integer, found 'x'"),
        (&["--seed", "-1"], "expected an integer in [0, 4294967295]"),
        (
            &["--episodes", "1000000", "--max-steps", "1000"],
            "expected at most 100000000 steps",
        ),
        (&["--bogus"], "unrecognized arguments"),
    ];
    for (args, want) in counts {
        refused(&py, script, args, &dir, want);
    }
    // Headers whose values are of the wrong type raised TypeError with a traceback.
    let headers = [
        (r#"{"fc1.weight":"x"}"#, "expected a tensor fc1.weight"),
        (
            r#"{"fc1.weight":{"dtype":"F32","shape":"ab","data_offsets":[0,4]}}"#,
            "expected fc1.weight with a shape and data_offsets of whole numbers",
        ),
        (r#"[1, 2]"#, "expected a JSON object as the header"),
        ("{\"a\":", "expected a safetensors JSON header"),
    ];
    for (header, want) in headers {
        let path = dir.join("h.safetensors");
        let mut bytes = (header.len() as u64).to_le_bytes().to_vec();
        bytes.extend_from_slice(header.as_bytes());
        std::fs::write(&path, bytes).unwrap();
        refused(
            &py,
            script,
            &["--policy", path.to_str().unwrap()],
            &dir,
            want,
        );
    }
    let short = dir.join("short.safetensors");
    std::fs::write(&short, (1u64 << 40).to_le_bytes()).unwrap();
    let want = "expected a safetensors header of at most 0 bytes";
    refused(
        &py,
        script,
        &["--policy", short.to_str().unwrap()],
        &dir,
        want,
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn count_insns_refuses_bad_files_counts_and_non_arm_elves() {
    let Some(py) = python() else {
        return;
    };
    let dir = scratch("insns");
    let script = "count_insns.py";
    for (path, want) in bad_files(&dir) {
        refused(&py, script, &[&path], &dir, want);
    }
    let garbage = dir.join("garbage");
    std::fs::write(&garbage, b"\x7fELF\x01").unwrap();
    let host = std::env::current_exe().unwrap();
    let (g, h) = (garbage.to_str().unwrap(), host.to_str().unwrap());
    let cases: [(&[&str], &str); 6] = [
        (&[g], "expected an ELF file"),
        (&[h], "expected a 32-bit little-endian Arm ELF"),
        (
            &[h, "--nout", "100000000"],
            "expected an integer in [1, 64]",
        ),
        (
            &[h, "--max-insns", "0"],
            "expected an integer in [1, 1000000000]",
        ),
        (&[h, "--in", "1,x"], "--in: expected at most 64 numbers"),
        (
            &[h, "--in-type", "i8", "--in", "300"],
            "--in: expected at most 64 numbers",
        ),
    ];
    for (args, want) in cases {
        refused(&py, script, args, &dir, want);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The Python with Unicorn, Capstone and pyelftools, for the counter's own runs; `None`
/// only where a `CARTPOLE_SKIP_*` variable says to skip `what`, which it says loudly.
fn unicorn_python(what: &str) -> Option<String> {
    let py = python()?;
    if skip("CARTPOLE_SKIP_UNICORN", what) {
        return None;
    }
    let has_unicorn = Command::new(&py)
        .args(["-c", "import unicorn, capstone, elftools"])
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    assert!(
        has_unicorn,
        "{py} cannot import Unicorn, Capstone and pyelftools: install \
         scripts/requirements-dev.txt (`python3 -m venv .venv && .venv/bin/pip install -r \
         scripts/requirements-dev.txt`, then CARTPOLE_PYTHON=.venv/bin/python; scripts/test.sh \
         does so), or set CARTPOLE_SKIP_UNICORN=1 to skip this test"
    );
    Some(py)
}

/// With Unicorn installed: a function that never returns is stopped at the cap and reported.
#[test]
fn count_insns_stops_a_function_that_never_returns() {
    let Some(py) = unicorn_python("the instruction counter's cap") else {
        return;
    };
    let dir = scratch("loop");
    let elf = dir.join("loop.elf");
    std::fs::write(&elf, looping_elf()).unwrap();
    let (e, cap) = (elf.to_str().unwrap(), "5000");
    let want = "spin: expected it to return within --max-insns 5000 instructions";
    refused_as(
        &py,
        "count_insns.py",
        &[e, "spin", "--max-insns", cap],
        &dir,
        want,
        false,
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A minimal Arm ELF: one loadable segment at 0 holding a Thumb `b .` (0xe7fe), and a
/// symbol table naming it `spin`, a function.
fn looping_elf() -> Vec<u8> {
    let le16 = |v: u16| v.to_le_bytes().to_vec();
    let le32 = |v: u32| v.to_le_bytes().to_vec();
    // Layout: ELF header (52), program header (32), code (4), .symtab (2 x 16),
    // .strtab, .shstrtab, then 4 section headers (40 each).
    let code = [0xfe, 0xe7, 0x00, 0xbf];
    let strtab = b"\0spin\0";
    let shstrtab = b"\0.symtab\0.strtab\0.shstrtab\0";
    let (code_off, sym_off) = (84u32, 88u32);
    let str_off = sym_off + 32;
    let shstr_off = str_off + strtab.len() as u32;
    let sh_off = (shstr_off + shstrtab.len() as u32 + 3) & !3;
    let mut b = b"\x7fELF\x01\x01\x01".to_vec();
    b.resize(16, 0);
    b.extend([le16(2), le16(40), le32(1), le32(1), le32(52), le32(sh_off)].concat());
    b.extend(
        [
            le32(0x0500_0000),
            le16(52),
            le16(32),
            le16(1),
            le16(40),
            le16(4),
            le16(3),
        ]
        .concat(),
    );
    // PT_LOAD: offset, vaddr, paddr, filesz, memsz, flags (R+X), align.
    b.extend(
        [
            le32(1),
            le32(code_off),
            le32(0),
            le32(0),
            le32(4),
            le32(4),
            le32(5),
            le32(4),
        ]
        .concat(),
    );
    b.extend(code);
    b.extend([0u8; 16]);
    // spin: name 1, value 1 (Thumb), size 4, info FUNC|GLOBAL, section 0xfff1 (absolute).
    b.extend([le32(1), le32(1), le32(4), vec![0x12, 0], le16(0xfff1)].concat());
    b.extend(strtab);
    b.extend(shstrtab);
    b.resize(sh_off as usize, 0);
    b.extend([0u8; 40]);
    let section =
        |name: u32, kind: u32, off: u32, size: u32, link: u32, info: u32, entsize: u32| {
            [
                le32(name),
                le32(kind),
                le32(0),
                le32(0),
                le32(off),
                le32(size),
                le32(link),
                le32(info),
                le32(1),
                le32(entsize),
            ]
            .concat()
        };
    b.extend(section(1, 2, sym_off, 32, 2, 1, 16));
    b.extend(section(9, 3, str_off, strtab.len() as u32, 0, 0, 0));
    b.extend(section(17, 3, shstr_off, shstrtab.len() as u32, 0, 0, 0));
    b
}

/// Instructions one call of `symbol` in the self-test's image for `target` runs on `cpu`,
/// the most over `inputs`, as `scripts/count_insns.py` counts them.
fn most_insns(py: &str, target: &str, symbol: &str, int: bool, inputs: &[&str]) -> u64 {
    let elf = e2e::build_app("selftest-app", Some(target));
    let cpu = if target.starts_with("thumbv6m") {
        "m0"
    } else {
        "m4"
    };
    let types: &[&str] = if int {
        &["--in-type", "i16", "--out-type", "i32"]
    } else {
        &[]
    };
    let count = |input: &&str| {
        let out = Command::new(py)
            .arg(repo().join("scripts/count_insns.py"))
            .arg(&elf)
            .args([
                symbol,
                "--cpu",
                cpu,
                "--nout",
                "9",
                &format!("--in={input}"),
            ])
            .args(types)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{symbol} on {cpu}: {text}{out:?}");
        let n = text
            .lines()
            .find_map(|l| l.strip_prefix("instructions: "))
            .and_then(|l| l.split(' ').next()?.parse().ok());
        n.unwrap_or_else(|| panic!("{symbol} on {cpu}: no count in {text}"))
    };
    inputs.iter().map(count).max().unwrap()
}

/// The forward passes within the budgets `docs/PERFORMANCE_MCU.md` states, for the shipped
/// two-output policy and the nine-level desk policy alike: the f32 one on the Cortex-M4F
/// within 10,000 instructions, the integer one on the Cortex-M0 within 25,000, wherever the
/// reading lies (ReLU's zeros and the integer clamps take other paths), and so the
/// nine-level one with its refinement between the levels, as the desk board runs it.
#[test]
fn the_forward_passes_keep_their_instruction_budgets() {
    let Some(py) = unicorn_python("the forward passes' instruction budgets") else {
        return;
    };
    let floats = [
        "0.5,-1,0.25,2",
        "0,0,0,0",
        "0.01,-0.02,0.03,0.04",
        "-2.4,-1.5,-0.2,-2",
    ];
    let ints = [
        "41,-82,123,164",
        "0,0,0,0",
        "2048,-4096,1024,8192",
        "-9830,-6144,-819,-8192",
    ];
    for symbol in ["selftest_forward", "selftest_forward_levels"] {
        let n = most_insns(&py, "thumbv7em-none-eabihf", symbol, false, &floats);
        assert!(
            n <= 10_000,
            "{symbol}: {n} instructions on the M4F, budget 10,000"
        );
    }
    let mut levels_int = 0;
    for symbol in ["selftest_forward_int", "selftest_forward_levels_int"] {
        let n = most_insns(&py, "thumbv6m-none-eabi", symbol, true, &ints);
        assert!(
            n <= 25_000,
            "{symbol}: {n} instructions on the M0, budget 25,000"
        );
        levels_int = n;
    }
    // Refining a choice in integers: the chosen output, its rises below and above. Soft
    // floats took about 2,000.
    let decisions = ["5,3,1,0", "5,0,7,0", "1,32767,32767,0", "4,1,32767,0"];
    let n = most_insns(
        &py,
        "thumbv6m-none-eabi",
        "selftest_refine_int",
        true,
        &decisions,
    );
    assert!(
        n <= 1_000,
        "refining: {n} instructions on the M0, budget 1,000"
    );
    // The desk board runs both: the goal's forward pass "with the chosen levels".
    assert!(
        levels_int + n <= 25_000,
        "the nine-level forward pass and its refinement: {levels_int} + {n} instructions on \
         the M0, budget 25,000"
    );
}

/// A whole balancing period of the desk board on the Cortex-M0 (the start-up around the
/// controller: counts, the watching observer, the predictor, the nine-level integer network,
/// the bridge) within a fifth of its 20 ms period at 16 MHz, one instruction a cycle: 64,000
/// instructions. Two runs from power-on differ by 80 balancing periods, the set-up cancelled.
#[test]
fn a_balancing_period_with_the_start_up_takes_under_a_fifth_of_the_m0s_period() {
    let Some(py) = unicorn_python("the start-up period's instruction budget") else {
        return;
    };
    let symbol = "selftest_startup_periods";
    let runs = |periods: &str| most_insns(&py, "thumbv6m-none-eabi", symbol, true, &[periods]);
    let (short, long) = (runs("80,0,0,0"), runs("160,0,0,0"));
    let per_period = (long - short) / 80;
    assert!(
        (20_000..=64_000).contains(&per_period),
        "{per_period} instructions a balancing period on the M0, budget 64,000"
    );
}
