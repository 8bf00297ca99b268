//! TOML text into the trainer's configuration overlay, then its validation.
#![no_main]

use libfuzzer_sys::fuzz_target;
use policy_export::config::Config;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data)
        && let Ok(cfg) = Config::paper().overlay_toml(text, "fuzz.toml")
    {
        let _ = cfg.validate();
    }
});
