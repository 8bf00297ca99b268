//! Which build of the host's vectorised code runs: the trainer's batched kernels and the
//! simulator's wide forward pass are each compiled for these three instruction sets and
//! chosen at run time.
//!
//! A kernel is [`supported`](Kernel::supported) only if the CPU has every feature any of
//! its builds enables, so that each `#[target_feature]` function called after this check is
//! called on a CPU that runs it: AVX2 and FMA for [`Kernel::Avx2`]; AVX-512F, AVX-512VL,
//! AVX2 and FMA for [`Kernel::Avx512`] (the trainer's AVX-512 build enables all four).

use serde::{Deserialize, Serialize};

/// One build of the host's vector code.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum Kernel {
    /// Baseline x86-64 (SSE2), or any other architecture: no fused multiply-add.
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detection_is_consistent() {
        let k = Kernel::detect();
        assert!(k.supported());
        assert!(Kernel::Portable.supported());
        // A CPU with AVX-512 has AVX2 too, so the faster kernel implies the slower.
        if Kernel::Avx512.supported() {
            assert!(Kernel::Avx2.supported() && k == Kernel::Avx512);
        }
        assert_eq!(Kernel::available()[0], Kernel::Portable);
        assert!(Kernel::available().contains(&k));
    }
}
