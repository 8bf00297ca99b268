//! The exporter's one path from a network to source: the command (`policy-export export`)
//! and the Python package's `export` both render through [`render`], so a file exported
//! either way is the same bytes.

use std::path::Path;

use anyhow::Result;
use twin::Machine;
use twin::rigfile::OtherRig;
use weights::checkpoint::Import;
use weights::quant::{self, Granularity};
use weights::source;

/// The language of the generated source.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Language {
    /// A Rust module for any crate that depends on `firmware`.
    Rust,
    /// A C header for the C API.
    C,
}

/// The static's name when none is given, by language and whether it is quantised.
pub fn default_name(lang: Language, int: bool) -> &'static str {
    match (lang, int) {
        (Language::Rust, false) => source::DEFAULT_RUST_NAME,
        (Language::C, false) => source::DEFAULT_C_NAME,
        (Language::Rust, true) => "POLICY_INT",
        (Language::C, true) => "cartpole_policy_int",
    }
}

/// Refuses a name the language cannot take (or the C API already uses).
pub fn check_name(lang: Language, name: &str) -> weights::Result<()> {
    match lang {
        Language::Rust => source::check_rust_name(name),
        Language::C => source::check_c_name(name),
    }
}

/// What was rendered, for the caller's report.
pub struct Rendered {
    /// The source text.
    pub text: String,
    /// Flash bytes and the quantiser's description, when int8.
    pub int8: Option<(usize, String)>,
}

/// The machine to export the network of `import` (named `source` in refusals) for: the rig
/// file at `rig` or, without one, the rig the policy file records, or Gymnasium's machine;
/// with [`OtherRig`] when the two differ, for the caller to warn in its own words.
pub fn machine(
    import: &Import,
    source: &str,
    rig: Option<&Path>,
) -> Result<(Machine, Option<OtherRig>)> {
    let given = rig.map(twin::rigfile::load).transpose()?;
    Ok(twin::rigfile::choose(
        given,
        twin::rigfile::recorded(&import.metadata, source)?,
    ))
}

/// The network of `import` as `lang` source under `name`,
/// int8-quantised with `quant`, with `provenance` in its header, for `machine` ([`machine`]).
pub fn render(
    import: &Import,
    provenance: &[String],
    machine: &Machine,
    lang: Language,
    quant: Option<Granularity>,
    name: &str,
) -> Result<Rendered> {
    let r = &machine.rig;
    let Some(g) = quant else {
        let text = match lang {
            Language::Rust => source::rust_module(&import.weights, name, provenance, r)?,
            Language::C => source::c_header(&import.weights, name, provenance, r)?,
        };
        return Ok(Rendered { text, int8: None });
    };
    let q = twin::calibrate::quantise_policy(&import.weights, g, machine)?;
    let text = match lang {
        Language::Rust => quant::rust_module(&q, name, provenance, r)?,
        Language::C => quant::c_header(&q, name, provenance, r)?,
    };
    Ok(Rendered {
        text,
        int8: Some((q.flash_bytes(), q.describe())),
    })
}
