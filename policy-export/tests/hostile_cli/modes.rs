//! Training keys that the chosen mode never reads (a soft update's period, a hard one's tau,
//! finalists' keys without finalists, early stops without periodic evaluations, the dead-time
//! predictor without dead time): refused when given, where they were recorded and dropped; a
//! preset's own values pass. And domains judged on the machine trained for.

use super::{refused, run, scratch, stderr};

#[test]
fn a_key_its_mode_never_reads_is_refused() {
    let fast = ["train", "--preset", "fast", "--print-config"];
    let with = |rest: &[&'static str]| [&fast[..], rest].concat();
    let cases: [(Vec<&str>, &str); 6] = [
        (
            with(&[
                "--eps-start",
                "0.1",
                "--eps-end",
                "0.1",
                "--eps-decay",
                "500",
            ]),
            "eps_decay = 500.0 is read only when eps_start is other than eps_end; eps_start = 0.1 \
             ignores it",
        ),
        (
            with(&["--target-update", "hard", "--tau", "0.5"]),
            "tau = 0.5 is read only when target_update is soft; target_update = \"hard\" ignores it",
        ),
        (
            with(&["--target-period", "7"]),
            "target_period = 7 is read only when target_update is hard; target_update = \"soft\"",
        ),
        (
            with(&[
                "--finalists",
                "0",
                "--trial-margin",
                "0.5",
                "--finalist-domain",
                "noise",
            ]),
            "finalist_domain = \"noise\" is read only when finalists is above 0; finalists = 0 \
             ignores it; trial_margin = 0.5 is read only when finalists is above 0",
        ),
        (
            with(&["--eval-every", "0", "--settle", "5", "--patience", "5"]),
            "patience = 5 is read only when eval_every is above 0; eval_every = 0 ignores it; \
             settle = 5",
        ),
        (
            vec![
                "train",
                "--print-config",
                "--finalists",
                "3",
                "--finalist-episodes",
                "2",
                "--finalist-max-steps",
                "9",
            ],
            "finalists = 3 is read only when eval_every is above 0",
        ),
    ];
    for (args, want) in cases {
        refused(&args, want);
    }
}

/// A preset's own values pass with their mode turned off, and so does every preset's
/// configuration read back whole over another.
#[test]
fn a_presets_own_values_and_the_defaults_pass_with_their_mode_off() {
    let fast = ["train", "--preset", "fast", "--print-config"];
    let with = |rest: &[&'static str]| [&fast[..], rest].concat();
    let dir = scratch("modes");
    for preset in [
        &["--preset", "paper"][..],
        &["--preset", "deploy"],
        &["--preset", "fast"],
    ] {
        let mut args = vec!["train", "--print-config"];
        args.extend(preset);
        let o = run(&args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        let file = dir.join("all.toml");
        std::fs::write(&file, &o.stdout).unwrap();
        let again = run(&[
            "train",
            "--preset",
            "robust",
            "--print-config",
            "--config",
            file.to_str().unwrap(),
        ]);
        assert_eq!(again.stdout, o.stdout, "{args:?}: {}", stderr(&again));
    }
    for args in [
        &[
            "train",
            "--preset",
            "deploy",
            "--print-config",
            "--eval-every",
            "0",
        ][..],
        &[
            "train",
            "--preset",
            "deploy",
            "--print-config",
            "--finalists",
            "0",
        ],
        &[
            "train",
            "--rig",
            "../rigs/desk-identified.toml",
            "--preset",
            "deploy",
            "--print-config",
        ],
        &with(&[
            "--eval-every",
            "0",
            "--settle",
            "0",
            "--target-update",
            "hard",
            "--tau",
            "0.005",
        ]),
    ] {
        let o = run(args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The dead-time predictor in worlds without dead time advances nothing: refused when asked
/// for, where it was recorded and dropped; a preset's own is put back to its default. What
/// has dead time is the machine trained for and the domains drawn around it.
#[test]
fn the_predictor_is_read_only_where_a_world_has_dead_time() {
    let robust = [
        "train",
        "--preset",
        "robust",
        "--print-config",
        "--compensate",
        "true",
    ];
    refused(
        &robust,
        "compensate = true is read only when a world has dead time; the machine trained for \
         has no dead time and no domain draws any",
    );
    refused(
        &[&robust[..], &["--domain", "noise=0..1"]].concat(),
        "compensate = true is read only when a world has dead time",
    );
    // The desk's own dead time, taken out by every domain drawn.
    refused(
        &[
            "train",
            "--rig",
            "../rigs/desk.toml",
            "--print-config",
            "--compensate",
            "true",
            "--domain",
            "delay=0",
            "--eval-domain",
            "noise+delay=0",
        ],
        "compensate = true is read only when a world has dead time; every domain drawn sets \
         the machine's dead time of 1 period to none",
    );
    let config = |args: &[&str]| {
        let o = run(&[&["train", "--print-config"][..], args].concat());
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        String::from_utf8(o.stdout).unwrap()
    };
    for args in [
        &["--rig", "../rigs/desk.toml", "--compensate", "true"][..],
        &["--compensate", "true", "--eval-domain", "delay=0..2@0.5"],
        &["--compensate", "true", "--domain", "delay"],
        &["--preset", "deploy"],
    ] {
        assert!(config(args).contains("compensate = true"), "{args:?}");
    }
    let still = [
        "--preset",
        "deploy",
        "--domain",
        "noise",
        "--eval-domain",
        "noise",
    ];
    // The deploy preset's finalist domain draws no dead time either.
    assert!(config(&still).contains("compensate = false"), "{still:?}");
    let all = [&still[..], &["--finalist-domain", "noise"]].concat();
    assert!(config(&all).contains("compensate = false"), "{all:?}");
}

/// A domain is drawn around the machine trained for: a damping range scales nothing on a
/// motor without damping (Gymnasium's), and is drawn on one with some.
#[test]
fn a_domain_is_judged_on_the_machine_trained_for() {
    for key in ["--domain", "--eval-domain"] {
        refused(
            &["train", "--print-config", key, "noise=0..1+damping=0.5..2"],
            "domain \"noise=0..1+damping=0.5..2\": damping changes nothing on a machine without \
             motor damping; expected another part, or a rig that has some",
        );
        let desk = ["--rig", "../rigs/desk.toml", key, "damping=0.5..2"];
        let o = run(&[&["train", "--print-config"][..], &desk].concat());
        assert!(o.status.success(), "{desk:?}: {}", stderr(&o));
    }
}

/// A domain's parts are judged as its sampler builds them, on the machine trained for: the
/// factors of one quantity together, and a part beside the parts it needs.
#[test]
fn a_domain_whose_parts_build_only_the_machine_is_refused() {
    for rig in [&[][..], &["--rig", "../rigs/desk.toml"]] {
        let train = [&["train", "--print-config"][..], rig].concat();
        for (domain, want) in [
            (
                "length=2+length=0.5",
                "domain \"length=2+length=0.5\": length changes nothing on this machine: its \
                 factors multiply to 1",
            ),
            (
                "noise=0..1+jitter=0..0.1",
                "jitter changes nothing under exact sensing, where no encoder is read early or \
                 late; expected an encoder part beside it",
            ),
        ] {
            refused(&[&train[..], &["--domain", domain]].concat(), want);
        }
        // Either coin may fall alone; an encoder part drawn in some worlds.
        for domain in [
            "length=2@0.5+length=0.5@0.5",
            "noise=0..1+jitter=0..0.1@0.3+encoder=256..8192@0.3",
        ] {
            let args = [&train[..], &["--domain", domain]].concat();
            let o = run(&args);
            assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        }
    }
}

/// The run's own flags are no part of the printed configuration: given with
/// `--print-config`, each was accepted and changed nothing (no run directory, no seed).
#[test]
fn print_config_takes_none_of_the_runs_own_flags() {
    for (flag, value) in [
        ("--out", "never"),
        ("--seed", "7"),
        ("--seeds", "0..3"),
        ("--threads", "2"),
    ] {
        let o = run(&["train", "--print-config", flag, value]);
        assert_eq!(o.status.code(), Some(2), "{flag}: {}", stderr(&o));
        let want = format!("'--print-config' cannot be used with '{flag}");
        assert!(stderr(&o).contains(&want), "{flag}: {}", stderr(&o));
        assert!(o.stdout.is_empty() && !std::path::Path::new("never").exists());
    }
}
