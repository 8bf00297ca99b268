//! Links the microcontroller binary: a memory map from `memory/` (`an505.x` for ARMv8-M
//! Mainline, run on mps2-an505; `virt.x` for RISC-V, QEMU's `virt`; `microbit.x` otherwise)
//! as the `memory.x` that the runtime's `link.x` (cortex-m-rt's or riscv-rt's) includes, and
//! with the `defmt` feature `defmt.x`. Host builds need none of it. On ARMv8-M
//! it also sets `selftest_m33`, for the machine's clock.
//!
//! No file named `memory.x` may sit in the workspace root: the linker looks in its working
//! directory before the search path, and would take it for every target.

use std::path::PathBuf;

fn main() {
    println!("cargo:rerun-if-changed=memory");
    println!("cargo::rustc-check-cfg=cfg(selftest_m33)");
    println!("cargo:rerun-if-changed=build.rs");
    if std::env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    let out = PathBuf::from(std::env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let target = std::env::var("TARGET").unwrap_or_default();
    let m33 = target.starts_with("thumbv8m.main");
    let map = if m33 {
        "memory/an505.x"
    } else if target.starts_with("riscv32") {
        "memory/virt.x"
    } else {
        "memory/microbit.x"
    };
    std::fs::copy(map, out.join("memory.x")).expect("copying the memory map");
    if m33 {
        println!("cargo::rustc-cfg=selftest_m33");
    }
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    if std::env::var_os("CARGO_FEATURE_DEFMT").is_some() {
        println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    }
}
