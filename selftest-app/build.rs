//! Links the microcontroller binary: its runtime's `link.x` (cortex-m-rt's or riscv-rt's),
//! the memory map of the machine it runs on and, with the `defmt` feature, `defmt.x`. Host
//! builds need none of it. On ARMv8-M it also sets `selftest_m33`, for the machine's clock.
//!
//! The default target's map (thumbv7em, which shares it with thumbv6m) is `memory.x` at the
//! repository root, and nothing here names it: cortex-m-rt's `link.x` says `INCLUDE memory.x`,
//! the linker looks for a script in its working directory before the search path, and cargo
//! runs rustc, and so the linker, from the workspace root. For the same reason no map of
//! another target may go through that `INCLUDE`, not even one copied into `OUT_DIR`: the root
//! file would win for every target. So the other machines give their map from `memory/` as a
//! `-T` argument of its own, by absolute path and ahead of a runtime script that includes no
//! `memory.x`:
//!
//! - RISC-V (`virt.x`, QEMU `virt`): riscv-rt's `link.x`, which includes `memory.x` only with
//!   the crate's `memory` feature, left off in Cargo.toml.
//! - ARMv8-M Mainline (`an505.x`, mps2-an505): cortex-m-rt's `link.x` always includes it, so
//!   this build links `memory/cortex-m-rt-link.x` instead, a copy without that line.

use std::path::Path;

fn main() {
    let dir = std::env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets CARGO_MANIFEST_DIR");
    let memory = Path::new(&dir).join("memory");
    // By absolute path, as the maps are linked: a build directory shared with a checkout
    // elsewhere (CI's clone) finds the paths it recorded gone and runs this again, rather
    // than linking the other checkout's maps.
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed={}", memory.display());
    println!(
        "cargo:rerun-if-changed={}",
        Path::new(&dir).join("../memory.x").display()
    );
    println!("cargo::rustc-check-cfg=cfg(selftest_m33)");
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    let target = std::env::var("TARGET").unwrap_or_default();
    let scripts = if target.starts_with("thumbv8m.main") {
        println!("cargo::rustc-cfg=selftest_m33");
        vec![memory.join("an505.x"), memory.join("cortex-m-rt-link.x")]
    } else if target.starts_with("riscv32") {
        vec![memory.join("virt.x"), "link.x".into()]
    } else {
        vec!["link.x".into()]
    };
    for script in scripts {
        println!("cargo:rustc-link-arg-bins=-T{}", script.display());
    }
    if std::env::var_os("CARGO_FEATURE_DEFMT").is_some() {
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
}
