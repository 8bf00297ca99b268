//! The configuration parser against hostile TOML: random text and random assignments to
//! the real keys never panic; a document is either refused with a short message or gives a
//! configuration that `validate` then accepts or refuses, again without panicking.

use std::sync::LazyLock;

use policy_export::config::Config;
use proptest::prelude::*;
use proptest::test_runner::Config as Cases;

/// Every key a file may set.
static KEYS: LazyLock<Vec<String>> = LazyLock::new(|| {
    toml::Table::try_from(Config::paper())
        .unwrap()
        .keys()
        .cloned()
        .collect()
});

fn check(text: &str) {
    match Config::paper().overlay_toml(text, "fuzz.toml") {
        Ok(cfg) => {
            if let Err(e) = cfg.validate() {
                assert!(e.to_string().len() < 2_000, "{e}");
            }
        }
        Err(e) => assert!(e.to_string().len() < 2_000, "{} bytes", e.to_string().len()),
    }
}

fn value() -> impl Strategy<Value = String> {
    prop_oneof![
        any::<i64>().prop_map(|v| v.to_string()),
        any::<u64>().prop_map(|v| v.to_string()),
        any::<f64>().prop_map(|v| format!("{v:e}")),
        Just("inf".to_string()),
        Just("nan".to_string()),
        Just("-0.0".to_string()),
        "\"[a-z0-9.]{0,12}\"",
        "\\[[0-9, ]{0,20}\\]",
        Just("true".to_string()),
    ]
}

fn cases() -> Cases {
    Cases {
        cases: 512,
        failure_persistence: None,
        ..Cases::default()
    }
}

proptest! {
    #![proptest_config(cases())]

    #[test]
    fn random_text_never_panics(text in "\\PC{0,400}") {
        check(&text);
    }

    #[test]
    fn random_values_for_real_keys_never_panic(
        lines in proptest::collection::vec((0..KEYS.len(), value()), 0..6)
    ) {
        let text: String = lines.iter().map(|(k, v)| format!("{} = {v}\n", KEYS[*k])).collect();
        check(&text);
    }
}
