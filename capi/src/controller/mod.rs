//! The whole control period for C, declared in `capi/include/cartpole_policy.h`:
//!
//! ```c
//! int cartpole_controller_init(cartpole_controller_t *c, int policy_kind);
//! int cartpole_controller_init_mlp64(cartpole_controller_t *c, const struct cartpole_mlp64 *w,
//!                                    const struct cartpole_rig *rig);   /* and every width */
//! int cartpole_controller_init_qmlp64(cartpole_controller_t *c, const struct cartpole_qmlp64 *w,
//!                                     const struct cartpole_rig *rig);
//! int cartpole_controller_step(cartpole_controller_t *c, int32_t cart_counts,
//!                              int32_t pole_counts, cartpole_command_t *out);
//! int cartpole_controller_step_state(cartpole_controller_t *c, const float state[4],
//!                                    cartpole_command_t *out);
//! int cartpole_controller_counters(const cartpole_controller_t *c, cartpole_counters_t *out);
//! int cartpole_controller_record_overruns(cartpole_controller_t *c, uint32_t ticks);
//! int cartpole_controller_period_us(const cartpole_controller_t *c, uint32_t *period_us);
//! int cartpole_controller_monitor(cartpole_controller_t *c, const float envelope[4],
//!                                 const struct cartpole_rig *rig);
//! ```
//!
//! A step is [`Controller::step`](firmware::controller::Controller::step), the period the
//! trainer, the simulator, the self-test and the Rust boards run, on a controller built as
//! they build theirs from a policy and its rig: the shipped policy's `RIG`, or the
//! `cartpole_rig` an exported header carries beside its weights. Its H-bridge is the
//! loopback's in-memory pins ([`firmware::loopback::Pins`]), read back into the command C
//! drives its own bridge from.
//!
//! Every call returns [`CARTPOLE_OK`] or a negative error, and a refused call writes
//! nothing: a NULL pointer ([`CARTPOLE_ERR_NULL`]), a `cartpole_controller_t` that no init
//! initialised ([`CARTPOLE_ERR_UNINITIALISED`]), an unknown policy
//! ([`CARTPOLE_ERR_POLICY_KIND`]), a step of the other input kind than the instance's first
//! ([`CARTPOLE_ERR_INPUT`]), or a rig no machine has ([`CARTPOLE_ERR_RIG`]). Pointers arrive
//! as `Option<&T>`, as in the forward passes; non-NULL ones must be valid and aligned.

use core::ffi::c_int;

use firmware::controller::{Assurance, FaultCounters, FaultFlags, Limits, Scores as _};
use firmware::loopback::{Duty, Level};
use firmware::network::int::QMlp;
use firmware::network::{Mlp, N_ACTIONS, OBS_DIM};

use crate::rig::CartpoleRig;

mod input;
mod storage;

use input::{Format, Handed};
pub use storage::{CONTROLLER_SIZE, CartpoleController};
use storage::{Float, Int, Kind, Slot, magic, slot, slot_mut};

/// The call did what it says.
pub const CARTPOLE_OK: c_int = 0;
/// A pointer argument was NULL.
pub const CARTPOLE_ERR_NULL: c_int = -1;
/// The `cartpole_controller_t` was not initialised by `cartpole_controller_init`.
pub const CARTPOLE_ERR_UNINITIALISED: c_int = -2;
/// `cartpole_controller_init` was given no known policy kind.
pub const CARTPOLE_ERR_POLICY_KIND: c_int = -3;
/// Counts handed to an instance that has read states, or the other way round.
pub const CARTPOLE_ERR_INPUT: c_int = -4;
/// A `cartpole_rig` with a field no machine has ([`CartpoleRig::to_rig`]), or one whose
/// observer the firmware refuses (its Kalman gain not finite); to
/// `cartpole_controller_monitor`, also a rig other than the instance's.
pub const CARTPOLE_ERR_RIG: c_int = -5;
/// An envelope with a bound that is NaN, infinite or negative.
pub const CARTPOLE_ERR_ENVELOPE: c_int = -6;

/// `CARTPOLE_POLICY_F32`: the shipped float policy (`firmware::policy`).
pub const CARTPOLE_POLICY_F32: c_int = 1;
/// `CARTPOLE_POLICY_INT`: the shipped integer policy (`firmware::policy_int`), integer
/// arithmetic from the observer's estimate to the decision.
pub const CARTPOLE_POLICY_INT: c_int = 2;

/// `cartpole_command_t`: what one period decided and drove.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CartpoleCommand {
    /// `-1` push left, `0` coast, `1` push right ([`Command::level`](firmware::controller::Command::level)).
    pub command: i32,
    /// The direction pin: `1` high (pushes towards +x), `0` low. Kept while coasting.
    pub direction: u32,
    /// The enable's duty, `0` (off) to [`firmware::loopback::MAX_DUTY`] (the full push).
    pub duty: u32,
    /// The period's [`FaultFlags`](firmware::controller::FaultFlags) bits; `0` when the
    /// reading was accepted.
    pub faults: u32,
    /// The float policy's Q-values `[left, right]` (NaN when the reading was rejected); zero
    /// for the integer policy.
    pub q: [f32; N_ACTIONS],
    /// The integer policy's outputs (zero when the reading was rejected); zero for the float
    /// policy.
    pub q_int: [i32; N_ACTIONS],
    /// The period's number, from 0.
    pub step: u32,
}

/// `cartpole_counters_t`: totals since `cartpole_controller_init`, saturating: the periods
/// run, then the controller's [`FaultCounters`] (`repr(C)`, flat in C, the same layout).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CartpoleCounters {
    /// Periods run.
    pub steps: u32,
    /// The controller's totals.
    pub faults: FaultCounters,
}

/// What C asks of an instance, whichever policy it runs.
trait Run {
    /// One period on `handed`; `None` when the instance reads the other kind of input.
    fn step(&mut self, handed: Handed) -> Option<CartpoleCommand>;
    fn counters(&self) -> CartpoleCounters;
    fn record_overruns(&mut self, ticks: u32);
    fn period_us(&self) -> u32;
    /// Puts the controller under the monitor of `assurance`, its observer watching for
    /// frozen encoders; refused if `rig` is not the digest of the instance's rig.
    fn monitor(&mut self, assurance: Assurance, rig: u64) -> Result<(), c_int>;
}

impl<K: Kind> Run for Slot<K> {
    fn step(&mut self, handed: Handed) -> Option<CartpoleCommand> {
        let c = &mut self.controller;
        if !c.sensor_mut().hand(handed) {
            return None;
        }
        let command = c.step();
        let (&Level(direction), &Duty(duty)) = c.actuator().pins();
        // `step` has just recorded its period: the fallback is never taken.
        let (step, q, faults) = c.last().map_or(
            (
                c.steps(),
                <K::Reading as Format>::Scores::UNSCORED,
                FaultFlags::default(),
            ),
            |r| (r.step, r.q, r.faults),
        );
        let (q, q_int) = K::Reading::scores(q);
        Some(CartpoleCommand {
            command: command.level() as i32,
            direction: direction.into(),
            duty: duty.into(),
            faults: faults.0.into(),
            q,
            q_int,
            step,
        })
    }

    fn counters(&self) -> CartpoleCounters {
        CartpoleCounters {
            steps: self.controller.steps(),
            faults: self.controller.faults(),
        }
    }

    fn monitor(&mut self, assurance: Assurance, rig: u64) -> Result<(), c_int> {
        if rig != self.rig {
            return Err(CARTPOLE_ERR_RIG);
        }
        self.controller.sensor_mut().watch();
        self.controller.set_monitor(assurance);
        Ok(())
    }

    fn record_overruns(&mut self, ticks: u32) {
        self.controller.record_overruns(ticks);
    }

    fn period_us(&self) -> u32 {
        self.period_us
    }
}

/// The instance in `c` and, mutably, of whichever kind initialised it: one pair for every
/// width of either format.
macro_rules! instances {
    ($($h:literal => $forward:ident / $qforward:ident,)*) => {
        /// The instance in `c`, whichever kind initialised it.
        fn instance(c: &CartpoleController) -> Result<&dyn Run, c_int> {
            $(
                if let Some(s) = slot::<Float<$h>>(c) {
                    return Ok(s);
                }
                if let Some(s) = slot::<Int<$h>>(c) {
                    return Ok(s);
                }
            )*
            Err(CARTPOLE_ERR_UNINITIALISED)
        }

        /// [`instance`], to run it.
        fn instance_mut(c: &mut CartpoleController) -> Result<&mut dyn Run, c_int> {
            // Which kind first, then the one borrow to return.
            let m = magic(c);
            let run: Option<&mut dyn Run> = $(
                if m == Float::<$h>::MAGIC {
                    slot_mut::<Float<$h>>(c).map(|s| s as _)
                } else if m == Int::<$h>::MAGIC {
                    slot_mut::<Int<$h>>(c).map(|s| s as _)
                } else
            )* {
                None
            };
            run.ok_or(CARTPOLE_ERR_UNINITIALISED)
        }
    };
}
firmware::for_each_width!(instances);

/// `Ok` as [`CARTPOLE_OK`], an error as its code.
fn status(done: Result<(), c_int>) -> c_int {
    done.err().unwrap_or(CARTPOLE_OK)
}

/// Runs `handed` through the instance in `c` and writes the command to `out`; on any
/// refusal writes nothing and runs nothing.
fn step(
    c: Option<&mut CartpoleController>,
    handed: Option<Handed>,
    out: Option<&mut CartpoleCommand>,
) -> c_int {
    let (Some(c), Some(handed), Some(out)) = (c, handed, out) else {
        return CARTPOLE_ERR_NULL;
    };
    status(
        instance_mut(c)
            .and_then(|r| r.step(handed).ok_or(CARTPOLE_ERR_INPUT))
            .map(|command| *out = command),
    )
}

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
            Slot::<Float<64>>::new(&firmware::policy::POLICY, &firmware::policy::RIG)
                .map(|s| s.store(c))
        }
        CARTPOLE_POLICY_INT => Slot::<Int<64>>::new(
            &firmware::policy_int::POLICY_INT,
            &firmware::policy_int::RIG,
        )
        .map(|s| s.store(c)),
        _ => return CARTPOLE_ERR_POLICY_KIND,
    };
    built.map_or(CARTPOLE_ERR_RIG, |()| CARTPOLE_OK)
}

/// Makes `c` a controller of the weights `w` of kind `K` on `rig`, as
/// [`cartpole_controller_init`] makes one of the shipped policy on its `RIG`; refuses a NULL
/// and a rig no machine has, writing nothing.
fn init_exported<K: Kind>(
    c: Option<&mut CartpoleController>,
    w: Option<K::Policy>,
    rig: Option<&CartpoleRig>,
) -> c_int {
    let (Some(c), Some(w), Some(rig)) = (c, w, rig) else {
        return CARTPOLE_ERR_NULL;
    };
    match rig.to_rig().map(|rig| Slot::<K>::new(w, &rig)) {
        Some(Ok(slot)) => {
            slot.store(c);
            CARTPOLE_OK
        }
        _ => CARTPOLE_ERR_RIG,
    }
}

/// `cartpole_controller_init_mlpH` and `cartpole_controller_init_qmlpH` for each width `H`.
macro_rules! exported_inits {
    ($($h:literal => $name:ident / $qname:ident,)*) => { $(
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
        pub extern "C" fn $name(
            c: Option<&mut CartpoleController>,
            // `'static`: the controller keeps it, for as long as C promises (the header).
            w: Option<&'static Mlp<$h>>,
            rig: Option<&CartpoleRig>,
        ) -> c_int {
            init_exported::<Float<$h>>(c, w, rig)
        }

        #[doc = concat!(
            "The integer 4-", stringify!($h), "-", stringify!($h), "-2 network's \
             counterpart of `cartpole_controller_init_mlp", stringify!($h), "`: integer \
             arithmetic from the observer's estimate to the decision."
        )]
        // SAFETY: as for `cartpole_controller_init`: one definition per C name.
        #[allow(unsafe_code)]
        #[unsafe(no_mangle)]
        pub extern "C" fn $qname(
            c: Option<&mut CartpoleController>,
            w: Option<&'static QMlp<$h>>,
            rig: Option<&CartpoleRig>,
        ) -> c_int {
            init_exported::<Int<$h>>(c, w, rig)
        }
    )* };
}
/// The widths `exported_inits!` is given, for the test that they are every supported one.
#[cfg(test)]
const INIT_WIDTHS: [usize; 3] = [16, 64, 128];
exported_inits! {
    16 => cartpole_controller_init_mlp16 / cartpole_controller_init_qmlp16,
    64 => cartpole_controller_init_mlp64 / cartpole_controller_init_qmlp64,
    128 => cartpole_controller_init_mlp128 / cartpole_controller_init_qmlp128,
}

/// One control period on this period's encoder counts, read through the rig's observer;
/// the command it decided and drove in `out`.
// SAFETY: as for `cartpole_controller_init`: one definition per C name.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn cartpole_controller_step(
    c: Option<&mut CartpoleController>,
    cart_counts: i32,
    pole_counts: i32,
    out: Option<&mut CartpoleCommand>,
) -> c_int {
    step(c, Some(Handed::Counts(cart_counts, pole_counts)), out)
}

/// One control period on a measured state `[x, x_dot, theta, theta_dot]` (SI units), for
/// a board that reads the state rather than encoders; a NaN, infinite or out-of-range
/// channel is the controller's to reject (it coasts and flags it).
// SAFETY: as for `cartpole_controller_init`: one definition per C name.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn cartpole_controller_step_state(
    c: Option<&mut CartpoleController>,
    state: Option<&[f32; OBS_DIM]>,
    out: Option<&mut CartpoleCommand>,
) -> c_int {
    step(c, state.map(|s| Handed::State(*s)), out)
}

/// The instance's totals in `out`.
// SAFETY: as for `cartpole_controller_init`: one definition per C name.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn cartpole_controller_counters(
    c: Option<&CartpoleController>,
    out: Option<&mut CartpoleCounters>,
) -> c_int {
    let (Some(c), Some(out)) = (c, out) else {
        return CARTPOLE_ERR_NULL;
    };
    status(instance(c).map(|r| *out = r.counters()))
}

/// Counts `ticks` timer ticks that arrived while the last step still ran: the loop that
/// paces the controller knows them, the controller does not.
// SAFETY: as for `cartpole_controller_init`: one definition per C name.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn cartpole_controller_record_overruns(
    c: Option<&mut CartpoleController>,
    ticks: u32,
) -> c_int {
    let Some(c) = c else {
        return CARTPOLE_ERR_NULL;
    };
    status(instance_mut(c).map(|r| r.record_overruns(ticks)))
}

/// The control period of the rig the policy was trained for, in microseconds (rounded), in
/// `period_us`: the period to call a step at.
// SAFETY: as for `cartpole_controller_init`: one definition per C name.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn cartpole_controller_period_us(
    c: Option<&CartpoleController>,
    period_us: Option<&mut u32>,
) -> c_int {
    let (Some(c), Some(out)) = (c, period_us) else {
        return CARTPOLE_ERR_NULL;
    };
    status(instance(c).map(|r| *out = r.period_us()))
}

/// Puts `c`'s controller under the runtime monitor from its next period
/// (`firmware::controller::monitor`): the policy drives inside `envelope` (per-channel
/// bounds on `|reading|`; NULL: the shipped policy's, `firmware::envelope`), bang-bang LQR
/// designed for `rig` outside it and after runs of faulty readings, a latched stop beyond
/// what LQR can recover; the observer watches for frozen encoders. `rig` must be the machine
/// `c` was initialised for (NULL: the shipped policies'). Solves the LQR gain: call it at
/// start-up. Refused, writing nothing: an envelope bound NaN, infinite or negative
/// ([`CARTPOLE_ERR_ENVELOPE`]), a rig no machine has or not the instance's
/// ([`CARTPOLE_ERR_RIG`]).
// SAFETY: as for `cartpole_controller_init`: one definition per C name.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn cartpole_controller_monitor(
    c: Option<&mut CartpoleController>,
    envelope: Option<&[f32; OBS_DIM]>,
    rig: Option<&CartpoleRig>,
) -> c_int {
    let Some(c) = c else {
        return CARTPOLE_ERR_NULL;
    };
    let envelope = match envelope.map(|e| Limits::new(*e)) {
        None => firmware::envelope::ENVELOPE,
        Some(Ok(e)) => e,
        Some(Err(_)) => return CARTPOLE_ERR_ENVELOPE,
    };
    let rig = match rig.map(CartpoleRig::to_rig) {
        None => firmware::policy::RIG,
        Some(Some(rig)) => rig,
        Some(None) => return CARTPOLE_ERR_RIG,
    };
    let Ok(assurance) = Assurance::for_rig(envelope, &rig) else {
        return CARTPOLE_ERR_RIG;
    };
    let digest = firmware::link::digest::rig(&rig);
    status(instance_mut(c).and_then(|r| r.monitor(assurance, digest)))
}

#[cfg(test)]
mod tests;
