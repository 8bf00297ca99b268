use super::*;

fn repo(path: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(path)
}

#[test]
fn gymnasiums_rig_file_is_gymnasiums_machine_bit_for_bit() {
    let m = load(&repo("rigs/gymnasium.toml")).unwrap();
    assert_eq!(m, Machine::GYMNASIUM);
}

#[test]
fn the_desk_rig_reads_as_written() {
    let m = load(&repo("rigs/desk.toml")).unwrap();
    let p = m.rig.params;
    assert_eq!((p.masscart, p.masspole, p.length), (0.6, 0.08, 0.22));
    assert_eq!((p.force_mag, p.motor_damping, p.tau), (5.0, 3.0, 0.02));
    assert_eq!(
        (p.x_threshold, m.rig.end_stop_margin, m.rig.dead_time),
        (0.4, 0.05, 1)
    );
    assert_eq!(m.integration, Integration::Rk4 { substeps: 20 });
    assert_eq!(m.rig.encoders.pole_counts_per_rev, 2400);
    // A pole given by its length is uniform: its centre of mass is halfway.
    let text = std::fs::read_to_string(repo("rigs/desk.toml"))
        .unwrap()
        .replace("pole_com_m = 0.22", "pole_length_m = 0.44");
    assert_eq!(parse(&text, "t").unwrap().rig.params.length, 0.22);
}

#[test]
fn a_rig_written_reads_back_bit_for_bit() {
    for m in [
        Machine::GYMNASIUM,
        load(&repo("rigs/desk.toml")).unwrap(),
        Machine {
            rig: Rig {
                params: Params {
                    masscart: 0.613_333_333_333_333_4,
                    length: 1.0 / 3.0,
                    theta_threshold_radians: 0.25,
                    cart_friction: 1e-3,
                    pole_friction: 7e-4,
                    tau: 0.0105,
                    ..Params::default()
                },
                dead_time: 3,
                ..Rig::GYMNASIUM
            },
            integration: Integration::Rk4 { substeps: 7 },
            uncertainty: Uncertainty {
                stall_force: 0.031,
                damping: 0.25 / 3.0,
                pole_com: 0.004,
            },
        },
    ] {
        assert_eq!(parse(&to_toml(&m), "t").unwrap(), m, "{}", to_toml(&m));
    }
}

#[test]
fn every_rig_of_the_repository_loads_and_a_substep_may_be_the_whole_period() {
    let mut names: Vec<_> = std::fs::read_dir(repo("rigs"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    names.sort();
    assert!(names.len() >= 10, "{names:?}");
    for path in names {
        crate::rigfile::load_startup(&path).unwrap_or_else(|e| panic!("{path:?}: {e}"));
    }
    let desk = std::fs::read_to_string(repo("rigs/desk.toml")).unwrap();
    let whole = parse(&format!("{desk}\n[world]\nsubstep_s = 0.02\n"), "t").unwrap();
    assert_eq!(whole.integration, Integration::Rk4 { substeps: 1 });
}

/// A change to the desk rig's file, `(from, to)`, and what its refusal must say.
const BAD_RIGS: &[(&str, &str, &str)] = &[
    // Normal in f64, a subnormal in the board's f32.
    (
        "cart_coulomb = 0.0",
        "cart_coulomb = 1e-40",
        "cart_coulomb: expected zero or a normal number (in the board's f32 too), found 1e-40",
    ),
    (
        "pivot_viscous_n_m_s = 0.0",
        "pivot_viscous_n_m_s = 0.0\n[identified]\nstall_force = -0.01",
        "identified.stall_force: expected a number in [0, 1], found -0.01",
    ),
    (
        "pivot_viscous_n_m_s = 0.0",
        "pivot_viscous_n_m_s = 0.0\n[identified]\npole_com = 1.5",
        "identified.pole_com: expected a number in [0, 1], found 1.5",
    ),
    (
        "pivot_viscous_n_m_s = 0.0",
        "pivot_viscous_n_m_s = 0.0\n[identified.misfit]\ncart_rms_counts = 9.0\npole_rms_counts = -1.0\nautocorrelation = 0.9",
        "identified.misfit.pole_rms_counts: expected a number in [0, ",
    ),
    (
        "pivot_viscous_n_m_s = 0.0",
        "pivot_viscous_n_m_s = 0.0\n[identified.misfit]\ncart_rms_counts = 9.0\npole_rms_counts = 1.0\nautocorrelation = 1.5",
        "identified.misfit.autocorrelation: expected a number in [-1, 1], found 1.5",
    ),
    (
        "pole_mass_kg = 0.08",
        "pole_mass_kg = 2000.0",
        "pole_mass_kg: expected a number in [0.0001, 1000], found 2000",
    ),
    (
        "period_s = 0.02",
        "period_s = 0.0",
        "period_s: expected a number in [0.002, 0.05], found 0",
    ),
    (
        "period_s = 0.02",
        "period_s = 0.1",
        "period_s: expected a number in [0.002, 0.05]",
    ),
    (
        "end_stop_margin_m = 0.05",
        "end_stop_margin_m = 0.5",
        "end_stop_margin_m: expected less than track_half_length_m (0.4)",
    ),
    (
        "cart_mass_kg = 0.6",
        "cart_mass_kg = -1.0",
        "cart_mass_kg: expected a number in [0.001, 1000], found -1",
    ),
    // A slip for 0.3: the physics would divide by it.
    (
        "cart_mass_kg = 0.6",
        "cart_mass_kg = 1e-300",
        "cart_mass_kg: expected a number in [0.001, 1000], found 1e-300",
    ),
    (
        "track_half_length_m = 0.4",
        "track_half_length_m = 1e-200",
        "track_half_length_m: expected a number in [0.001, 100]",
    ),
    (
        "pole_com_m = 0.22",
        "pole_com_m = 0.0009",
        "pole_com_m: expected a number in [0.001, 100]",
    ),
    (
        "pole_mass_kg = 0.08",
        "pole_mass_kg = 0.00009",
        "pole_mass_kg: expected a number in [0.0001, 1000]",
    ),
    (
        "cart_mass_kg = 0.6",
        "gravity_m_s2 = 0.09\ncart_mass_kg = 0.6",
        "gravity_m_s2: expected a number in [0.1, 100]",
    ),
    (
        "cart_mass_kg = 0.6",
        "failure_angle_deg = 0.05\ncart_mass_kg = 0.6",
        "failure_angle_deg: expected a number in [0.1, 90]",
    ),
    (
        "pivot_viscous_n_m_s = 0.0",
        "pivot_viscous_n_m_s = 0.0\n\n[observer]\nforce_sd = 1e-300\naccel_sd = [1.0, 2.0]",
        "observer.force_sd: expected a number in [0.001, 10000]",
    ),
    (
        "cart_mass_kg = 0.6",
        "cart_mass_kg = nan",
        "cart_mass_kg: expected a number",
    ),
    (
        "cart_mass_kg = 0.6",
        "cart_mass_kg = inf",
        "cart_mass_kg: expected a number",
    ),
    (
        "stall_force_n = 5.0",
        "stall_force_n = 0.0",
        "actuator.stall_force_n: expected a number in [0.001,",
    ),
    (
        "damping_n_s_per_m = 3.0",
        "damping_n_s_per_m = -3.0",
        "actuator.damping_n_s_per_m",
    ),
    (
        "dead_time_periods = 1",
        "dead_time_periods = 40",
        "dead_time_periods: expected a whole number in [0, 16], found 40<end>",
    ),
    // No whole number, or past u32: serde named a Rust type ("expected u32").
    (
        "dead_time_periods = 1",
        "dead_time_periods = 1.5",
        "dead_time_periods: expected a whole number in [0, 16], found 1.5<end>",
    ),
    (
        "dead_time_periods = 1",
        "dead_time_periods = 4294967296",
        "found 4294967296<end>",
    ),
    (
        "cart_counts_per_m = 15000",
        "cart_counts_per_m = 1.5e4",
        "encoders.cart_counts_per_m: expected a whole number in [16, 67108864], found 15000.0<end>",
    ),
    (
        "pole_counts_per_rev = 2400",
        "pole_counts_per_rev = 4",
        "encoders.pole_counts_per_rev: expected a whole number in [",
    ),
    (
        "cart_coulomb = 0.0",
        "cart_coulomb = 2.0",
        "friction.cart_coulomb",
    ),
    (
        "pivot_viscous_n_m_s = 0.0",
        "pivot_viscous_n_m_s = 0.2",
        "friction.pivot_viscous_n_m_s: expected a number in [0, 0.1], found 0.2",
    ),
    (
        "cart_counts_per_m = 15000",
        "cart_counts_per_m = 100000000",
        "encoders.cart_counts_per_m: expected a whole number in [16, 67108864], found 100000000<end>",
    ),
    (
        "pole_com_m = 0.22",
        "",
        "expected one of pole_com_m and pole_length_m, found neither",
    ),
    (
        "pole_com_m = 0.22",
        "pole_com_m = 0.22\npole_length_m = 0.44",
        "found both",
    ),
    ("cart_mass_kg = 0.6", "", "missing field `cart_mass_kg`"),
    (
        "cart_mass_kg = 0.6",
        "cart_mass_kg = 0.6\nwheels = 4",
        "unknown field `wheels`",
    ),
    (
        "dead_time_periods = 1",
        "dead_time_periods = 1\n[world]\nintegration = \"rk2\"",
        "world.integration: expected",
    ),
    // A step longer than the period is cut to it: 0.05 and 0.03 built 0.02's world.
    (
        "dead_time_periods = 1",
        "dead_time_periods = 1\n[world]\nsubstep_s = 0.05",
        "world.substep_s (at most period_s): expected a number in [0.00001, 0.02], found 0.05",
    ),
    (
        "dead_time_periods = 1",
        "dead_time_periods = 1\n[world]\nsubstep_s = 0.020000000000000004",
        "world.substep_s (at most period_s): expected a number in [0.00001, 0.02], found \
         0.020000000000000004",
    ),
];

#[test]
fn bad_rigs_are_refused_naming_the_field() {
    let desk = std::fs::read_to_string(repo("rigs/desk.toml")).unwrap();
    for &(from, to, needle) in BAD_RIGS {
        assert!(desk.contains(from), "the desk rig has no {from:?}");
        let text = desk.replace(from, to);
        let e = parse(&text, "rig desk").unwrap_err();
        assert!(e.is_input(), "{to}");
        // `<end>` in a needle holds it to the message's end.
        assert!(format!("{e}<end>").contains(needle), "{to}: {e}");
        assert!(e.to_string().len() < 600, "{}", e.to_string().len());
    }
    // A line of control characters, as the parser quotes it: escaped and cut.
    let text = format!("{}\u{1b}[2J\u{7} = 1\n", "\u{7}".repeat(10_000));
    let e = parse(&text, "rig hostile").unwrap_err().to_string();
    assert!(e.len() < 600 && !e.chars().any(char::is_control), "{e}");
}

/// A misfit table written reads back as written, after the file's other tables and with or
/// without an `[identified]` table of its own; a file without one has none. The machine it
/// describes has every identified half-width widened to at least [`MISFIT_HALF_WIDTH`], a
/// wider one kept.
#[test]
fn a_misfit_reads_back_as_written_and_widens_the_intervals() {
    let m = Misfit {
        cart_rms_counts: 12.5,
        pole_rms_counts: 0.3,
        autocorrelation: 0.97,
    };
    let desk = std::fs::read_to_string(repo("rigs/desk.toml")).unwrap();
    assert_eq!(misfit(&desk, "desk").unwrap(), None);
    let mut identified = Machine::GYMNASIUM;
    identified.uncertainty.stall_force = 0.1;
    identified.uncertainty.damping = 0.8;
    for machine in [Machine::GYMNASIUM, identified] {
        let text = to_toml(&machine) + &m.to_toml();
        assert_eq!(misfit(&text, "t").unwrap(), Some(m), "{text}");
        let read = parse(&text, "t").unwrap();
        let u = machine.uncertainty;
        let widened = Uncertainty {
            stall_force: u.stall_force.max(0.5),
            damping: u.damping.max(0.5),
            pole_com: u.pole_com.max(0.5),
        };
        assert_eq!(read.uncertainty, widened, "{text}");
        assert_eq!(parse(&to_toml(&machine), "t").unwrap(), machine);
        assert_eq!(
            Machine {
                uncertainty: u,
                ..read
            },
            machine
        );
    }
}

#[test]
fn rig_text_from_anywhere_is_held_to_a_rig_files_size_and_refused_with_its_reason() {
    let desk = std::fs::read_to_string(repo("rigs/desk.toml")).unwrap();
    // A policy file's metadata or a configuration's `rig` carries the text, not a file: it
    // is held to the same size (an array of half a million numbers took 79 MB).
    let big = format!("{desk}\nx = [{}]\n", vec!["1"; 40_000].join(","));
    let e = parse(&big, "the recorded rig").unwrap_err().to_string();
    assert!(
        e.contains("expected a rig file's text of at most 65536 bytes, found 80"),
        "{e}"
    );
    // The parser's reason comes first, not cut off behind the offending line's quote.
    let long = desk.replace(
        "cart_mass_kg = 0.6",
        &format!("cart_mass_kg = \"{}\"", "x".repeat(300)),
    );
    assert_ne!(long, desk, "the desk rig's cart mass is written as 0.6");
    // TOML reads 1e-400 as 0: a friction meant tiny, read as none.
    let tiny = desk.replace("cart_coulomb = 0.0", "cart_coulomb = 1e-400");
    assert_ne!(tiny, desk, "the desk rig's friction is written as 0.0");
    let e = parse(&tiny, "rig t").unwrap_err().to_string();
    assert!(
        e.starts_with("rig t: line 24, column 16: 1e-400 reads as 0"),
        "{e}"
    );
    let e = parse(&long, "rig t").unwrap_err().to_string();
    assert!(
        e.starts_with("rig t: line ") && e.contains("expected f64"),
        "{e}"
    );
}

#[test]
fn a_policys_recorded_rig_is_refused_naming_the_policy() {
    let mut metadata = std::collections::BTreeMap::new();
    metadata.insert(METADATA_KEY.to_string(), "cart_mass_kg = nan".to_string());
    let e = recorded(&metadata, "policy runs/x")
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("policy runs/x: its recorded rig: "), "{e}");
    assert_eq!(
        recorded(&Default::default(), "policy runs/x").unwrap(),
        None
    );
}
