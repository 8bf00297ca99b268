//! Scenario and domain specs into their parsers; an accepted scenario's plant, and that of
//! a world drawn from an accepted domain, must stay finite.
#![no_main]

use firmware::cartpole::{Plant, State};
use libfuzzer_sys::fuzz_target;
use rand_pcg::Pcg64Mcg;
use twin::machine::advance;
use twin::{Domain, Scenario};

/// One period at full duty in the scenario's own world (Euler or Runge-Kutta).
fn assert_finite(s: &Scenario, spec: &str) {
    let start = State::from_array([0.0, 0.0, 0.1, 0.0]);
    let next = advance(&Plant::new(&s.params), s.integration, &start, 1.0, 0.0);
    assert!(next.to_array().iter().all(|v| v.is_finite()), "{spec:?}");
}

fuzz_target!(|data: &[u8]| {
    let Ok(spec) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(s) = Scenario::parse(spec) {
        assert_finite(&s, spec);
    }
    if let Ok(d) = Domain::parse(spec) {
        let mut rng = Pcg64Mcg::new(7);
        for _ in 0..4 {
            assert_finite(&d.sample(&mut rng), spec);
        }
    }
});
