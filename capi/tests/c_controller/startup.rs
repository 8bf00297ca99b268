//! The C start-up beside the Rust [`Sequencer`], period for period.

use firmware::startup::Homing;

use super::*;

/// Under the start-up of `flags`: the pole hanging at power-on, swinging 10 degrees, zeroed,
/// swung up and caught (homing first, from a cart a metre off the centre, with `HOME`), the
/// phase asked every 50 periods; states refused once it runs. Asserts that the loop reached
/// the balance, so that every phase's periods were compared.
pub(crate) fn script<O: Format, P: Policy<O, Scores = <O as Scores>::Scores> + Copy>(
    policy: P,
    rig: &Rig,
    kind: i32,
    script: &mut Script,
    flags: i32,
) {
    let home = flags & CARTPOLE_STARTUP_HOME != 0;
    script.call(&format!("init {kind}"), &format!("init {CARTPOLE_OK}"));
    script.call(
        "phase",
        &format!("phase refused {CARTPOLE_ERR_NO_STARTUP} 1"),
    );
    script.call("startup 4", &format!("startup {CARTPOLE_ERR_FLAGS}"));
    script.call(
        &format!("startup {flags}"),
        &format!("startup {CARTPOLE_OK}"),
    );
    let sensor = ObserverSensor::<_, O>::new(rig.observer().unwrap(), Latest::default());
    let mut c = board(policy, sensor, rig);
    let startup = Startup {
        homing: home.then(|| Homing::suggested(rig.params.tau)),
        ..Startup::suggested(rig).unwrap()
    };
    let mut sequencer = Sequencer::new(startup, rig).unwrap();
    let x = if home { 1.0 } else { 0.0 };
    let mut s = State::from_array([x, 0.0, std::f64::consts::PI - 0.17, 0.0]);
    let origin = rig.encoders.counts(s.x, s.theta);
    let fine = firmware::cartpole::Params {
        tau: rig.params.tau / 20.0,
        ..rig.params
    };
    for k in 0..if home { 2500 } else { 1500 } {
        let (cart, pole) = rig.encoders.counts(s.x, s.theta);
        let counts = (cart.wrapping_sub(origin.0), pole.wrapping_sub(origin.1));
        c.sensor_mut().counter_mut().0 = counts;
        sequencer.run(counts, &mut c);
        script.call(&format!("count {} {}", counts.0, counts.1), &step_line(&c));
        if k % 50 == 49 {
            let t = sequencer.transitions();
            let phase = sequencer.phase() as u32;
            let (z, e, ca, m, f) = (t.zeroed, t.entered, t.caught, t.missed, t.fell);
            let (trim, h) = (sequencer.trim().to_bits(), t.homed);
            script.call(
                "phase",
                &format!("phase {CARTPOLE_OK} {phase} {z} {e} {ca} {m} {f} {trim:08x} {h}"),
            );
        }
        // Euler's steps of a whole period feed a free swing energy: twenty shorter ones do not.
        for _ in 0..20 {
            s = advance(&fine, &s, loopback::duty(c.actuator()), 0.0);
            // The track's end stops, which homing drives the cart against: they stop a cart
            // moving into them, and let one pushed away go.
            if s.x.abs() >= rig.params.x_threshold && s.x * s.x_dot > 0.0 {
                (s.x, s.x_dot) = (s.x.clamp(-1.0, 1.0) * rig.params.x_threshold, 0.0);
            }
        }
    }
    assert_eq!(sequencer.phase(), Phase::Balancing);
    assert_eq!(sequencer.transitions().homed, u32::from(home));
    script.call("state 0 0 0 0", &format!("refused {CARTPOLE_ERR_INPUT} 1"));
}
