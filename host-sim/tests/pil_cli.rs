//! `eval --pil` against bad input before any work (a place that is none, flags that do not
//! go with it) and against targets that misbehave on the link (silence, an early exit, an
//! echo, garbage, a truncated, oversized, replayed or other version's frame, a refusal,
//! another policy): each refused by the rules of `docs/HOSTILE_INPUT.md` (exit 2, a message
//! naming what was expected, nothing on standard output, no file touched); a silent one
//! within the timeout given.

use std::ffi::OsString;
use std::os::unix::ffi::OsStrExt;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};

// The shared harness; the file-making half of it is the other suites'.
#[allow(dead_code)]
#[path = "../../host-common/tests/support/hostile.rs"]
mod hostile;

use firmware::link::{Format, Info, MAX_FRAME, Message, Packet, Reason, frame};
use hostile::{Case, Scratch, run_all};

fn exe() -> PathBuf {
    PathBuf::from(env!("CARGO_BIN_EXE_host-sim"))
}

/// A program at `dir/name` that writes `bytes` and then waits, as a target that answered
/// the first request so and then fell silent.
fn target(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let data = dir.join(format!("{name}.bin"));
    std::fs::write(&data, bytes).unwrap();
    let script = dir.join(name);
    let body = format!("#!/bin/sh\ncat '{}'\nexec sleep 30\n", data.display());
    std::fs::write(&script, body).unwrap();
    std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755)).unwrap();
    script
}

fn wire(seq: u16, message: Message) -> Vec<u8> {
    let mut out = [0u8; MAX_FRAME];
    let n = frame::encode(&Packet { seq, message }, &mut out);
    out[..n].to_vec()
}

/// Frames a target could answer the Hello (request 1) with, and what each must be called.
fn answers() -> Vec<(&'static str, Vec<u8>, &'static str)> {
    let info = Info {
        format: Format::F32,
        hidden: 64,
        policy: 1,
        rig: 2,
        period_ns: 20_000_000,
        clock_hz: 1,
    };
    let good = wire(1, Message::Info(info));
    let mut truncated = good.clone();
    truncated.remove(3);
    // A Started of version 1, its CRC right.
    let payload = [1, 0x82, 1, 0];
    let raw = [
        &payload[..],
        &firmware::link::crc::crc32(&payload).to_le_bytes(),
    ]
    .concat();
    let mut version = [0u8; MAX_FRAME];
    let n = firmware::link::cobs::encode(&raw, &mut version).unwrap();
    let version = [&version[..n], &[0]].concat();
    vec![
        ("silent", Vec::new(), "did not answer within 0.5 s"),
        ("garbage", b"garbage\0".to_vec(), "corrupted answer"),
        ("truncated", truncated, "corrupted answer"),
        (
            "oversized",
            [vec![0x55; 100], vec![0]].concat(),
            "longer than the longest",
        ),
        ("version", version, "another protocol version"),
        (
            "replayed",
            wire(7, Message::Info(info)),
            "numbered 7 to request 1",
        ),
        (
            "refusing",
            wire(1, Message::Refused(Reason::Unsupported)),
            "refused",
        ),
        ("other-policy", good, "holds another policy"),
    ]
}

/// `eval` of one nominal episode, then `rest`.
fn eval(rest: &[&dyn AsRef<std::ffi::OsStr>]) -> Vec<OsString> {
    let head: [&dyn AsRef<std::ffi::OsStr>; 5] =
        [&"eval", &"--episodes", &"1", &"--scenario", &"nominal"];
    head.iter()
        .chain(rest)
        .map(|a| a.as_ref().to_owned())
        .collect()
}

/// Places and flags the rules refuse before any target answers.
/// What a target cannot run: a controller other than its policy's, a policy file, a
/// monitor without an envelope, refined levels of two, an envelope file, a shipped policy it
/// lacks.
fn bad_controllers(echo: &str) -> Vec<Case> {
    vec![
        Case::new(
            "a baseline".into(),
            &eval(&[&"--pil", &echo, &"--controller", &"lqr"]),
            &[
                "runs the controllers policy, policy-int, policy-refined, policy-int-refined, \
                 monitored, monitored-int, found --controller lqr",
            ],
        ),
        Case::new(
            "a refined policy of two levels, both ends".into(),
            &eval(&[&"--pil", &echo, &"--controller", &"policy,policy-refined"]),
            &[
                "--pil-policy shipped: its two levels are both ends, with nothing between them \
               to refine; found policy-refined, which would run as policy (run that)",
            ],
        ),
        Case::new(
            "a policy file".into(),
            &eval(&[&"--pil", &echo, &"--policy", &"/bin/cat"]),
            &["compiled into the target"],
        ),
        Case::new(
            "an envelope file".into(),
            &eval(&[&"--pil", &echo, &"--envelope", &"/bin/cat"]),
            &["envelope compiled into the target's application, found --envelope"],
        ),
        Case::new(
            "a monitor without an envelope".into(),
            &eval(&[
                &"--pil",
                &echo,
                &"--pil-policy",
                &"desk",
                &"--controller",
                &"policy-int,monitored-int",
            ]),
            &["--pil-policy desk: no envelope"],
        ),
        Case::new(
            "an unknown shipped policy".into(),
            &eval(&[&"--pil", &echo, &"--pil-policy", &"gym"]),
            &["--pil-policy"],
        ),
    ]
}

fn bad_places(s: &Scratch) -> Vec<Case> {
    let (echo, m0) = ("exec:/bin/cat", "qemu:thumbv6m-none-eabi");
    // A program whose name is not UTF-8 is started (and ends at once), not refused unread.
    let odd = s
        .join("t")
        .with_file_name(std::ffi::OsStr::from_bytes(b"t\xff"));
    std::fs::copy("/bin/true", &odd).unwrap();
    let mut odd_place = OsString::from("exec:");
    odd_place.push(&odd);
    std::fs::write(s.join("garbage.elf"), [0x5a; 64]).unwrap();
    vec![
        Case::new(
            "a program named in bytes that are not UTF-8".into(),
            &eval(&[&"--pil", &odd_place]),
            &["ended", "closed the link"],
        ),
        Case::new(
            "no place".into(),
            &eval(&[&"--pil", &"usb"]),
            &["qemu:TARGET"],
        ),
        Case::new(
            "unknown target".into(),
            &eval(&[&"--pil", &"qemu:avr"]),
            &["must be one of"],
        ),
        Case::new(
            "missing elf".into(),
            &eval(&[&"--pil", &m0, &"--pil-elf", &s.join("none")]),
            &["no application at"],
        ),
        Case::new(
            "an application that is no ELF file, which QEMU ran".into(),
            &eval(&[&"--pil", &m0, &"--pil-elf", &s.join("garbage.elf")]),
            &[
                "expected a 32-bit little-endian ELF application for Arm (thumbv6m-none-eabi), found no",
            ],
        ),
        Case::new(
            "missing program".into(),
            &eval(&[&"--pil", &"exec:/no/such"]),
            &["no program"],
        ),
        Case::new(
            "elf for exec".into(),
            &eval(&[&"--pil", &echo, &"--pil-elf", &"/bin/cat"]),
            &["goes with --pil qemu"],
        ),
        Case::new(
            "no timeout".into(),
            &eval(&[&"--pil", &echo, &"--pil-timeout", &"0"]),
            &["must lie in"],
        ),
        Case::new(
            "a subnormal timeout, no time at all".into(),
            &eval(&[&"--pil", &echo, &"--pil-timeout", &"5e-324"]),
            &["a normal number"],
        ),
        Case::new(
            "an echo".into(),
            &eval(&[&"--pil", &echo, &"--pil-timeout", &"600"]),
            &["where Info was due"],
        ),
        Case::new(
            "an early exit".into(),
            &eval(&[&"--pil", &"exec:/bin/true"]),
            // Which the host sees first: the exit, or its output closing.
            &["ended", "closed the link"],
        ),
    ]
}

#[test]
fn bad_places_and_misbehaving_targets_are_refused_by_the_rules() {
    let s = Scratch::new("pil-cli");
    let mut cases = bad_places(&s);
    cases.extend(bad_controllers("exec:/bin/cat"));
    let dir = s.join("targets");
    std::fs::create_dir(&dir).unwrap();
    // A target that writes escape sequences and forged lines on its standard error: shown
    // escaped (the harness refuses any raw control character), named as the target's.
    let noisy = dir.join("noisy");
    let body = "#!/bin/sh\nprintf '\\033[2J error: forged\\n' >&2\nexit 3\n";
    std::fs::write(&noisy, body).unwrap();
    std::fs::set_permissions(&noisy, std::fs::Permissions::from_mode(0o755)).unwrap();
    let place = format!("exec:{}", noisy.display());
    let says = "noisy says: \"\\u{1b}[2J error: forged\"";
    cases.push(Case::new(
        "noisy".into(),
        &eval(&[&"--pil", &place]),
        &[says],
    ));
    // A bare name is the file checked in the working directory, not one the search path
    // finds (it was looked for there, and not found).
    std::fs::copy(&noisy, s.join("bare")).unwrap();
    cases.push(Case::new(
        "a bare name".into(),
        &eval(&[&"--pil", &"exec:bare"]),
        &["bare says: \"\\u{1b}[2J error: forged\""],
    ));
    // A script whose interpreter is missing: "No such file or directory" named the script,
    // which was there.
    let orphan = dir.join("orphan");
    std::fs::write(&orphan, "#!/nonexistent/interpreter\n").unwrap();
    std::fs::set_permissions(&orphan, std::fs::Permissions::from_mode(0o755)).unwrap();
    cases.push(Case::new(
        "no interpreter".into(),
        &eval(&[&"--pil", &format!("exec:{}", orphan.display())]),
        &["the program that runs it (its #! line's interpreter, or its loader) was not found"],
    ));
    for (name, bytes, want) in answers() {
        let place = format!("exec:{}", target(&dir, name, &bytes).display());
        // Only the silent target is to be timed out. The others' bytes must decide however
        // late a busy host runs them, so their wait outlasts the harness's watchdog.
        let timeout = if bytes.is_empty() { "0.5" } else { "600" };
        let args = eval(&[&"--pil", &place, &"--pil-timeout", &timeout]);
        cases.push(Case::new(name.into(), &args, &[want]));
    }
    let n = run_all(&exe(), &s.0, &cases);
    assert_eq!(n, cases.len());
}

/// The target holds its own policy and rig: with `--pil-policy desk --rig` of the desk, no
/// warning that the policy was trained for another rig (the shipped policy's, never run).
#[test]
fn a_target_of_its_own_rig_draws_no_warning_of_another() {
    let desk = Path::new(env!("CARGO_MANIFEST_DIR")).join("../rigs/desk-identified.toml");
    let out = std::process::Command::new(exe())
        .args(eval(&[
            &"--pil",
            &"exec:/bin/true",
            &"--pil-policy",
            &"desk",
            &"--rig",
            &desk,
        ]))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    // Which the host sees first: the exit, or its output closing.
    let ended = [
        "ended (exit status: 0) without answering",
        "closed the link",
    ];
    assert!(ended.iter().any(|e| err.contains(e)), "{err}");
    assert!(!err.contains("trained for another rig"), "{err}");
}

/// A target's own children end with it: a script's `sleep` outlived the run, reparented; so
/// did a daemon that forked twice and started a session of its own.
#[test]
fn a_targets_children_end_with_it() {
    let s = Scratch::new("pil-group");
    let (script, pid, daemon) = (s.join("sleeper"), s.join("pid"), s.join("daemon"));
    // It answers by echoing, refused at once, once its child and its daemon have started
    // and been written down: no timeout to race on a busy host.
    let body = format!(
        "#!/bin/sh\nsleep 30 &\necho $! > '{pid}'\n\
         ( setsid sh -c 'echo $$ > \"{daemon}\"; exec sleep 30' & )\n\
         while [ ! -s '{daemon}' ]; do :; done\nexec cat\n",
        pid = pid.display(),
        daemon = daemon.display()
    );
    std::fs::write(&script, body).unwrap();
    std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755)).unwrap();
    let place = format!("exec:{}", script.display());
    let args = eval(&[&"--pil", &place, &"--pil-timeout", &"600"]);
    let out = std::process::Command::new(exe())
        .args(args)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("where Info was due"), "{err}");
    for file in [&pid, &daemon] {
        let child = std::fs::read_to_string(file).unwrap();
        let ended = ended_or_killed(child.trim());
        assert!(ended.is_ok(), "{}: {child}: {ended:?}", file.display());
    }
}

/// Whether a process is gone, a zombie nobody has reaped yet, or holds a KILL it has not yet
/// been scheduled to act on (a busy host showed it running just after the kill): no longer
/// running either way, with no wait to race.
fn ended_or_killed(pid: &str) -> Result<(), String> {
    let Ok(status) = std::fs::read_to_string(format!("/proc/{pid}/status")) else {
        return Ok(());
    };
    let field = |name: &str| {
        let line = status.lines().find(|l| l.starts_with(name));
        line.and_then(|l| u64::from_str_radix(l[name.len()..].trim(), 16).ok())
    };
    let kill_bit = 1 << (9 - 1);
    let pending = field("SigPnd:").unwrap_or(0) | field("ShdPnd:").unwrap_or(0);
    let zombie = status.lines().any(|l| l.starts_with("State:\tZ"));
    if zombie || pending & kill_bit != 0 {
        Ok(())
    } else {
        Err(status)
    }
}
