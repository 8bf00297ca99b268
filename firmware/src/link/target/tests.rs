extern crate std;
use std::vec::Vec;

use super::*;
use crate::cartpole::{CartPole, State};
use crate::controller::{Command, Duty, Levels, Refined, answer};
use crate::estimator::ObserverSensor;
use crate::link::{Sensing, digest};
use crate::loopback::{Latest, duty};
use crate::shipped::envelope::{ENVELOPE, POLICY_DIGEST};
use crate::shipped::policy::{LEVELS, POLICY, RIG};
use crate::shipped::policy_int::POLICY_INT;
use crate::shipped::{desk, desk_int};

const CLOCK_HZ: u32 = 1_000;

fn target() -> Target<'static, 64> {
    Target::new(&POLICY, &POLICY_INT, LEVELS, RIG, Some(ENVELOPE), CLOCK_HZ)
}

/// The nine-level desk policy's target: no envelope measured for it.
fn desk_target() -> Target<'static, 64, 9> {
    let (f, i) = (&desk::POLICY, &desk_int::POLICY_INT);
    Target::new(f, i, desk::LEVELS, desk::RIG, None, CLOCK_HZ)
}

/// Sends `message` numbered `seq`; the answer's message, checked to carry `seq`.
fn send<const A: usize>(t: &mut Target<'_, 64, A>, seq: u16, message: Message) -> Message {
    let answer = t.handle(Ok(Packet { seq, message }), || 7);
    assert_eq!(answer.seq, seq);
    answer.message
}

fn reply(m: Message) -> Reply {
    match m {
        Message::Reply(r) => r,
        other => panic!("a Reply was due, got {other:?}"),
    }
}

/// A closed loop of `rig`'s plant and a controller built as a board builds it (the rig's
/// observer on the counts, its predictor for `dead_time` periods, its limits, and with
/// `monitor` the runtime monitor with the shipped envelope, the encoders frozen for half a
/// second); beside it the target `t`, handed the same counts as frames. Their commands and
/// faults, period by period.
fn both<O: Estimate, P: crate::controller::Policy<O>, const A: usize>(
    (policy, mut t, rig): (P, Target<'_, 64, A>, Rig),
    format: Format,
    (dead_time, monitor): (u8, bool),
) -> Vec<((Command, u16), (Command, u16))> {
    let rig = Rig {
        dead_time: dead_time.into(),
        ..rig
    };
    let mut plant = CartPole::new(rig.params, 300);
    plant.reset_to(State::from_array([0.03, 0.0, -0.04, 0.02]));
    let counts = |s: State| rig.encoders.counts(s.x, s.theta);
    let observer = rig.observer().unwrap();
    let observer = if monitor {
        observer.watching()
    } else {
        observer
    };
    let sensor = ObserverSensor::<_, O>::new(observer, Latest::default());
    let mut board = Controller::new(policy, sensor, pins(), rig.limits().unwrap())
        .with_predictor(rig.predictor().unwrap());
    if monitor {
        board.set_monitor(rig.lqr_assurance(ENVELOPE).unwrap());
    }
    assert!(matches!(
        send(&mut t, 0, Message::Hello(format)),
        Message::Info(_)
    ));
    let start = Start {
        sensing: Sensing::Observer,
        predict: true,
        monitor,
        refine: false,
        dead_time,
    };
    assert_eq!(send(&mut t, 1, Message::Start(start)), Message::Started);
    let mut out = Vec::new();
    let mut held = (0, 0);
    for seq in 2u16.. {
        if !(monitor && (100..125).contains(&seq)) {
            held = counts(plant.state());
        }
        let (cart, pole) = held;
        board.sensor_mut().counter_mut().0 = (cart, pole);
        let want = (board.step(), board.last().unwrap().faults.0);
        let got = reply(send(&mut t, seq, Message::Counts { cart, pole }));
        assert_eq!(got.ticks, 7);
        out.push(((got.command, got.faults.0), want));
        let step = plant.advance(duty(board.actuator()), 0.0);
        if step.terminated || step.truncated {
            return out;
        }
    }
    unreachable!()
}

#[test]
fn the_target_commands_what_a_board_built_from_its_rig_commands() {
    for aids in [(0, false), (2, false), (0, true)] {
        let f32s = both::<[f32; 4], _, 2>((&POLICY, target(), RIG), Format::F32, aids);
        let ints = both::<[i16; 4], _, 2>((&POLICY_INT, target(), RIG), Format::Int8, aids);
        for run in [f32s, ints] {
            assert_eq!(run.len(), 300, "the board balanced for the whole run");
            for (k, (got, want)) in run.iter().enumerate() {
                assert_eq!(got, want, "period {k}, dead time and monitor {aids:?}");
            }
            // Monitored, the frozen encoder was seen and the fallback took over.
            let flagged = |f: FaultFlags| run.iter().any(|(got, _)| got.1 & f.0 != 0);
            assert_eq!(flagged(FaultFlags::MODEL_ONLY), aids.1);
            assert_eq!(flagged(FaultFlags::FALLBACK), aids.1);
        }
    }
}

/// The desk policy's nine outputs each drive their level: the target commands what a board
/// built from the desk rig commands with the same levels, in both formats, with dead time,
/// and more than two of the levels drive the motor.
#[test]
fn a_target_of_nine_levels_commands_what_its_board_commands() {
    for dead_time in [0, 1] {
        let f32s = both::<[f32; 4], _, 9>(
            (
                Greedy {
                    net: &desk::POLICY,
                    levels: desk::LEVELS,
                },
                desk_target(),
                desk::RIG,
            ),
            Format::F32,
            (dead_time, false),
        );
        let ints = both::<[i16; 4], _, 9>(
            (
                Greedy {
                    net: &desk_int::POLICY_INT,
                    levels: desk_int::LEVELS,
                },
                desk_target(),
                desk_int::RIG,
            ),
            Format::Int8,
            (dead_time, false),
        );
        for run in [f32s, ints] {
            assert_eq!(run.len(), 300, "the board balanced for the whole run");
            for (k, (got, want)) in run.iter().enumerate() {
                assert_eq!(got, want, "period {k}, dead time {dead_time}");
            }
            let drive = |c: Command| match c {
                Command::Drive(d) => Some(d),
                Command::Coast => None,
            };
            let mut seen: Vec<Option<Duty>> = run.iter().map(|(got, _)| drive(got.0)).collect();
            seen.sort_unstable();
            seen.dedup();
            assert!(seen.len() > 2, "dead time {dead_time}: only {seen:?}");
            let levels: Vec<_> = (0..9).map(|i| desk::LEVELS.duty(i)).collect();
            assert!(seen.iter().all(|d| levels.contains(d)), "{seen:?}");
        }
    }
}

/// A reply carries all nine scores, the network's own bits; a monitor the target holds no
/// envelope for is refused.
#[test]
fn a_target_of_nine_levels_replies_with_nine_scores_and_refuses_a_monitor() {
    let mut t = desk_target();
    send(&mut t, 1, Message::Hello(Format::F32));
    let exact = Start {
        sensing: Sensing::Exact,
        predict: false,
        monitor: false,
        refine: false,
        dead_time: 0,
    };
    assert_eq!(send(&mut t, 2, Message::Start(exact)), Message::Started);
    let obs = [0.01, -0.02, 0.03, 0.1];
    let got = reply(send(&mut t, 3, Message::State(obs)));
    let want = desk::POLICY.forward(&obs);
    let Scores::F32(q) = got.scores else {
        panic!("f32 scores were due, got {got:?}");
    };
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(q.as_slice()), bits(&want));
    let chosen = crate::network::argmax(&want);
    assert_eq!(
        got.command,
        Command::Drive(desk::LEVELS.duty(chosen).unwrap())
    );
    let monitored = Start {
        monitor: true,
        ..exact
    };
    assert_eq!(
        send(&mut t, 4, Message::Start(monitored)),
        Message::Refused(Reason::Unsupported)
    );
}

#[test]
fn a_start_that_asks_for_refined_levels_drives_between_them_where_there_are_any() {
    let exact = Start {
        sensing: Sensing::Exact,
        predict: false,
        monitor: false,
        refine: true,
        dead_time: 0,
    };
    let mut t = desk_target();
    send(&mut t, 1, Message::Hello(Format::Int8));
    assert_eq!(send(&mut t, 2, Message::Start(exact)), Message::Started);
    let mut policy = Refined(Greedy {
        net: &desk_int::POLICY_INT,
        levels: desk::LEVELS,
    });
    let mut moved = 0;
    for k in 0..40u16 {
        let obs = [0.0, 0.0, 0.002 * (f32::from(k) - 20.0), 0.0];
        let got = reply(send(&mut t, 3 + k, Message::State(obs)));
        let want = answer(&mut policy, &crate::fixed::from_state(&obs))
            .1
            .unwrap();
        assert_eq!(got.command, Command::Drive(want), "{obs:?}");
        moved += usize::from(!desk::LEVELS.duties().contains(&want));
    }
    assert!(moved > 20, "only {moved} periods between the levels");
    // The paper's two levels are both ends: nothing to refine.
    let mut t = target();
    send(&mut t, 1, Message::Hello(Format::F32));
    assert_eq!(
        send(&mut t, 2, Message::Start(exact)),
        Message::Refused(Reason::Unsupported)
    );
    // An envelope is measured for the plain levels: the monitor runs them alone.
    let (f, i) = (&desk::POLICY, &desk_int::POLICY_INT);
    let mut t = Target::new(f, i, desk::LEVELS, desk::RIG, Some(ENVELOPE), CLOCK_HZ);
    send(&mut t, 1, Message::Hello(Format::F32));
    let monitored = Start {
        monitor: true,
        ..exact
    };
    assert_eq!(
        send(&mut t, 2, Message::Start(monitored)),
        Message::Refused(Reason::Unsupported)
    );
    let plain = Start {
        refine: false,
        ..monitored
    };
    assert_eq!(send(&mut t, 3, Message::Start(plain)), Message::Started);
}

#[test]
fn hello_says_what_the_target_holds_in_the_format_asked_for() {
    let mut t = target();
    let Message::Info(info) = send(&mut t, 3, Message::Hello(Format::Int8)) else {
        panic!("an Info was due");
    };
    assert_eq!(info.format, Format::Int8);
    assert_eq!(info.hidden, 64);
    assert_eq!(
        info.policy,
        digest::policy(digest::qmlp(&POLICY_INT), &LEVELS)
    );
    assert_eq!(info.rig, digest::rig(&RIG));
    assert_eq!((info.period_ns, info.clock_hz), (20_000_000, CLOCK_HZ));
    let Message::Info(info) = send(&mut t, 4, Message::Hello(Format::F32)) else {
        panic!("an Info was due");
    };
    assert_eq!(info.policy, digest::policy(digest::mlp(&POLICY), &LEVELS));
    // The runtime monitor's envelope names the policy it was measured for alike.
    assert_eq!(info.policy, POLICY_DIGEST);
}

/// The same networks driving other duties are another policy: a host that runs the
/// shipped levels refuses a target that would push the cart at half of them.
#[test]
fn hello_names_the_levels_with_the_network() {
    let halved = Levels::new([-0.5, 0.5]).unwrap();
    let mut shipped = target();
    let mut other = Target::new(&POLICY, &POLICY_INT, halved, RIG, Some(ENVELOPE), CLOCK_HZ);
    for format in [Format::F32, Format::Int8] {
        let (Message::Info(a), Message::Info(b)) = (
            send(&mut shipped, 1, Message::Hello(format)),
            send(&mut other, 1, Message::Hello(format)),
        ) else {
            panic!("an Info was due");
        };
        assert_ne!(a.policy, b.policy, "{format:?}");
        assert_eq!(
            (a.hidden, a.rig, a.period_ns),
            (b.hidden, b.rig, b.period_ns)
        );
    }
    // The digest over the levels is FNV-1a's over their thousandths' bytes, continued.
    let by_hand = [0x0cu8, 0xfe, 0xf4, 0x01]
        .iter()
        .fold(digest::mlp(&POLICY), |h, &b| {
            (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3)
        });
    assert_eq!(digest::policy(digest::mlp(&POLICY), &halved), by_hand);
}

#[test]
fn a_refusal_stops_the_motor_until_the_next_start() {
    let mut t = target();
    let exact = Start {
        sensing: Sensing::Exact,
        predict: false,
        monitor: false,
        refine: false,
        dead_time: 0,
    };
    let state = Message::State([0.0, 0.0, 0.01, 0.0]);
    // Before any Hello, and before any Start.
    assert_eq!(
        send(&mut t, 1, Message::Start(exact)),
        Message::Refused(Reason::NotStarted)
    );
    send(&mut t, 2, Message::Hello(Format::F32));
    assert_eq!(send(&mut t, 3, state), Message::Refused(Reason::NotStarted));
    // A dead time the predictor's line cannot hold, a filter the firmware refuses.
    for bad in [
        Start {
            dead_time: 200,
            ..exact
        },
        Start {
            sensing: Sensing::AlphaBeta(f32::NAN),
            ..exact
        },
    ] {
        assert_eq!(
            send(&mut t, 4, Message::Start(bad)),
            Message::Refused(Reason::Unsupported)
        );
        assert_eq!(send(&mut t, 5, state), Message::Refused(Reason::NotStarted));
    }
    assert_eq!(send(&mut t, 6, Message::Start(exact)), Message::Started);
    assert_eq!(
        reply(send(&mut t, 7, state)).command,
        Command::Drive(crate::controller::Duty::RIGHT)
    );
    // A missed reading coasts, counted as the sensor's error.
    let missed = reply(send(&mut t, 8, Message::Missed));
    assert_eq!(missed.command, Command::Coast);
    assert_eq!(missed.faults, FaultFlags::SENSOR_ERROR);
    // A corrupted frame mid-episode: refused, and the readings after it too.
    let crc = t.handle(Err(Reason::Crc), || 0);
    assert_eq!((crc.seq, crc.message), (8, Message::Refused(Reason::Crc)));
    assert_eq!(send(&mut t, 9, state), Message::Refused(Reason::NotStarted));
    assert_eq!(send(&mut t, 10, Message::Start(exact)), Message::Started);
    assert!(matches!(send(&mut t, 11, state), Message::Reply(_)));
    // A replayed reading: refused, and after it any reading, in sequence or not, of either
    // kind, until the next Start.
    assert_eq!(send(&mut t, 11, state), Message::Refused(Reason::Sequence));
    for (seq, m) in [
        (12, state),
        (20, state),
        (12, Message::Counts { cart: 0, pole: 0 }),
    ] {
        assert_eq!(send(&mut t, seq, m), Message::Refused(Reason::NotStarted));
    }
    assert_eq!(t.refused(), 12);
}

#[test]
fn bytes_in_answers_out() {
    let mut t = target();
    let mut wire = [0u8; MAX_FRAME];
    let hello = Packet {
        seq: 5,
        message: Message::Hello(Format::F32),
    };
    let n = frame::encode(&hello, &mut wire);
    let (last, head) = wire[..n].split_last().unwrap();
    assert!(head.iter().all(|&b| t.receive(b, || 0).is_none()));
    let answer = t
        .receive(*last, || 0)
        .expect("a frame's last byte gets its answer");
    let mut reader = FrameReader::default();
    let got: Vec<_> = answer.iter().filter_map(|&b| reader.push(b)).collect();
    assert!(matches!(
        got[..],
        [Ok(Packet {
            seq: 5,
            message: Message::Info(_)
        })]
    ));
}
