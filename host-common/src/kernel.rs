//! Which build of the host's vectorised code runs: the trainer's batched kernels and the
//! wide forward pass are each compiled for these instruction sets and chosen at run time.
//!
//! A kernel is [`supported`](Kernel::supported) only if the CPU has every feature any of
//! its builds enables, so that each `#[target_feature]` function called after this check is
//! called on a CPU that runs it: AVX2 and FMA for [`Kernel::Avx2`]; AVX-512F, AVX-512VL,
//! AVX2 and FMA for [`Kernel::Avx512`] (the trainer's AVX-512 build enables all four).
//! Every kernel computes the same bits; they differ only in speed.

use serde::{Deserialize, Serialize};

/// One build of the host's vector code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Kernel {
    /// The target's baseline: NEON on aarch64 (whose `fmla` is a fused multiply-add), SSE2
    /// on x86-64 (with fused multiply-adds in software).
    Portable,
    /// AVX2 with fused multiply-add.
    Avx2,
    /// AVX-512F and AVX-512VL with fused multiply-add.
    Avx512,
}

impl Kernel {
    /// Every kernel, portable first.
    pub const ALL: [Kernel; 3] = [Kernel::Portable, Kernel::Avx2, Kernel::Avx512];

    /// The fastest kernel this CPU runs.
    pub fn detect() -> Kernel {
        [Kernel::Avx512, Kernel::Avx2]
            .into_iter()
            .find(|k| k.supported())
            .unwrap_or(Kernel::Portable)
    }

    /// Whether this CPU has every feature the kernel's builds enable.
    pub fn supported(self) -> bool {
        match self {
            Kernel::Portable => true,
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2 => {
                std::arch::is_x86_feature_detected!("avx2")
                    && std::arch::is_x86_feature_detected!("fma")
            }
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx512 => {
                Kernel::Avx2.supported()
                    && std::arch::is_x86_feature_detected!("avx512f")
                    && std::arch::is_x86_feature_detected!("avx512vl")
            }
            #[cfg(not(target_arch = "x86_64"))]
            Kernel::Avx2 | Kernel::Avx512 => false,
        }
    }

    /// The kernels this CPU runs, portable first.
    pub fn available() -> Vec<Kernel> {
        Kernel::ALL.into_iter().filter(|k| k.supported()).collect()
    }
}

/// What the kernel says against what the operating system says the CPU has: Linux's flags
/// in `/proc/cpuinfo`, read independently of the instruction the kernel uses.
#[cfg(all(test, target_arch = "x86_64", target_os = "linux"))]
mod tests {
    use super::*;

    #[test]
    fn support_follows_the_cpus_own_flags() {
        let info = std::fs::read_to_string("/proc/cpuinfo").expect("Linux has /proc/cpuinfo");
        let flags: Vec<&str> = info
            .lines()
            .find(|l| l.starts_with("flags"))
            .expect("a flags line")
            .split_whitespace()
            .collect();
        let has = |f: &str| flags.contains(&f);
        let avx2 = has("avx2") && has("fma");
        let avx512 = avx2 && has("avx512f") && has("avx512vl");
        assert_eq!(Kernel::Avx2.supported(), avx2, "{flags:?}");
        assert_eq!(Kernel::Avx512.supported(), avx512, "{flags:?}");
        let best = if avx512 {
            Kernel::Avx512
        } else if avx2 {
            Kernel::Avx2
        } else {
            Kernel::Portable
        };
        assert_eq!(Kernel::detect(), best);
    }
}
