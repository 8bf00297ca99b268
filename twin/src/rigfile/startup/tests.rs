use firmware::startup::Startup;

use crate::rigfile::parse_startup;

/// The desk rig's file with `table` appended, read with its start-up.
fn desk_with(table: &str) -> weights::Result<Startup> {
    let repo = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let text = std::fs::read_to_string(repo.join("rigs/desk.toml")).unwrap();
    parse_startup(&format!("{text}\n[startup]\n{table}\n"), "desk").map(|(_, s)| s)
}

#[test]
fn a_startup_table_overrides_the_suggested_values_it_names() {
    let repo = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let rig = crate::rigfile::load(&repo.join("rigs/desk.toml"))
        .unwrap()
        .rig;
    let suggested = desk_with("").unwrap();
    assert_eq!(suggested, Startup::suggested(&rig).unwrap());
    let s = desk_with("catch_angle_deg = 6.0\nzero_window_s = 0.5\nswing_max_accel_m_s2 = 3.0")
        .unwrap();
    assert_eq!(s.catch_angle, 6f64.to_radians() as f32);
    // 0.5 s at 50 Hz: 25 periods.
    assert_eq!(s.zero_periods, 25);
    assert_eq!(s.swing.unwrap().max_accel, 3.0);
    assert_eq!(s.catch_rate, suggested.catch_rate);
    assert_eq!(desk_with("swing_up = false").unwrap().swing, None);
    assert_eq!(desk_with("").unwrap().homing, None);
    let h = desk_with("homing = true\nhoming_duty = 0.25\nhoming_stall_s = 0.3")
        .unwrap()
        .homing
        .unwrap();
    // 0.3 s at 50 Hz: 15 periods.
    assert_eq!((h.duty, h.stall_periods), (0.25, 15));
    let t = desk_with("trim_deg_per_m_s = 0.5\ntrim_max_deg = 1").unwrap();
    assert_eq!(
        (t.trim_rate, t.trim_max),
        (0.5f64.to_radians() as f32, 1f64.to_radians() as f32)
    );
    assert_eq!(desk_with("trim_deg_per_m_s = 0").unwrap().trim_rate, 0.0);
}

#[test]
fn regions_a_board_cannot_run_are_refused_naming_the_field() {
    let refusal = |table: &str| desk_with(table).unwrap_err().to_string();
    let e = refusal("release_angle_deg = 13.0");
    assert!(
        e.contains("startup.release_angle: expected at most params.theta_threshold_radians"),
        "{e}"
    );
    let e = refusal("catch_angle_deg = 11.5");
    assert!(
        e.contains("startup.catch_angle: expected below startup.release_angle"),
        "{e}"
    );
    let e = refusal("catch_rate_deg_s = nan");
    assert!(
        e.contains("startup.catch_rate_deg_s: expected a number in (0, 10000], found NaN"),
        "{e}"
    );
    let e = refusal("catch_angle_deg = -1.0");
    assert!(e.contains("startup.catch_angle_deg"), "{e}");
    // Past u16 and no whole number alike: serde named a Rust type ("expected u16").
    for n in ["0", "501", "65535", "70000", "2.5", "-1", "\"3\""] {
        let e = refusal(&format!("catch_periods = {n}"));
        assert!(
            e.contains(&format!(
                "startup.catch_periods: expected 1 to 500 periods, found {n}"
            )),
            "{e}"
        );
    }
    // The board holds these in f32 radians: 1e-37 degrees is a subnormal there.
    let e = refusal("catch_rate_deg_s = 1e-37");
    assert!(
        e.contains("startup.catch_rate_deg_s: expected zero or a number the board's f32"),
        "{e}"
    );
    // A swing-up's values where none runs are refused, as homing's are.
    let e = refusal("swing_up = false\nswing_energy_gain_s = 1e-300\nswing_overshoot = 5");
    assert!(
        e.contains(
            "startup.swing_energy_gain_s, startup.swing_overshoot: given, but no swing-up runs"
        ),
        "{e}"
    );
    let e = refusal("trim_deg_per_m_s = -0.1");
    assert!(
        e.contains("startup.trim_deg_per_m_s: expected a number in [0, 90], found -0.1"),
        "{e}"
    );
    let e = refusal("trim_max_deg = 9");
    assert!(
        e.contains("startup.trim_max: expected below startup.catch_angle"),
        "{e}"
    );
    // A limit of a trim that never runs, or one that leaves the rate nothing to do.
    let e = refusal("trim_deg_per_m_s = 0\ntrim_max_deg = 2.0");
    assert!(
        e.contains("startup.trim_max_deg: given, but the trim is off (trim_deg_per_m_s = 0)"),
        "{e}"
    );
    let e = refusal("trim_max_deg = 0");
    assert!(
        e.contains("startup.trim_max_deg: expected a number in (0, 90], found 0"),
        "{e}"
    );
    let e = refusal("homing = true\nhoming_duty = 1.5");
    assert!(
        e.contains("startup.homing_duty: expected a number in (0, 1], found 1.5"),
        "{e}"
    );
    let e = refusal("homing_duty = 0.2");
    assert!(e.contains("given, but homing is not true"), "{e}");
    let e = refusal("catch_region = 3");
    assert!(e.contains("unknown field `catch_region`"), "{e}");
}
