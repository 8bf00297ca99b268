use super::*;

mod arriving;

#[test]
fn presets_are_valid_and_the_paper_preset_is_table_2() {
    Config::robust().validate().unwrap();
    let p = Config::paper();
    p.validate().unwrap();
    assert_eq!(
        (p.lr, p.gamma, p.buffer_size, p.batch_size),
        (5e-4, 0.98, 2000, 32)
    );
    assert_eq!(
        (p.target_period, p.target_period_unit),
        (50, Unit::Episodes)
    );
    assert_eq!((p.eps_start, p.eps_end, p.eps_decay), (0.9, 0.01, 200.0));
    assert_eq!((p.episodes, p.max_steps, p.grad_clip), (300, 200, 10.0));
    assert_eq!(
        (p.algo, p.init, p.loss, p.width),
        (Algo::Ddqn, Init::Xavier, Loss::Mse, 64)
    );
}

#[test]
fn the_fixed_and_fast_presets_are_their_documented_changes() {
    let f = Config::paper_fixed();
    f.validate().unwrap();
    assert_eq!(
        f,
        Config {
            reward: "morvan".into(),
            target_period_unit: Unit::Steps,
            ..Config::paper()
        }
    );
    let fast = Config::fast();
    fast.validate().unwrap();
    assert_eq!(
        fast,
        Config {
            reward: "morvan".into(),
            max_env_steps: 50_000,
            episodes: 10_000,
            ..Config::robust()
        }
    );
    assert_eq!((fast.max_steps, fast.eval_max_steps), (500, 500));
    assert!(fast.stop_when_perfect && fast.eval_episodes == 100);
    for p in [
        Preset::Paper,
        Preset::PaperFixed,
        Preset::Fast,
        Preset::Robust,
        Preset::Deploy,
    ] {
        Config::preset(p).validate().unwrap();
    }
}

#[test]
fn configurations_written_before_the_schedule_fields_still_load() {
    let mut old = toml::Table::try_from(Config::paper()).unwrap();
    for k in ["train_unit", "updates_per_train", "max_env_steps"] {
        old.remove(k).unwrap();
    }
    let c: Config = old.try_into().unwrap();
    assert_eq!(c, Config::paper());
}

#[test]
fn bad_values_are_named() {
    let bad = |f: fn(&mut Config), want: &str| {
        let mut c = Config::paper();
        f(&mut c);
        let e = c.validate().unwrap_err().to_string();
        assert!(e.contains(want), "{e:?} lacks {want:?}");
    };
    bad(|c| c.lr = 0.0, "lr must be > 0");
    bad(|c| c.lr = -1e-3, "lr must be > 0");
    bad(|c| c.lr = 1e39, "lr must be > 0 and finite in f32");
    bad(
        |c| c.batch_size = 4000,
        "batch_size (4000) must not exceed buffer_size (2000)",
    );
    bad(|c| c.width = 0, "width must be one of");
    bad(|c| c.gamma = 1.5, "gamma must be in [0, 1]");
    bad(
        |c| c.gamma = 5e-324,
        "gamma must be in [0, 1], zero or normal in f32, got 5e-324",
    );
    bad(
        |c| c.lr = 1e-320,
        "lr must be > 0 and finite in f32, got 1e-320",
    );
    bad(
        |c| c.grad_clip = 1e-40,
        "grad_clip must be >= 0 and finite in f32, zero or normal",
    );
    bad(|c| c.gamma = -0.1, "gamma must be in [0, 1]");
    bad(
        |c| c.episodes = 0,
        "episodes must be in [1, 1000000], got 0",
    );
    bad(
        |c| c.episodes = usize::MAX,
        "episodes must be in [1, 1000000]",
    );
    bad(
        |c| c.buffer_size = 10_000_000_000,
        "buffer_size must be in [1, 5000000]",
    );
    bad(
        |c| c.max_steps = u32::MAX,
        "max_steps must be in [1, 1000000]",
    );
    bad(
        |c| c.final_eval_episodes = 0,
        "final_eval_episodes must be in [1, 100000]",
    );
    bad(
        |c| c.finalists = 3,
        "finalists (3) need finalist_episodes and finalist_max_steps >= 1, got 0 and 0",
    );
    bad(|c| c.adam_eps = 1e-50, "adam_eps must be a normal f32 > 0");
    bad(|c| c.tau = 0.0, "tau must be in (0, 1]");
}

#[test]
fn every_preset_read_whole_over_any_other_asks_for_nothing_unread() {
    use clap::ValueEnum;
    let on = |p: &Preset| Config::preset_on(*p, &twin::Machine::GYMNASIUM);
    for p in Preset::value_variants() {
        for q in Preset::value_variants() {
            assert_eq!(on(p).unread(&on(q)), Ok(()), "{p:?} over {q:?}");
        }
    }
    // A preset's value its mode turned off no longer reads is put back to the default, so
    // what is recorded reads back over any preset.
    let deploy = Config::deploy();
    let mut quiet = Config {
        eval_every: 0,
        ..deploy.clone()
    };
    assert_ne!(deploy.patience, Config::paper().patience);
    quiet.unread(&deploy).unwrap();
    assert_eq!(quiet.patience, Config::paper().patience);
    assert_eq!(quiet.clone().unread(&Config::paper()), Ok(()));
    let mut hard = Config {
        tau: 0.5,
        ..Config::paper()
    };
    assert_eq!(
        hard.unread(&Config::fast()).unwrap_err().0,
        "tau = 0.5 is read only when target_update is soft; target_update = \"hard\" ignores it"
    );
}

#[test]
fn the_documented_limits_are_the_checked_ones() {
    let doc = include_str!("../../../docs/HOSTILE_INPUT.md");
    for l in LIMITS {
        let Limit::Count(range) = &l.limit else {
            continue;
        };
        let (key, min, max) = (l.key, *range.start(), *range.end());
        let row = format!("| `{key}` | {min} to {max}");
        assert!(doc.contains(&row), "docs/HOSTILE_INPUT.md lacks {row:?}");
        let mut at_max = Config::paper();
        let mut over = Config::paper();
        set(&mut at_max, key, max);
        set(&mut over, key, max + 1);
        assert!(over.validate().unwrap_err().0.contains(key), "{key}");
        // The limit itself is accepted (where other fields allow it).
        if let Err(e) = at_max.validate() {
            assert!(!e.0.contains(&format!("{key} must be in")), "{e}");
        }
    }
}

/// Sets the count named `key` through the TOML overlay, as a user would.
fn set(c: &mut Config, key: &str, v: u64) {
    *c = c.overlay_toml(&format!("{key} = {v}"), "t.toml").unwrap();
}

#[test]
fn toml_overlays_known_keys_and_rejects_unknown_ones() {
    let c = Config::paper()
        .overlay_toml(
            "gamma = 0.99\nalgo = \"dqn\"\ninit = \"normal0.1\"\n",
            "t.toml",
        )
        .unwrap();
    assert_eq!((c.gamma, c.algo, c.init), (0.99, Algo::Dqn, Init::Normal01));
    assert_eq!(c.lr, 5e-4);
    let e = Config::paper()
        .overlay_toml("gama = 0.99\n", "t.toml")
        .unwrap_err();
    assert!(e.0.contains("unknown key \"gama\""), "{e}");
    let e = Config::paper()
        .overlay_toml("gamma = \"high\"\n", "t.toml")
        .unwrap_err();
    assert!(e.0.contains("t.toml"), "{e}");
    // TOML reads 1e-400 as 0, which turns clipping off.
    let e = Config::paper()
        .overlay_toml("gamma = 0.9 # 1e-400\ngrad_clip = 1e-400\n", "t.toml")
        .unwrap_err();
    assert!(
        e.0.starts_with("t.toml: line 2, column 13: 1e-400 reads as 0"),
        "{e}"
    );
    // And so inside a spec a string holds: levels of -1, 0 and 1 trained, recorded as such.
    let e = Config::paper()
        .overlay_toml("levels = \"-1,1e-400,1\"\n", "t.toml")
        .unwrap_err();
    assert!(
        e.0.starts_with("t.toml: line 1, column 14: 1e-400 reads as 0"),
        "{e}"
    );
    // A parser message that quotes a huge line is cut.
    let long = format!("gamma = [{}\n", "1, ".repeat(100_000));
    let e = Config::paper().overlay_toml(&long, "big.toml").unwrap_err();
    assert!(e.0.len() < 600, "{}", e.0.len());
    // Control characters the parser quotes arrive escaped: a terminal sees no ESC or BEL.
    let hostile = format!(
        "gamma = \"{}\"\nlr = \u{1b}[2J\u{7}\n",
        "\u{1b}]0;x\u{7}".repeat(5_000)
    );
    let e = Config::paper()
        .overlay_toml(&hostile, "t.toml")
        .unwrap_err();
    assert!(e.0.len() < 600 && !e.0.chars().any(char::is_control), "{e}");
}

fn paper_table() -> toml::Table {
    toml::Table::try_from(Config::paper()).unwrap()
}

/// The flags of every key, as `train` takes them.
fn flag_parser() -> clap::Command {
    <Overrides as clap::Args>::augment_args(
        clap::Command::new("train").allow_negative_numbers(true),
    )
}

/// Values of the flag `arg` other than `v`, its key's paper value.
fn other_values(v: &toml::Value, arg: &clap::Arg) -> Vec<toml::Value> {
    match v {
        toml::Value::Integer(n) => vec![toml::Value::Integer(n + 1)],
        toml::Value::Float(x) => vec![toml::Value::Float(x + 0.5)],
        toml::Value::Boolean(b) => vec![toml::Value::Boolean(!b)],
        toml::Value::String(s) => {
            let named: Vec<toml::Value> = arg
                .get_possible_values()
                .iter()
                .map(|p| p.get_name())
                .filter(|name| name != s)
                .map(|name| toml::Value::String(name.into()))
                .collect();
            if named.is_empty() {
                vec![toml::Value::String(format!("{s}x"))]
            } else {
                named
            }
        }
        other => panic!("a key of unexpected TOML type: {other}"),
    }
}

#[test]
fn every_key_has_one_flag_which_sets_that_key_as_the_toml_key_does() {
    let paper = paper_table();
    let parser = flag_parser();
    let mut flags: Vec<String> = parser
        .get_arguments()
        .map(|a| a.get_long().unwrap().replace('-', "_"))
        .collect();
    flags.sort();
    // `rig`'s flag names a file, so `train` declares it (tests/rig_cli.rs).
    let keys: Vec<&String> = paper.keys().filter(|k| *k != "rig").collect();
    assert_eq!(flags.iter().collect::<Vec<_>>(), keys);
    for arg in parser.get_arguments() {
        let flag = format!("--{}", arg.get_long().unwrap());
        let key = arg.get_long().unwrap().replace('-', "_");
        for v in other_values(&paper[&key], arg) {
            let text = match &v {
                toml::Value::String(s) => s.clone(),
                v => v.to_string(),
            };
            let m = flag_parser()
                .try_get_matches_from(["train", &flag, &text])
                .unwrap();
            let mut by_flag = Config::paper();
            <Overrides as clap::FromArgMatches>::from_arg_matches(&m)
                .unwrap()
                .apply(&mut by_flag);
            let by_file = Config::paper()
                .overlay_toml(&format!("{key} = {v}"), "t.toml")
                .unwrap();
            assert_eq!(by_flag, by_file, "{flag} {text}");
            let mut want = paper.clone();
            want.insert(key.clone(), v);
            assert_eq!(toml::Table::try_from(&by_flag).unwrap(), want, "{flag}");
        }
    }
}

#[test]
fn a_file_setting_every_key_round_trips() {
    let presets = [
        Preset::Paper,
        Preset::PaperFixed,
        Preset::Fast,
        Preset::Robust,
        Preset::Deploy,
    ];
    for p in presets {
        let c = Config::preset(p);
        let file = toml::to_string(&c).unwrap();
        for base in presets {
            let read = Config::preset(base).overlay_toml(&file, "t.toml").unwrap();
            assert_eq!(read, c, "{p:?} over {base:?}");
        }
        let json = serde_json::to_string(&c).unwrap();
        assert_eq!(serde_json::from_str::<Config>(&json).unwrap(), c, "{p:?}");
    }
}

#[test]
fn a_file_lacking_a_key_gets_its_paper_value_or_is_refused_naming_it() {
    let paper = paper_table();
    let deploy = toml::Table::try_from(Config::deploy()).unwrap();
    for key in paper.keys() {
        let mut lacking = deploy.clone();
        lacking.remove(key);
        match lacking.try_into::<Config>() {
            Ok(read) => {
                let mut want = deploy.clone();
                want.insert(key.clone(), paper[key].clone());
                assert_eq!(toml::Table::try_from(&read).unwrap(), want, "{key}");
            }
            Err(e) => assert!(
                e.to_string().contains(&format!("missing field `{key}`")),
                "{key}: {e}"
            ),
        }
    }
}

#[test]
fn every_count_has_an_upper_limit_and_no_real_key_takes_infinity_or_nan() {
    for (key, v) in paper_table() {
        let huge = match v {
            toml::Value::Integer(_) => vec![u32::MAX.to_string()],
            toml::Value::Float(_) => vec!["inf".into(), "-inf".into(), "nan".into()],
            _ => continue,
        };
        for h in huge {
            let c = Config::paper()
                .overlay_toml(&format!("{key} = {h}"), "t.toml")
                .unwrap();
            let e = c.validate().unwrap_err().0;
            assert!(e.contains(&key), "{key} = {h}: {e}");
        }
    }
}

#[test]
fn a_limit_refuses_a_value_of_another_kind() {
    for (limit, v) in [
        (Limit::Count(0..=10), Value::Real(1.0)),
        (Limit::ZeroToOne, Value::Whole(1)),
        (Limit::Domain, Value::Whole(0)),
    ] {
        let e = limit.check("k", v).unwrap_err();
        assert!(e.starts_with("k: "), "{e}");
    }
}

#[test]
fn the_deploy_recipe_is_made_for_its_machine() {
    // On Gymnasium's machine, the recipe's worlds as they were written.
    let g = Config::deploy();
    assert!(
        g.domain.ends_with("+delay=0..4@0.5+push=0.8..1.2/50"),
        "{}",
        g.domain
    );
    assert!(
        g.eval_domain
            .ends_with("+delay=0..1+encoder+push=0.5/100@0.5"),
        "{}",
        g.eval_domain
    );
    assert!(
        g.finalist_domain
            .ends_with("+noise=0..1@0.5+encoder+push=1.1/50")
    );
    assert_eq!(
        (g.max_steps, g.finalist_max_steps, g.rig.as_str()),
        (500, 10_000, "")
    );
    assert_eq!(
        (g.levels.as_str(), g.reward.as_str()),
        ("", "upright=20+centre=5")
    );
    // The shipped policy keeps its bits: its finalists are not tried as int8 boards.
    assert!(!g.board_int8);
    // A weaker motor at twice the rate: pushes half as strong, counts of periods doubled.
    let text = "cart_mass_kg = 0.6\npole_mass_kg = 0.08\npole_com_m = 0.22\n\
                track_half_length_m = 0.4\nend_stop_margin_m = 0.05\nperiod_s = 0.01\n\
                dead_time_periods = 2\n[encoders]\ncart_counts_per_m = 15000\n\
                pole_counts_per_rev = 2400\n[actuator]\nstall_force_n = 5.0\n\
                damping_n_s_per_m = 3.0\n";
    let m = twin::rigfile::parse(text, "t").unwrap();
    let d = Config::deploy_on(&m);
    assert!(d.domain.ends_with("+push=0.4..0.6/100"), "{}", d.domain);
    // Its trial's pushes are the periodic evaluation's, which a balanced rig survives, and
    // its cost chooses among the finalists surviving within 5% of the longest.
    assert!(
        d.finalist_domain.ends_with("+encoder+push=0.25/200"),
        "{}",
        d.finalist_domain
    );
    assert_eq!((d.trial_margin, g.trial_margin), (0.05, 0.0));
    assert_eq!(
        (d.max_steps, d.eval_max_steps, d.finalist_max_steps),
        (1000, 1000, 20_000)
    );
    assert_eq!(d.machine().unwrap(), m);
    // A rig's motor is driven gently: nine levels, effort paid for at the same price per
    // second as at 50 Hz: a change of duty weighs twice beside the per-period parts, and
    // the discount reaches as many seconds ahead (0.99 per 20 ms).
    assert_eq!(d.levels, "-1,-0.4,-0.15,-0.05,0,0.05,0.15,0.4,1");
    assert_eq!(d.reward, "upright=20+centre=5+effort=1+smooth=40");
    assert!((d.gamma * d.gamma - 0.99).abs() < 1e-15, "{}", d.gamma);
    assert_eq!(g.gamma, 0.99);
    // And judged as each of its boards runs it, stopping once settled, on a shorter trial
    // than the shipped policy's.
    assert!(d.board_int8);
    assert_eq!((d.settle, d.finalists, d.finalist_episodes), (5, 8, 25));
    assert_eq!((g.settle, g.finalists, g.finalist_episodes), (0, 20, 50));
    d.validate().unwrap();
}

/// On Gymnasium's machine the deploy domains are the shipped recipe's, to the character (the
/// recipe's strings are recorded in the policy file); on a rig with a damped motor the damping
/// is drawn too, and a value identified less precisely than the range is drawn wider, as is
/// every value of a fit that did not explain its logs.
#[test]
fn deploy_domains_widen_to_the_identifications_intervals() {
    let g = Config::deploy();
    assert_eq!(
        g.domain,
        "length=0.75..1.25+polemass=0.75..1.25+cartmass=0.75..1.25+force=0.75..1.25\
         +friction=0..0.1/0..0.002@0.3+noise=0..1.2@0.3+encoder=256..8192@0.3+jitter=0..0.1@0.3\
         +delay=0..4@0.5+push=0.8..1.2/50"
    );
    assert_eq!(
        g.finalist_domain,
        "length=0.8..1.2+polemass=0.8..1.2+cartmass=0.8..1.2+force=0.8..1.2+noise=0..1@0.5\
         +encoder+push=1.1/50"
    );
    let mut m = twin::rigfile::parse(include_str!("../../../rigs/desk.toml"), "desk").unwrap();
    m.uncertainty.stall_force = 0.4;
    m.uncertainty.pole_com = 0.1;
    let d = Config::deploy_on(&m);
    for spec in [&d.domain, &d.eval_domain] {
        assert!(spec.starts_with("length=0.75..1.25+"), "{spec}");
        assert!(
            spec.contains("+force=0.6..1.4+damping=0.75..1.25+"),
            "{spec}"
        );
    }
    assert!(
        d.finalist_domain
            .contains("+force=0.6..1.4+damping=0.8..1.2+")
    );
    d.validate().unwrap();
    // A fit that did not explain its logs: every value drawn over +-50% at least.
    let misfit = "\n[identified]\nstall_force = 0.01\ndamping = 0.75\npole_com = 0.01\n\
                  [identified.misfit]\ncart_rms_counts = 9.0\npole_rms_counts = 1.2\n\
                  autocorrelation = 0.9\n";
    let text = include_str!("../../../rigs/desk.toml").to_owned() + misfit;
    let d = Config::deploy_on(&twin::rigfile::parse(&text, "misfit").unwrap());
    for spec in [&d.domain, &d.eval_domain, &d.finalist_domain] {
        assert!(spec.starts_with("length=0.5..1.5+polemass="), "{spec}");
        assert!(
            spec.contains("+force=0.5..1.5+damping=0.25..1.75"),
            "{spec}"
        );
    }
}
