//! The processor-in-the-loop application (`selftest-app`'s `pil`) on every microcontroller
//! target in QEMU, driven by the twin's world over the link: every answer must equal the
//! same target code's run here, period by period, in both formats, with encoders, faults
//! and dead time; the application built for the host must give `eval`'s rows; and so must
//! a board on the far end of a serial port (a pseudo-terminal pair). The C application
//! (`capi/c-app`) on the Cortex-M4F must answer as the Rust one. Under the runtime monitor
//! too, through a frozen encoder; refined between the nine levels of the desk policy, and
//! refused for the shipped policy's two.
//!
//! Needs QEMU as `qemu.rs` does; `CARTPOLE_SKIP_QEMU=1` skips the QEMU part, loudly.

use std::cell::RefCell;
use std::collections::BTreeSet;
use std::process::Command;
use std::rc::Rc;
use std::time::Duration;

use e2e::{build_app, mcu_targets, repo, runners};
use firmware::controller::Command as Drive;
use firmware::link::{Format, Info, Message, Scores, Sensing, Start};
use host_sim::eval::{self, ControllerKind, Net, Row};
use host_sim::pil::link::{Remote, Session};
use host_sim::pil::{Board, Check, ICOUNT, MACHINES, Place, handshake, run_row};
use serialport::SerialPort;
use twin::Scenario;

/// How long the host waits for one answer: a watchdog against a target that hangs, far
/// beyond the milliseconds an answer takes (QEMU's start-up included) on a busy host, and no
/// verdict on speed.
const WATCHDOG: Duration = Duration::from_secs(120);

fn reference() -> Session<Box<dyn Remote>> {
    Session::new(Board::Shipped.reference())
}

/// Encoders through the observer with dropped readings and restarts, and the exact state
/// with noise, dead time and pushes.
fn scenarios() -> Vec<Scenario> {
    ["encoder+drop=40+reset=150", "noise+delay+push"]
        .map(|s| Scenario::parse(s).unwrap())
        .into()
}

/// The same machines, and the same virtual time.
#[test]
fn the_pil_machines_are_the_self_tests_machines() {
    let runners = runners();
    assert_eq!(
        MACHINES.map(|m| m.target).to_vec(),
        mcu_targets(),
        "one machine per target, in rust-toolchain.toml's order"
    );
    for m in &MACHINES {
        let (_, runner) = runners.iter().find(|(t, _)| t == m.target).unwrap();
        let want = std::iter::once(m.program).chain(m.args.iter().copied());
        let words: Vec<&str> = runner.split_whitespace().collect();
        for w in want {
            assert!(
                words.contains(&w),
                "{}: `{w}` is not in its runner `{runner}`",
                m.target
            );
        }
        assert!(
            words.windows(2).any(|w| w == ["-icount", ICOUNT]),
            "{}: its runner `{runner}` does not give `-icount {ICOUNT}`",
            m.target
        );
    }
}

#[test]
fn on_every_target_the_pil_application_answers_as_the_controller_here() {
    if skip_qemu() {
        return;
    }
    let scenarios = scenarios();
    for target in mcu_targets() {
        let elf = build_app("pil", Some(&target));
        let place = Place::parse(format!("qemu:{target}"), Some(&elf), Board::Shipped).unwrap();
        let mut remote = Session::new(place.start(WATCHDOG).unwrap());
        let mut here = reference();
        for format in [Format::F32, Format::Int8] {
            let info =
                handshake(&mut remote, &mut here, format, &scenarios, Board::Shipped).unwrap();
            for s in &scenarios {
                let what = format!("{target} {format:?} {}", s.name);
                let run = (&info, ControllerKind::Policy);
                let check = two_episodes_agree(&mut remote, &mut here, run, s, &what);
                let [median, _, worst] = check.time_ns;
                assert!(median > 0, "{what}: the target's clock did not move");
                // Under -icount the time counts instructions: with an FPU, or in integers,
                // the period fits; on the Cortex-M0 the integer pipeline with its observer
                // fits in a fifth of it (docs/PIL.md).
                let fpu = target.ends_with("eabihf");
                if fpu || format == Format::Int8 {
                    assert_eq!(check.overruns, 0, "{what}: {check:?}");
                }
                if target == "thumbv6m-none-eabi" && format == Format::Int8 {
                    assert!(5 * worst < u64::from(info.period_ns), "{what}: {check:?}");
                }
            }
            monitored_row(
                &mut remote,
                &mut here,
                &info,
                &format!("{target} {format:?}"),
            );
        }
    }
}

/// Two episodes of 200 periods of `scenario` on the target and here, run by the controller
/// `kind`: both run whole, and no answer of the target's differs from the reference's.
fn two_episodes_agree(
    remote: &mut Session<impl Remote>,
    here: &mut Session<impl Remote>,
    run: (&Info, ControllerKind),
    scenario: &Scenario,
    what: &str,
) -> Check {
    let (eps, check) = run_row(remote, here, run, scenario, 200, 0, 2, || ()).unwrap();
    assert_eq!(eps.len(), 2, "{what}");
    assert!(check.periods >= 200, "{what}: {check:?}");
    assert_eq!(check.mismatches, 0, "{what}: {check:?}");
    check
}

/// What the answers of a run said: the duties driven (thousandths; coasting is none) and how
/// many scores each answer carried.
#[derive(Default)]
struct Seen {
    duties: BTreeSet<i16>,
    scores: BTreeSet<usize>,
}

/// A remote whose answers are noted as they pass.
struct Noting<R> {
    remote: R,
    seen: Rc<RefCell<Seen>>,
}

impl<R: Remote> Remote for Noting<R> {
    fn exchange(&mut self, seq: u16, message: Message) -> anyhow::Result<Message> {
        let answer = self.remote.exchange(seq, message)?;
        if let Message::Reply(r) = &answer {
            let mut seen = self.seen.borrow_mut();
            if let Drive::Drive(d) = r.command {
                seen.duties.insert(d.thousandths());
            }
            seen.scores.insert(match r.scores {
                Scores::F32(q) => q.as_slice().len(),
                Scores::I32(q) => q.as_slice().len(),
            });
        }
        Ok(answer)
    }
}

/// The nine-level desk policy (`pil-desk`) on every target in QEMU, on the desk rig it was
/// trained for, in both formats: every answer equals the same target code's here, each
/// carries nine scores, and the commands drive more than two of the policy's levels (a
/// target that collapsed them to two would fail); refined, duties between them.
#[test]
fn on_every_target_a_policy_of_nine_levels_answers_as_the_controller_here() {
    if skip_qemu() {
        return;
    }
    let desk = twin::rigfile::load(&repo().join("rigs/desk-identified.toml")).unwrap();
    let specs = ["encoder+drop=40+reset=150", "noise+push"].map(String::from);
    let scenarios = Scenario::words_on(&specs, &desk).unwrap();
    let levels: BTreeSet<i16> = (0..9)
        .filter_map(|i| shipped::desk::LEVELS.duty(i).map(|d| d.thousandths()))
        .collect();
    assert_eq!(levels.len(), 9);
    for target in mcu_targets() {
        let elf = build_app(Board::Desk.app(), Some(&target));
        let place = Place::parse(format!("qemu:{target}"), Some(&elf), Board::Desk).unwrap();
        let seen = Rc::new(RefCell::new(Seen::default()));
        let remote = place.start(WATCHDOG).unwrap();
        let mut remote = Session::new(Noting {
            remote,
            seen: seen.clone(),
        });
        let mut here = Session::new(Board::Desk.reference());
        for format in [Format::F32, Format::Int8] {
            *seen.borrow_mut() = Seen::default();
            let info = handshake(&mut remote, &mut here, format, &scenarios, Board::Desk).unwrap();
            for s in &scenarios {
                let what = format!("{target} {format:?} {}", s.name);
                let run = (&info, ControllerKind::Policy);
                two_episodes_agree(&mut remote, &mut here, run, s, &what);
            }
            let what = format!("{target} {format:?}");
            {
                let seen = seen.borrow();
                assert_eq!(seen.scores, BTreeSet::from([9]), "{what}");
                assert!(seen.duties.is_subset(&levels), "{what}: {:?}", seen.duties);
                assert!(seen.duties.len() > 2, "{what}: only {:?}", seen.duties);
            }
            // Refined, the duties leave the levels, as the reference's do.
            let refined = match format {
                Format::F32 => ControllerKind::PolicyRefined,
                Format::Int8 => ControllerKind::PolicyIntRefined,
            };
            *seen.borrow_mut() = Seen::default();
            let run = (&info, refined);
            two_episodes_agree(&mut remote, &mut here, run, &scenarios[1], &what);
            let between = seen.borrow().duties.difference(&levels).count();
            assert!(between > 10, "{what} refined: {:?}", seen.borrow().duties);
        }
    }
}

/// Under the runtime monitor, with the encoders frozen for a quarter of every 2 s: the
/// target's monitor answers as the one here, and its fallback took over.
fn monitored_row(
    remote: &mut Session<impl Remote>,
    here: &mut Session<impl Remote>,
    info: &Info,
    what: &str,
) {
    let frozen = Scenario::parse("encoder+stuck=25/100").unwrap();
    let (eps, check) = run_row(
        remote,
        here,
        (info, ControllerKind::Monitored),
        &frozen,
        200,
        0,
        2,
        || (),
    )
    .unwrap();
    assert_eq!(check.mismatches, 0, "{what} monitored: {check:?}");
    assert!(
        eps.iter().all(|e| e.fallback > 0),
        "{what} monitored: {eps:?}"
    );
}

fn skip_qemu() -> bool {
    let skip = std::env::var_os("CARTPOLE_SKIP_QEMU").is_some_and(|v| v == "1");
    if skip {
        eprintln!("SKIPPED: CARTPOLE_SKIP_QEMU=1, no processor-in-the-loop run");
    }
    skip
}

#[test]
fn the_c_application_answers_as_the_rust_one() {
    if skip_qemu() {
        return;
    }
    let out = std::env::temp_dir().join(format!("c-app-{}", std::process::id()));
    let built = Command::new(repo().join("scripts/c-app.sh"))
        .arg(&out)
        .env("PROFILE", "quick")
        .current_dir(repo())
        .output()
        .expect("running scripts/c-app.sh");
    assert!(
        built.status.success(),
        "{}",
        String::from_utf8_lossy(&built.stderr)
    );
    let elf = out.join("c-pil.elf");
    let place = Place::parse("qemu:thumbv7em-none-eabihf", Some(&elf), Board::Shipped).unwrap();
    let mut remote = Session::new(place.start(WATCHDOG).unwrap());
    let mut here = reference();
    let scenarios = ["encoder+noise+push", "noise+delay+push"].map(|s| Scenario::parse(s).unwrap());
    for format in [Format::F32, Format::Int8] {
        let info = handshake(&mut remote, &mut here, format, &scenarios, Board::Shipped).unwrap();
        for s in &scenarios {
            let (_, check) = run_row(
                &mut remote,
                &mut here,
                (&info, ControllerKind::Policy),
                s,
                300,
                0,
                3,
                || (),
            )
            .unwrap();
            assert_eq!(check.mismatches, 0, "{format:?} {}: {check:?}", s.name);
            assert_eq!(check.overruns, 0, "{format:?} {}: {check:?}", s.name);
        }
        monitored_row(&mut remote, &mut here, &info, &format!("C {format:?}"));
        // Refined levels: the shipped policy's two are both ends, so both refuse them, as
        // the same reason, and the next episode runs.
        let refine = Start {
            sensing: Sensing::Observer,
            predict: true,
            monitor: false,
            refine: true,
            dead_time: 0,
        };
        let refused = |e: anyhow::Error| e.to_string();
        let (c, rust) = (remote.start(refine), here.start(refine));
        let (c, rust) = (c.map_err(refused), rust.map_err(refused));
        assert_eq!(c, rust, "C {format:?}");
        assert!(c.is_err_and(|e| e.contains("refused")), "C {format:?}");
        let run = (&info, ControllerKind::Policy);
        two_episodes_agree(
            &mut remote,
            &mut here,
            run,
            &scenarios[0],
            "C after a refusal",
        );
    }
    std::fs::remove_dir_all(&out).unwrap();
}

#[test]
fn the_host_build_of_the_pil_application_gives_evals_rows() {
    let exe = build_app("pil", None);
    let place = Place::parse(format!("exec:{}", exe.display()), None, Board::Shipped).unwrap();
    let mut remote = Session::new(place.start(WATCHDOG).unwrap());
    let mut here = reference();
    let mut scenarios = scenarios();
    scenarios.push(Scenario::parse("encoder+glitch+stuck+late+weak=0.5").unwrap());
    let runs = [
        (Format::F32, ControllerKind::Policy),
        (Format::Int8, ControllerKind::PolicyInt),
        (Format::F32, ControllerKind::Monitored),
        (Format::Int8, ControllerKind::MonitoredInt),
    ];
    let ends = (&mut remote, &mut here);
    rows_are_evals(
        ends,
        Board::Shipped,
        &Net::shipped(),
        &scenarios,
        &runs,
        (400, 8),
    );
}

/// Each row of `runs` (a format and a controller) on each of `scenarios`, `episodes` of
/// `horizon` periods of seed 3 run through `target` (no answer differing from `here`'s),
/// equals `eval`'s row of `net`.
fn rows_are_evals(
    (target, here): (&mut Session<impl Remote>, &mut Session<impl Remote>),
    board: Board,
    net: &Net,
    scenarios: &[Scenario],
    runs: &[(Format, ControllerKind)],
    (horizon, episodes): (u32, u64),
) {
    for &(format, kind) in runs {
        let info = handshake(target, here, format, scenarios, board).unwrap();
        for s in scenarios {
            let run = (&info, kind);
            let (eps, check) = run_row(target, here, run, s, horizon, 3, episodes, || ()).unwrap();
            assert_eq!(check.mismatches, 0, "{kind} {}: {check:?}", s.name);
            let span = (horizon, s.params.tau);
            let pil = Row::from_episodes(&kind.to_string(), &s.name, span, 3, &eps);
            let want = eval::evaluate(kind, net, s, horizon, 3, episodes);
            assert_eq!(pil, want, "{kind} {}", s.name);
        }
    }
}

/// The desk policy's target code, run here as a board would run it, gives `eval`'s rows of
/// the desk policy, refined or not: the target's `Refinable` drives as eval's `Refined`, and
/// the world applies a level between the paper's two (-0.15) as the board's pins set it,
/// not as its nearest f32.
#[test]
fn the_desk_target_gives_evals_rows_refined_or_not() {
    let desk = twin::rigfile::load(&repo().join("rigs/desk-identified.toml")).unwrap();
    let specs = ["nominal", "encoder", "noise+push"].map(String::from);
    let scenarios = Scenario::words_on(&specs, &desk).unwrap();
    let mut target = Session::new(Board::Desk.reference());
    let mut here = Session::new(Board::Desk.reference());
    let runs = [
        (Format::F32, ControllerKind::Policy),
        (Format::F32, ControllerKind::PolicyRefined),
        (Format::Int8, ControllerKind::PolicyIntRefined),
        (Format::Int8, ControllerKind::PolicyInt),
    ];
    let ends = (&mut target, &mut here);
    rows_are_evals(
        ends,
        Board::Desk,
        &Net::shipped_desk(),
        &scenarios,
        &runs,
        (300, 4),
    );
}

/// A board on the far end of a pseudo-terminal: the link's target on the bytes it reads,
/// until the host's end closes.
fn board_on(mut port: serialport::TTYPort) {
    use std::io::{Read, Write};
    let mut target = shipped::target(1);
    let mut buf = [0u8; 64];
    loop {
        let n = match port.read(&mut buf) {
            Ok(0) | Err(_) => return,
            Ok(n) => n,
        };
        for &b in &buf[..n] {
            if let Some(answer) = target.receive(b, || 1)
                && port.write_all(answer).is_err()
            {
                return;
            }
        }
    }
}

#[test]
fn a_board_on_a_serial_port_gives_evals_rows() {
    let (board, host) = serialport::TTYPort::pair().unwrap();
    let path = host.name().expect("the host's end of the pair has a name");
    let _board = std::thread::spawn(move || board_on(board));
    let place = Place::parse(format!("serial:{path}"), None, Board::Shipped).unwrap();
    let mut remote = Session::new(place.start(WATCHDOG).unwrap());
    let mut here = reference();
    let s = Scenario::parse("encoder+drop=40+reset=150+noise+push").unwrap();
    let info = handshake(
        &mut remote,
        &mut here,
        Format::F32,
        std::slice::from_ref(&s),
        Board::Shipped,
    )
    .unwrap();
    let (eps, check) = run_row(
        &mut remote,
        &mut here,
        (&info, ControllerKind::Policy),
        &s,
        300,
        1,
        4,
        || (),
    )
    .unwrap();
    assert_eq!(check.mismatches, 0, "{check:?}");
    let kind = ControllerKind::Policy;
    let pil = Row::from_episodes(&kind.to_string(), &s.name, (300, s.params.tau), 1, &eps);
    assert_eq!(pil, eval::evaluate(kind, &Net::shipped(), &s, 300, 1, 4));
    drop(host);
}
