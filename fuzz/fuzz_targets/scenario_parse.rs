//! Scenario specs into the parser; an accepted scenario's plant must stay finite.
#![no_main]

use firmware::cartpole::{State, step_with_force};
use host_sim::twin::Scenario;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(spec) = std::str::from_utf8(data)
        && let Ok(s) = Scenario::parse(spec)
    {
        let next = step_with_force(
            &s.params,
            &State::from_array([0.0, 0.0, 0.1, 0.0]),
            s.params.force_mag,
        );
        assert!(next.to_array().iter().all(|v| v.is_finite()), "{spec:?}");
    }
});
