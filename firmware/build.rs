//! `cartpole_dsp` on the targets whose every core has the DSP extension (ARMv7E-M: the
//! Cortex-M4 and M7, with or without FPU), where `network::int` runs its `smlad` kernels.
//! Rust's stable `cfg` does not show the `dsp` target feature, and on ARMv8-M Mainline (the
//! Cortex-M33) the extension is optional, so those cores take the ARMv6-M kernel instead.
fn main() {
    println!("cargo::rustc-check-cfg=cfg(cartpole_dsp)");
    println!("cargo::rerun-if-changed=build.rs");
    let target = std::env::var("TARGET").unwrap_or_default();
    if target.starts_with("thumbv7em-") {
        println!("cargo::rustc-cfg=cartpole_dsp");
    }
}
