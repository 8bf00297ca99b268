//! `host-sim identify` end to end: logs the board's experiments would stream from a
//! simulated desk rig, the rig file its builder measured (the motor, friction, length and
//! dead time wrong), the binary run on them; and bad logs and rig files refused with exit 2
//! and nothing written.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use host_sim::identify::synthetic::{self, Reading, Zero};
use twin::Machine;

// The shared harness: its listings.
#[allow(dead_code)]
#[path = "../../host-common/tests/support/hostile.rs"]
mod hostile;

use hostile::entries;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("identify-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn run(args: &[&Path]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .arg("identify")
        .args(args)
        .output()
        .unwrap()
}

/// The desk rig of `rigs/desk.toml` as the truth (with some friction and a dead time of 2),
/// and the rig file its builder wrote: the motor a third too strong and too weakly damped,
/// the pole 5% long, no friction, a dead time of 1.
fn desk() -> (Machine, Machine) {
    let desk = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../rigs/desk.toml");
    let mut truth = twin::rigfile::load(&desk).unwrap();
    truth.rig.params.cart_friction = 0.02;
    truth.rig.params.pole_friction = 2e-4;
    truth.rig.dead_time = 2;
    let mut measured = truth;
    let p = &mut measured.rig.params;
    p.force_mag *= 1.3;
    p.motor_damping *= 0.7;
    p.length *= 1.05;
    p.cart_friction = 0.0;
    p.pole_friction = 0.0;
    measured.rig.dead_time = 1;
    (truth, measured)
}

/// Writes the logs and the measured rig file into `dir`: `[cart, swing, rig]`.
fn inputs(dir: &Path) -> [PathBuf; 3] {
    let (truth, measured) = desk();
    let reading = Reading {
        zero: Zero {
            cart: 0.4,
            pole: 0.6,
        },
        jitter_counts: 0.3,
        seed: 9,
    };
    let [cart, swing] = synthetic::experiments(&truth, &measured.rig, 1, reading);
    let paths = ["cart.log", "swing.log", "measured.toml"].map(|n| dir.join(n));
    std::fs::write(&paths[0], cart).unwrap();
    std::fs::write(&paths[1], swing).unwrap();
    // How the builder's rig starts, which identification carries into the identified file.
    let startup =
        "\n[startup]\nswing_up = false\nhoming = true\nhoming_duty = 0.2\ncatch_periods = 5\n";
    std::fs::write(&paths[2], twin::rigfile::to_toml(&measured) + startup).unwrap();
    paths
}

#[test]
fn identify_writes_a_rig_near_the_truth_and_draws_the_fit() {
    let dir = scratch("ok");
    let [cart, swing, rig] = inputs(&dir);
    let (out, plots) = (dir.join("rig.toml"), dir.join("plots"));
    let flag = |s: &str| PathBuf::from(s);
    let o = run(&[
        &cart,
        &swing,
        &flag("--rig"),
        &rig,
        &flag("--out"),
        &out,
        &flag("--plots"),
        &plots,
    ]);
    let (stdout, stderr) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    assert!(o.status.success(), "{stderr}");
    assert!(!stderr.contains("warning"), "{stderr}");
    for field in [
        "actuator.stall_force_n",
        "pole_com_m",
        "dead_time_periods",
        "+- ",
    ] {
        assert!(stdout.contains(field), "{field} in {stdout}");
    }
    let found = twin::rigfile::load(&out).unwrap();
    let (truth, measured) = desk();
    let (q, p) = (&found.rig.params, &truth.rig.params);
    assert!((q.force_mag / p.force_mag - 1.0).abs() < 0.05, "{q:?}");
    assert!(
        (q.motor_damping / p.motor_damping - 1.0).abs() < 0.05,
        "{q:?}"
    );
    assert!((q.length / p.length - 1.0).abs() < 0.02, "{q:?}");
    assert_eq!(found.rig.dead_time, 2);
    // Everything measured is kept as the builder wrote it.
    assert_eq!(found.rig.encoders, measured.rig.encoders);
    assert_eq!(q.masscart, measured.rig.params.masscart);
    assert_eq!(q.x_threshold, measured.rig.params.x_threshold);
    let (_, starts) = twin::rigfile::load_startup(&out).unwrap();
    assert_eq!(starts.catch_periods, 5);
    assert_eq!(starts.swing, None);
    assert_eq!(starts.homing.map(|h| h.duty), Some(0.2));
    assert_eq!(
        entries(&plots),
        [
            "identify-1-cart-residuals.png",
            "identify-1-cart-residuals.svg",
            "identify-1-cart.png",
            "identify-1-cart.svg",
            "identify-2-swing-residuals.png",
            "identify-2-swing-residuals.svg",
            "identify-2-swing.png",
            "identify-2-swing.svg"
        ]
    );
    let png = std::fs::read(plots.join("identify-1-cart.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    another_fits_plots_are_refused([&cart, &swing, &rig], &out, &plots);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A fit of the swing alone into the plots of the fit of both would leave those beside its
/// own: refused, naming them; the fit of both again replaces its own.
fn another_fits_plots_are_refused([cart, swing, rig]: [&Path; 3], out: &Path, plots: &Path) {
    let flag = |s: &str| PathBuf::from(s);
    let again = |logs: &[&Path]| {
        let mut args: Vec<PathBuf> = logs.iter().map(|p| p.to_path_buf()).collect();
        args.extend([flag("--rig"), rig.into(), flag("--out"), out.into()]);
        args.extend([flag("--plots"), plots.into()]);
        args
    };
    // A user's own picture of the set-up is no fit's plot.
    std::fs::write(plots.join("identify-setup-photo.png"), b"mine").unwrap();
    let alone = again(&[swing]);
    let alone: Vec<&Path> = alone.iter().map(PathBuf::as_path).collect();
    refused(
        plots,
        &alone,
        &["expected a directory without another fit's plots, found \
             \"identify-1-cart-residuals.png\", \"identify-1-cart-residuals.svg\", \
             \"identify-1-cart.png\" and 5 more"],
    );
    let both = again(&[cart, swing]);
    let both: Vec<&Path> = both.iter().map(PathBuf::as_path).collect();
    assert!(run(&both).status.success());
    assert_eq!(
        std::fs::read(plots.join("identify-setup-photo.png")).unwrap(),
        b"mine"
    );
}

/// Exit 2, `wants` in the message, nothing on stdout and no file but the inputs.
fn refused(dir: &Path, args: &[&Path], wants: &[&str]) {
    let before = entries(dir);
    let o = run(args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    for w in wants {
        assert!(err.contains(w), "{w:?} in {err}");
    }
    assert!(o.stdout.is_empty(), "{args:?}");
    assert_eq!(entries(dir), before, "{args:?} wrote something");
}

/// The cart log `cart` with period 10's row broken three ways (a column missing, a gap, a
/// pole count a revolution and more on), each refused naming the row's line.
fn malformed_rows_are_refused(dir: &Path, [cart, swing, rig]: [&Path; 3], out: &Path) {
    let text = std::fs::read_to_string(cart).unwrap();
    let header = text
        .lines()
        .position(|l| l == firmware::identify::COLUMNS)
        .unwrap();
    // The header row is line header + 1, period 10's row line header + 12.
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let row = lines[header + 11].clone();
    let f: Vec<&str> = row.split(',').collect();
    let over = format!(
        "10,{},{},{}",
        f[1],
        f[2],
        f[3].parse::<i32>().unwrap() + 5000
    );
    let bad = dir.join("bad.log");
    let plots = dir.join("plots");
    let at = format!("bad.log:{}:", header + 12);
    for (replacement, want) in [
        ("10,1,5".to_string(), "expected 4 columns"),
        ("11,1,5,0".to_string(), "period: expected 10, found 11"),
        (over, "at most a revolution"),
        // Parsed as 0 without a word.
        (
            format!("10,1e-400,{},{}", f[2], f[3]),
            "duty: expected a number from -1 to 1",
        ),
    ] {
        lines[header + 11] = replacement;
        std::fs::write(&bad, lines.join("\n") + "\n").unwrap();
        lines[header + 11] = row.clone();
        let flags = ["--rig", "--out", "--plots"].map(PathBuf::from);
        refused(
            dir,
            &[
                &bad, swing, &flags[0], rig, &flags[1], out, &flags[2], &plots,
            ],
            &[&at, want],
        );
    }
    std::fs::remove_file(&bad).unwrap();
}

/// One experiment given twice, through a link, under other bytes (CRLF line ends) or twice
/// in one file: counted twice, it narrowed every interval by the square root of two.
fn a_repeated_experiment_is_refused(dir: &Path, [cart, swing, rig]: [&Path; 3], out: &Path) {
    let (rig_flag, out_flag) = (PathBuf::from("--rig"), PathBuf::from("--out"));
    let link = dir.join("cart-again.log");
    std::os::unix::fs::symlink(cart, &link).unwrap();
    let cart_text = std::fs::read_to_string(cart).unwrap();
    let once = format!("{}:1", cart.display());
    refused(
        dir,
        &[cart, swing, &link, &rig_flag, rig, &out_flag, out],
        &[&format!(
            "cart-again.log:1: expected each experiment once, found the same samples as {once}"
        )],
    );
    std::fs::remove_file(&link).unwrap();
    // The same samples under other bytes: CRLF line ends, or one file holding them twice.
    let crlf = dir.join("cart-crlf.log");
    std::fs::write(&crlf, cart_text.replace('\n', "\r\n")).unwrap();
    refused(
        dir,
        &[cart, swing, &crlf, &rig_flag, rig, &out_flag, out],
        &[&format!(
            "cart-crlf.log:1: expected each experiment once, found the same samples as {once}"
        )],
    );
    std::fs::remove_file(&crlf).unwrap();
    let double = dir.join("cart-double.log");
    std::fs::write(&double, cart_text.repeat(2)).unwrap();
    let second = cart_text.lines().count() + 1;
    refused(
        dir,
        &[&double, swing, &rig_flag, rig, &out_flag, out],
        &[&format!(
            "cart-double.log:{second}: expected each experiment once, found the same samples \
             as {}:1",
            double.display()
        )],
    );
    std::fs::remove_file(&double).unwrap();
    // The same samples counted from another zero: the pole a revolution on, the cart pushed
    // along by a few counts; and the swing copied so, but only the pole.
    let per_rev = desk().0.rig.encoders.pole_counts_per_rev as i32;
    let moved = recounted(cart, &dir.join("cart-moved.log"), |c, p| {
        (c + 7, p + per_rev)
    });
    refused(
        dir,
        &[cart, swing, &moved, &rig_flag, rig, &out_flag, out],
        &[&format!(
            "cart-moved.log:1: expected each experiment once, found the same samples as {once}, \
             its counts shifted by 7 (cart) and {per_rev} (pole)"
        )],
    );
    let turned = recounted(swing, &dir.join("swing-turned.log"), |c, p| {
        (c, p - per_rev)
    });
    refused(
        dir,
        &[&turned, cart, swing, &rig_flag, rig, &out_flag, out],
        &[&format!(
            "swing.log:1: expected each experiment once, found the same samples as {}:1, its \
             counts shifted by 0 (cart) and {per_rev} (pole)",
            turned.display()
        )],
    );
    std::fs::remove_file(&moved).unwrap();
    std::fs::remove_file(&turned).unwrap();
}

/// `path`'s logs written to `to` with each row's cart and pole counts mapped by `f`.
fn recounted(path: &Path, to: &Path, f: impl Fn(i32, i32) -> (i32, i32)) -> PathBuf {
    let text: String = std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| match l.split(',').collect::<Vec<_>>()[..] {
            [k, d, c, p] if k.parse::<u32>().is_ok() => {
                let (c, p) = f(c.parse().unwrap(), p.parse().unwrap());
                format!("{k},{d},{c},{p}\n")
            }
            _ => format!("{l}\n"),
        })
        .collect();
    std::fs::write(to, text).unwrap();
    to.to_path_buf()
}

/// The pole's counts of `cart` and `swing` as an encoder wired the other way reads them;
/// then more log files than the fit takes, and more bytes of them.
fn inverted_and_too_many_logs_are_refused(dir: &Path, [cart, swing, rig]: [&Path; 3], out: &Path) {
    let (rig_flag, out_flag) = (PathBuf::from("--rig"), PathBuf::from("--out"));
    // Each pole count c as -c - 1.
    let flipped = |path: &Path, name: &str| recounted(path, &dir.join(name), |c, p| (c, -p - 1));
    let (cart_flipped, swing_flipped) = (
        flipped(cart, "cart-inverted.log"),
        flipped(swing, "swing-inverted.log"),
    );
    refused(
        dir,
        &[
            &cart_flipped,
            &swing_flipped,
            &rig_flag,
            rig,
            &out_flag,
            out,
        ],
        &[
            "cart-inverted.log: the pole's counts appear inverted",
            "swap the pole encoder's A and B",
        ],
    );
    // More log files than the fit takes, and more bytes of them: the third of three logs
    // of 22 MiB each (comments, then a whole log) passes 64 MiB in all.
    let many: Vec<&Path> = std::iter::repeat_n(cart, 65)
        .chain([rig_flag.as_path(), rig, out_flag.as_path(), out])
        .collect();
    refused(
        dir,
        &many,
        &["LOG: expected at most 64 log files, found 65"],
    );
    let big = |n: &str| {
        let log = std::fs::read_to_string(cart).unwrap();
        format!("# {n} {}\n{log}", "x".repeat(22 << 20))
    };
    let bigs = ["big1.log", "big2.log", "big3.log"].map(|n| dir.join(n));
    for b in &bigs {
        std::fs::write(b, big(&b.to_string_lossy())).unwrap();
    }
    refused(
        dir,
        &[
            &bigs[0], &bigs[1], &bigs[2], swing, &rig_flag, rig, &out_flag, out,
        ],
        &["big3.log: expected at most 67108864 bytes of logs in all, found 692"],
    );
    for b in &bigs {
        std::fs::remove_file(b).unwrap();
    }
}

#[test]
fn bad_logs_and_rigs_are_refused_and_nothing_is_written() {
    let dir = scratch("bad");
    let [cart, swing, rig] = inputs(&dir);
    let out = dir.join("rig.toml");
    malformed_rows_are_refused(&dir, [&cart, &swing, &rig], &out);
    let (rig_flag, out_flag) = (PathBuf::from("--rig"), PathBuf::from("--out"));
    // A rig file whose motor has no force, and one whose log period is not the rig's.
    let measured = std::fs::read_to_string(&rig).unwrap();
    let no_force = dir.join("no-force.toml");
    let stall = measured
        .lines()
        .find(|l| l.starts_with("stall_force_n"))
        .unwrap();
    std::fs::write(&no_force, measured.replace(stall, "stall_force_n = -1.0")).unwrap();
    refused(
        &dir,
        &[&cart, &swing, &rig_flag, &no_force, &out_flag, &out],
        &["actuator.stall_force_n"],
    );
    let fast = dir.join("fast.toml");
    std::fs::write(
        &fast,
        measured.replace("period_s = 0.02", "period_s = 0.01"),
    )
    .unwrap();
    refused(
        &dir,
        &[&cart, &swing, &rig_flag, &fast, &out_flag, &out],
        &["period_s: expected the rig's period_s 0.01, found 0.02"],
    );
    inverted_and_too_many_logs_are_refused(&dir, [&cart, &swing, &rig], &out);
    a_repeated_experiment_is_refused(&dir, [&cart, &swing, &rig], &out);
    // Only one experiment, and an output that is an input.
    refused(
        &dir,
        &[&cart, &rig_flag, &rig, &out_flag, &out],
        &["expected at least one swing log"],
    );
    refused(
        &dir,
        &[&cart, &swing, &rig_flag, &rig, &out_flag, &cart],
        &["would overwrite the input"],
    );
    let _ = std::fs::remove_dir_all(&dir);
}
