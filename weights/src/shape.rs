//! Running code for a network whose shape is known only at run time: the one place that
//! turns a hidden width and an output count into a monomorphised instance, for every shape
//! of [`firmware::for_each_shape!`].

use firmware::network::SUPPORTED_SHAPES;

use crate::{Error, Result};

/// Work to do with a network of hidden width `H` and `A` outputs, chosen at run time by
/// [`by_shape`].
pub trait ForShape {
    /// What the work gives.
    type Output;
    /// Does it for width `H` and `A` outputs.
    fn run<const H: usize, const A: usize>(self) -> Self::Output;
}

/// Runs `work` for hidden width `width` and `outputs` outputs, or says which shapes the
/// tools are built for.
pub fn by_shape<W: ForShape>(width: usize, outputs: usize, work: W) -> Result<W::Output> {
    macro_rules! dispatch {
        ($($h:literal x $a:literal => $($c:ident)/+,)*) => {
            match (width, outputs) {
                $(($h, $a) => Ok(work.run::<$h, $a>()),)*
                _ => Err(unsupported(width, outputs)),
            }
        };
    }
    firmware::for_each_shape!(dispatch)
}

/// The refusal of a shape the tools are not built for.
pub fn unsupported(width: usize, outputs: usize) -> Error {
    let list: Vec<String> = SUPPORTED_SHAPES
        .iter()
        .map(|(h, a)| format!("{h} x {a}"))
        .collect();
    Error::Input(format!(
        "a network of hidden width {width} with {outputs} outputs is not one the tools are \
         built for (width x outputs: {})",
        list.join(", ")
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Params;
    impl ForShape for Params {
        type Output = usize;
        fn run<const H: usize, const A: usize>(self) -> usize {
            firmware::network::Mlp::<H, A>::PARAMS
        }
    }

    #[test]
    fn every_supported_shape_runs_its_own_instance_and_others_are_refused() {
        for &(h, a) in SUPPORTED_SHAPES {
            assert_eq!(
                by_shape(h, a, Params).unwrap(),
                4 * h + h + h * h + h + a * h + a
            );
        }
        let e = by_shape(48, 2, Params).unwrap_err();
        assert!(
            e.to_string().contains("hidden width 48 with 2 outputs"),
            "{e}"
        );
        assert!(e.to_string().contains("64 x 5"), "{e}");
        assert!(by_shape(16, 5, Params).is_err());
    }
}
