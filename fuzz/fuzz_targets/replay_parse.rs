//! JSON Lines into the trajectory parser; every accepted case is replayed.
#![no_main]

use firmware::cartpole::Params;
use host_sim::replay;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data)
        && let Ok(cases) = replay::parse(text, "fuzz.jsonl")
    {
        for c in &cases {
            replay::replay_case(c, &Params::default()).expect("an accepted case replays");
        }
    }
});
