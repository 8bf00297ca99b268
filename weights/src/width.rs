//! Running code for a network whose hidden width is known only at run time: the one place
//! that turns a width into a monomorphised instance, for every width of
//! [`firmware::for_each_width!`].

use firmware::network::SUPPORTED_WIDTHS;

use crate::{Error, Result};

/// Work to do with a network of width `H`, chosen at run time by [`by_width`].
pub trait ForWidth {
    /// What the work gives.
    type Output;
    /// Does it for width `H`.
    fn run<const H: usize>(self) -> Self::Output;
}

/// Runs `work` for hidden width `width`, or says which widths the tools are built for.
pub fn by_width<W: ForWidth>(width: usize, work: W) -> Result<W::Output> {
    macro_rules! dispatch {
        ($($h:literal => $c:ident / $qc:ident,)*) => {
            match width {
                $($h => Ok(work.run::<$h>()),)*
                other => Err(Error::Input(format!(
                    "hidden width {other} is not one of {SUPPORTED_WIDTHS:?}"
                ))),
            }
        };
    }
    firmware::for_each_width!(dispatch)
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Params;
    impl ForWidth for Params {
        type Output = usize;
        fn run<const H: usize>(self) -> usize {
            firmware::network::Mlp::<H>::PARAMS
        }
    }

    #[test]
    fn every_supported_width_runs_its_own_instance_and_others_are_refused() {
        for &h in SUPPORTED_WIDTHS {
            assert_eq!(
                by_width(h, Params).unwrap(),
                4 * h + h + h * h + h + 2 * h + 2
            );
        }
        let e = by_width(48, Params).unwrap_err();
        assert!(
            e.to_string()
                .contains("hidden width 48 is not one of [16, 32"),
            "{e}"
        );
    }
}
