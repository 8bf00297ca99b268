//! A policy file exported and loaded from Rust with the functions `policy-export export`
//! runs: `shipped/policy.safetensors` read by `weights::checkpoint::load`, rendered by
//! `policy_export::export::render` as a Rust module, a C header and an int8 Rust module,
//! written with the weights written again as safetensors into a temporary directory, and
//! that safetensors file loaded back. The loaded network's forward pass must equal the
//! shipped crate's `POLICY.forward` bit for bit on the probe states every export is checked
//! on, and the int8 module must be `shipped/src/policy_int.rs` byte for byte (the manifest
//! makes that file with the same export).
//!
//! ```sh
//! cargo run --release -p cartpole-examples --example export_and_load
//! ```
//!
//! Exits non-zero if any of this fails.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{Result, bail};
use policy_export::export::{Language, default_name, render};
use weights::checkpoint::{self, Import};
use weights::files::write_atomic;
use weights::quant::Granularity;

/// Renders `import` read from `src` as `lang` source, int8 with `quant`, into `dir/file`;
/// returns the text.
fn export(
    import: &Import,
    src: &Path,
    (lang, quant): (Language, Option<Granularity>),
    dir: &Path,
    file: &str,
) -> Result<String> {
    let provenance = policy_export::run::source_provenance(src, import)?;
    let name = default_name(lang, quant.is_some());
    let source = format!("policy {}", src.display());
    let (machine, _) = policy_export::export::machine(import, &source, None)?;
    let r = render(import, &provenance, &machine, lang, quant, name)?;
    write_atomic(&dir.join(file), r.text.as_bytes())?;
    println!("wrote {file}: {name}, {} bytes of source", r.text.len());
    Ok(r.text)
}

fn run(dir: &Path) -> Result<()> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let src = root.join("shipped/policy.safetensors");
    let import = checkpoint::load(&src, None)?;
    println!("read policy.safetensors: {}", import.describe());
    export(&import, &src, (Language::Rust, None), dir, "policy.rs")?;
    export(&import, &src, (Language::C, None), dir, "policy.h")?;
    let int8 = (Language::Rust, Some(Granularity::default()));
    let int_text = export(&import, &src, int8, dir, "policy_int.rs")?;
    if int_text != std::fs::read_to_string(root.join("shipped/src/policy_int.rs"))? {
        bail!("the int8 module differs from shipped/src/policy_int.rs");
    }
    println!("policy_int.rs is shipped/src/policy_int.rs byte for byte");

    let written = dir.join("policy.safetensors");
    write_atomic(
        &written,
        &checkpoint::to_safetensors(&import.weights, &import.metadata)?,
    )?;
    let loaded = checkpoint::load(&written, None)?;
    let net = loaded.weights.to_mlp::<64, 2>()?;
    let mut probes = 0;
    for obs in weights::probe_states() {
        let (got, want) = (net.forward(&obs), shipped::policy::POLICY.forward(&obs));
        if got.map(f32::to_bits) != want.map(f32::to_bits) {
            bail!("at {obs:?} the loaded network gives {got:?}, the shipped one {want:?}");
        }
        probes += 1;
    }
    println!("loaded policy.safetensors back: its forward pass is POLICY's bit for bit");
    println!("on all {probes} probe states");
    Ok(())
}

fn main() -> ExitCode {
    let dir: PathBuf = std::env::temp_dir().join(format!("cartpole-export-{}", std::process::id()));
    let result = std::fs::create_dir(&dir)
        .map_err(anyhow::Error::from)
        .and_then(|()| run(&dir));
    // Best effort: a temporary directory left behind does no harm.
    let _ = std::fs::remove_dir_all(&dir);
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("export and load failed: {e:#}");
            ExitCode::FAILURE
        }
    }
}
