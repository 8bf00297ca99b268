//! Logs the fit cannot use, refused naming the log's line and what was expected there.

use super::*;

/// A desk rig's two logs and the rig they are fitted for.
fn desk() -> (Machine, [String; 2]) {
    let mut rng = Pcg64Mcg::new(2);
    let (truth, measured) = random_rig(&mut rng, 0.02, 0.5);
    let logs = synthetic::experiments(&truth, &measured.rig, 1, Reading::default());
    (measured, logs)
}

/// The refusal of `text` (parsed, then checked with a good swing log against `machine`).
fn refusal(text: &str, machine: &Machine) -> String {
    let swing = desk().1[1].clone();
    let mut logs = match log::parse(text, "log") {
        Ok(logs) => logs,
        Err(e) => return e.to_string(),
    };
    logs.extend(log::parse(&swing, "swing").unwrap());
    match identify(&logs, machine) {
        Ok(_) => panic!("accepted: {text:.300}"),
        Err(e) => e.to_string(),
    }
}

/// `text` with its `n`-th line (from 1) replaced by `with`.
fn replace_line(text: &str, n: usize, with: &str) -> String {
    let lines: Vec<&str> = text
        .lines()
        .enumerate()
        .map(|(i, l)| if i + 1 == n { with } else { l })
        .collect();
    lines.join("\n") + "\n"
}

/// The line number (from 1) of the data row of period `k` in a single log's text.
fn row_line(text: &str, k: usize) -> usize {
    let header = text
        .lines()
        .position(|l| l == firmware::identify::COLUMNS)
        .unwrap();
    header + 2 + k
}

fn assert_names(message: &str, wants: &[&str]) {
    for w in wants {
        assert!(message.contains(w), "expected {w:?} in: {message}");
    }
}

#[test]
fn short_saturated_and_unexcited_logs_are_refused() {
    let (machine, [cart, swing]) = desk();
    // The first 2 s of the cart log.
    let end = row_line(&cart, 100);
    let short: String = cart
        .lines()
        .take(end - 1)
        .map(|l| format!("{l}\n"))
        .collect();
    assert_names(
        &refusal(&short, &machine),
        &["log:1:", "too short", "found 100 periods"],
    );

    // The same log against a rig whose end stops are nearer than the cart went.
    let mut near = machine;
    near.rig.params.x_threshold = 0.05;
    near.rig.end_stop_margin = 0.01;
    assert_names(&refusal(&cart, &near), &["saturated", "at the end stop"]);

    // Every duty towards +x.
    let one_way = cart.replace(",-1,", ",1,");
    assert_names(
        &refusal(&one_way, &machine),
        &["unexcited", "duties of both signs"],
    );

    // The cart standing still under the motor's pushes: a stalled or unpowered motor.
    let still: String = cart
        .lines()
        .map(|l| match l.split(',').collect::<Vec<_>>()[..] {
            [k, d, _, p] if k.parse::<u32>().is_ok() => format!("{k},{d},0,{p}\n"),
            _ => format!("{l}\n"),
        })
        .collect();
    assert_names(&refusal(&still, &machine), &["unexcited", "at least 1 cm"]);

    // A pole that never swings through hanging.
    let hanging_still: String = swing
        .lines()
        .map(|l| match l.split(',').collect::<Vec<_>>()[..] {
            [k, d, c, _] if k.parse::<u32>().is_ok() => format!("{k},{d},{c},80\n"),
            _ => format!("{l}\n"),
        })
        .collect();
    let message = log::parse(&hanging_still, "swing").unwrap()[0]
        .check(&machine)
        .unwrap_err();
    assert_names(
        &message.to_string(),
        &["swing:1:", "unexcited", "never passing hanging"],
    );
}

#[test]
fn wrong_columns_gaps_and_jumps_are_refused_naming_the_line() {
    let (machine, [cart, _]) = desk();
    let line = row_line(&cart, 40);
    let at = format!("log:{line}:");
    let three = replace_line(&cart, line, "40,1,12");
    assert_names(
        &refusal(&three, &machine),
        &[&at, "expected 4 columns", "found 3"],
    );

    let gap = replace_line(&cart, line, "41,1,0,0");
    assert_names(
        &refusal(&gap, &machine),
        &[&at, "period: expected 40, found 41"],
    );

    let row: Vec<&str> = cart.lines().nth(line - 1).unwrap().split(',').collect();
    let pole: i32 = row[3].parse().unwrap();
    let jump = replace_line(
        &cart,
        line,
        &format!("40,{},{},{}", row[1], row[2], pole + 3_000),
    );
    assert_names(
        &refusal(&jump, &machine),
        &[&at, "pole_counts", "at most a revolution (2400 counts)"],
    );

    // Whole, but past a board's 32-bit counter: the range named.
    let huge = replace_line(
        &cart,
        line,
        &format!("40,{},{},{}", row[1], i64::MAX, row[3]),
    );
    assert_names(
        &refusal(&huge, &machine),
        &[
            &at,
            "cart_counts: expected a whole number of counts in [-2147483648, 2147483647]",
        ],
    );

    let cart_jump = replace_line(
        &cart,
        line,
        &format!("40,{},{},{}", row[1], 1_000_000, row[3]),
    );
    assert_names(
        &refusal(&cart_jump, &machine),
        &[&at, "cart_counts", "at most 0.25 m"],
    );

    // A header's count past 32 bits, a `+` and a huge period number: each named by its range.
    let counts = cart
        .lines()
        .find(|l| l.contains("cart_counts_per_m"))
        .unwrap();
    let huge = cart.replace(counts, "# cart_counts_per_m: 4294967296");
    assert_names(
        &refusal(&huge, &machine),
        &["a whole number in [1, 4294967295]"],
    );
    let period = replace_line(
        &cart,
        line,
        &format!("+40,{},{},{}", row[1], row[2], row[3]),
    );
    assert_names(
        &refusal(&period, &machine),
        &[&at, "period: expected a period number in [0, "],
    );

    let header = cart.replace(firmware::identify::COLUMNS, "period,duty,cart,pole");
    assert_names(&refusal(&header, &machine), &["expected the header row"]);
}

/// More seconds of logs than the fit takes in all: refused naming the log that passes the
/// limit, before any fitting.
#[test]
fn more_logs_than_the_fit_takes_are_refused() {
    let (machine, [cart, swing]) = desk();
    let one = log::parse(&cart, "cart").unwrap().remove(0);
    let seconds = one.duty.len() as f64 * one.period_s;
    let fits = (log::MAX_TOTAL_SECONDS / seconds) as usize;
    let mut logs = vec![one; fits];
    logs.extend(log::parse(&swing, "swing").unwrap());
    let e = check(&logs, &machine).unwrap_err().to_string();
    assert_names(
        &e,
        &["swing:1:", "expected at most 1800 s of logs in all, found"],
    );
    logs.truncate(fits - 3);
    logs.extend(log::parse(&swing, "swing").unwrap());
    assert!(check(&logs, &machine).is_ok());
}

/// A copy of a log is one experiment counted twice, its cart from any zero and its pole a
/// whole revolution on; a pole counted from another angle, another experiment, or another
/// period or encoder is another measurement.
#[test]
fn only_the_same_measurement_is_refused_as_an_experiment_given_twice() {
    let (_, [cart, _]) = desk();
    let log = log::parse(&cart, "cart").unwrap().remove(0);
    let per_rev = log.encoders.pole_counts_per_rev as i32;
    let changed = |f: &dyn Fn(&mut Log)| {
        let mut copy = log.clone();
        f(&mut copy);
        log::check_each_once(&[log.clone(), copy])
    };
    type Change<'a> = &'a dyn Fn(&mut Log);
    let same: [Change; 2] = [&|l| l.cart.iter_mut().for_each(|c| *c += 7), &|l| {
        l.pole.iter_mut().for_each(|p| *p -= per_rev)
    }];
    for change in same {
        let e = changed(change).unwrap_err().to_string();
        assert!(e.contains("expected each experiment once"), "{e}");
    }
    let other: [Change; 4] = [
        &|l| l.pole.iter_mut().for_each(|p| *p += 3),
        &|l| l.experiment = firmware::identify::Experiment::Swing,
        &|l| l.period_s *= 2.0,
        &|l| l.encoders.cart_counts_per_m += 1,
    ];
    for other in other {
        changed(other).unwrap();
    }
}
