//! The inits: a `cartpole_controller_t` made a controller of the shipped policy, or of a
//! policy of one's own of every shape of [`firmware::for_each_shape!`] on its rig (and, for
//! more than two outputs, its duty levels), built as every Rust board builds one
//! ([`Slot::new`]).

use core::ffi::c_int;

use firmware::controller::{Greedy, Levels};
use firmware::loopback::MAX_DUTY;
use firmware::network::Mlp;
use firmware::network::int::QMlp;

use super::storage::{CartpoleController, Float, Int, Kind, Slot};
use super::{
    CARTPOLE_ERR_LEVELS, CARTPOLE_ERR_NULL, CARTPOLE_ERR_POLICY_KIND, CARTPOLE_ERR_RIG,
    CARTPOLE_OK, CARTPOLE_POLICY_F32, CARTPOLE_POLICY_INT,
};
use crate::rig::CartpoleRig;

/// Makes `c` a controller of the shipped policy `policy_kind` ([`CARTPOLE_POLICY_F32`] or
/// [`CARTPOLE_POLICY_INT`]) on its `RIG`, which has run no period: the observer starts
/// from the first counts at rest. Solves the observer's gain: call it at start-up, not in
/// the control interrupt. Initialising an instance again starts it afresh.
// SAFETY: exporting an unmangled symbol is `unsafe` because two such symbols with one name
// would clash at link time; this crate defines each C name once.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn cartpole_controller_init(
    c: Option<&mut CartpoleController>,
    policy_kind: c_int,
) -> c_int {
    let Some(c) = c else {
        return CARTPOLE_ERR_NULL;
    };
    // The shipped rigs pass the firmware's checks as it is compiled; their gain is
    // solved here, and a refusal is the rig's.
    let built = match policy_kind {
        CARTPOLE_POLICY_F32 => {
            Slot::<Float<64, 2>>::new(bang_bang(&shipped::policy::POLICY), &shipped::policy::RIG)
                .map(|s| s.store(c))
        }
        CARTPOLE_POLICY_INT => Slot::<Int<64, 2>>::new(
            bang_bang(&shipped::policy_int::POLICY_INT),
            &shipped::policy_int::RIG,
        )
        .map(|s| s.store(c)),
        _ => return CARTPOLE_ERR_POLICY_KIND,
    };
    built.map_or(CARTPOLE_ERR_RIG, |()| CARTPOLE_OK)
}

/// The paper's network on its two levels, full push left and right, as the firmware's
/// `Policy` for `&Mlp<H>` runs it.
pub(crate) fn bang_bang<N>(net: N) -> Greedy<N, 2> {
    Greedy {
        net,
        levels: Levels::BANG_BANG,
    }
}

/// Makes `c` a controller of `policy` of kind `K` on `rig`, as [`cartpole_controller_init`]
/// makes one of the shipped policy on its `RIG`; refuses a NULL and a rig no machine has,
/// writing nothing.
fn init_exported<K: Kind>(
    c: Option<&mut CartpoleController>,
    policy: Option<K::Policy>,
    rig: Option<&CartpoleRig>,
) -> c_int {
    let (Some(c), Some(policy), Some(rig)) = (c, policy, rig) else {
        return CARTPOLE_ERR_NULL;
    };
    match rig.to_rig().map(|rig| Slot::<K>::new(policy, &rig)) {
        Some(Ok(slot)) => {
            slot.store(c);
            CARTPOLE_OK
        }
        _ => CARTPOLE_ERR_RIG,
    }
}

/// The `n` duty levels C hands at `levels`, in thousandths of the full push, as the levels
/// of a network of `A` outputs: `None` for NULL, `Some(Err(..))` for levels the firmware
/// refuses ([`Levels::new`]: not `A` of them, beyond the full push, not strictly
/// increasing). Reads nothing unless `n` is `A`.
fn levels<const A: usize>(levels: *const i16, n: u32) -> Option<Result<Levels<A>, c_int>> {
    if levels.is_null() {
        return None;
    }
    if usize::try_from(n) != Ok(A) {
        return Some(Err(CARTPOLE_ERR_LEVELS));
    }
    // SAFETY: non-NULL, and C promises (the header) that `levels` points at `n_levels`
    // readable int16_t, which are `A` of them, so at an `[i16; A]` (alignment 2, as int16_t).
    #[allow(unsafe_code)]
    let thousandths = unsafe { *levels.cast::<[i16; A]>() };
    let full = f32::from(MAX_DUTY);
    Some(Levels::new(thousandths.map(|t| f32::from(t) / full)).map_err(|_| CARTPOLE_ERR_LEVELS))
}

/// [`init_exported`] of the network `w` on the `n` levels at `levels`: refused as
/// [`levels`] refuses, writing nothing.
fn init_levelled<K, N, const A: usize>(
    c: Option<&mut CartpoleController>,
    w: Option<N>,
    thousandths: *const i16,
    n: u32,
    rig: Option<&CartpoleRig>,
) -> c_int
where
    K: Kind<Policy = Greedy<N, A>>,
{
    match levels::<A>(thousandths, n) {
        Some(Err(code)) if c.is_some() && w.is_some() && rig.is_some() => code,
        Some(Ok(levels)) => init_exported::<K>(c, w.map(|net| Greedy { net, levels }), rig),
        _ => CARTPOLE_ERR_NULL,
    }
}

/// `cartpole_controller_init_mlpS` and `cartpole_controller_init_qmlpS` for one shape of
/// [`firmware::for_each_shape!`]: a two-output network's on the full pushes, one of more
/// outputs on the levels C hands with it.
macro_rules! exported_init {
    ($h:literal x 2 => $init:ident / $qinit:ident) => {
        #[doc = concat!(
            "Makes `c` a controller of the float 4-", stringify!($h), "-", stringify!($h),
            "-2 network `w` on `rig` (an exported header's `NAME` and `NAME_rig`). The \
             controller keeps `w`, not a copy: C must keep the weights for as long as the \
             controller, or any copy of it, runs (`static const` ones, as exported, always \
             are). Refuses a rig outside [`CartpoleRig::to_rig`]'s ranges, or one whose \
             observer the firmware refuses ([`CARTPOLE_ERR_RIG`]), writing nothing."
        )]
        // SAFETY: as for `cartpole_controller_init`: one definition per C name.
        #[allow(unsafe_code)]
        #[unsafe(no_mangle)]
        pub extern "C" fn $init(
            c: Option<&mut CartpoleController>,
            // `'static`: the controller keeps it, for as long as C promises (the header).
            w: Option<&'static Mlp<$h>>,
            rig: Option<&CartpoleRig>,
        ) -> c_int {
            init_exported::<Float<$h, 2>>(c, w.map(bang_bang), rig)
        }

        #[doc = concat!(
            "The integer 4-", stringify!($h), "-", stringify!($h), "-2 network's \
             counterpart of `cartpole_controller_init_mlp", stringify!($h), "`: integer \
             arithmetic from the observer's estimate to the decision."
        )]
        // SAFETY: as for `cartpole_controller_init`: one definition per C name.
        #[allow(unsafe_code)]
        #[unsafe(no_mangle)]
        pub extern "C" fn $qinit(
            c: Option<&mut CartpoleController>,
            w: Option<&'static QMlp<$h>>,
            rig: Option<&CartpoleRig>,
        ) -> c_int {
            init_exported::<Int<$h, 2>>(c, w.map(bang_bang), rig)
        }
    };
    ($h:literal x $a:literal => $init:ident / $qinit:ident) => {
        #[doc = concat!(
            "Makes `c` a controller of the float 4-", stringify!($h), "-", stringify!($h),
            "-", stringify!($a), " network `w` whose output `i` drives `levels[i]` \
             thousandths of the full push, on `rig` (an exported header's `NAME`, \
             `NAME_levels` and `NAME_rig`). `levels` must point at `n_levels` int16_t, read \
             during the call only; the controller keeps `w`, as the two-output inits do. \
             Refuses levels the firmware refuses ([`CARTPOLE_ERR_LEVELS`]: not ",
            stringify!($a), " of them, beyond `[-1000, 1000]`, not strictly increasing) and \
             a rig the two-output inits refuse ([`CARTPOLE_ERR_RIG`]), writing nothing."
        )]
        // SAFETY: as for `cartpole_controller_init`: one definition per C name.
        #[allow(unsafe_code)]
        #[unsafe(no_mangle)]
        pub extern "C" fn $init(
            c: Option<&mut CartpoleController>,
            w: Option<&'static Mlp<$h, $a>>,
            levels: *const i16,
            n_levels: u32,
            rig: Option<&CartpoleRig>,
        ) -> c_int {
            init_levelled::<Float<$h, $a>, _, $a>(c, w, levels, n_levels, rig)
        }

        #[doc = concat!(
            "The integer 4-", stringify!($h), "-", stringify!($h), "-", stringify!($a),
            " network's counterpart of `cartpole_controller_init_mlp", stringify!($h), "x",
            stringify!($a), "`: integer arithmetic from the observer's estimate to the \
             decision."
        )]
        // SAFETY: as for `cartpole_controller_init`: one definition per C name.
        #[allow(unsafe_code)]
        #[unsafe(no_mangle)]
        pub extern "C" fn $qinit(
            c: Option<&mut CartpoleController>,
            w: Option<&'static QMlp<$h, $a>>,
            levels: *const i16,
            n_levels: u32,
            rig: Option<&CartpoleRig>,
        ) -> c_int {
            init_levelled::<Int<$h, $a>, _, $a>(c, w, levels, n_levels, rig)
        }
    };
}

/// Every shape's inits. The shape's tokens pass on as they are (`tt`): a `literal` fragment
/// would no longer match `exported_init!`'s `2`.
macro_rules! exported_inits {
    ($($h:tt x $a:tt => $f:ident / $qf:ident / $init:ident / $qinit:ident,)*) => {
        $(exported_init!($h x $a => $init / $qinit);)*
    };
}
firmware::for_each_shape!(exported_inits);
