//! Scenario and domain specs into their parsers; an accepted scenario's plant, and that of
//! a world drawn from an accepted domain, must stay finite.
#![no_main]

use firmware::cartpole::{Params, State, step_with_force};
use libfuzzer_sys::fuzz_target;
use rand_pcg::Pcg64Mcg;
use twin::{Domain, Scenario};

fn assert_finite(p: &Params, spec: &str) {
    let next = step_with_force(p, &State::from_array([0.0, 0.0, 0.1, 0.0]), p.force_mag);
    assert!(next.to_array().iter().all(|v| v.is_finite()), "{spec:?}");
}

fuzz_target!(|data: &[u8]| {
    let Ok(spec) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(s) = Scenario::parse(spec) {
        assert_finite(&s.params, spec);
    }
    if let Ok(d) = Domain::parse(spec) {
        let mut rng = Pcg64Mcg::new(7);
        for _ in 0..4 {
            assert_finite(&d.sample(&mut rng).params, spec);
        }
    }
});
