//! The whole control period for C, declared in `capi/include/cartpole_policy.h`:
//!
//! ```c
//! int cartpole_controller_init(cartpole_controller_t *c, int policy_kind);
//! int cartpole_controller_init_mlp64(cartpole_controller_t *c, const struct cartpole_mlp64 *w,
//!                                    const struct cartpole_rig *rig);   /* and every width */
//! int cartpole_controller_init_qmlp64(cartpole_controller_t *c, const struct cartpole_qmlp64 *w,
//!                                     const struct cartpole_rig *rig);
//! int cartpole_controller_init_mlp64x7(cartpole_controller_t *c,            /* and 64x3, 64x5, */
//!                                      const struct cartpole_mlp64x7 *w,    /* 64x9; qmlp too */
//!                                      const int16_t *levels, uint32_t n_levels,
//!                                      const struct cartpole_rig *rig);
//! int cartpole_controller_step(cartpole_controller_t *c, int32_t cart_counts,
//!                              int32_t pole_counts, cartpole_command_t *out);
//! int cartpole_controller_step_state(cartpole_controller_t *c, const float state[4],
//!                                    cartpole_command_t *out);
//! int cartpole_controller_counters(const cartpole_controller_t *c, cartpole_counters_t *out);
//! int cartpole_controller_record_overruns(cartpole_controller_t *c, uint32_t ticks);
//! int cartpole_controller_period_us(const cartpole_controller_t *c, uint32_t *period_us);
//! int cartpole_controller_monitor(cartpole_controller_t *c, const float envelope[4],
//!                                 const struct cartpole_rig *rig);
//! int cartpole_controller_refine(cartpole_controller_t *c, int on);
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
//! ([`CARTPOLE_ERR_INPUT`]), a rig no machine has ([`CARTPOLE_ERR_RIG`]), or duty levels
//! the firmware refuses ([`CARTPOLE_ERR_LEVELS`]). Pointers arrive
//! as `Option<&T>`, as in the forward passes; non-NULL ones must be valid and aligned.

use core::ffi::c_int;

use firmware::controller::{
    Assurance, Command, FaultCounters, FaultFlags, Limits, RefineRefused, Scores,
};
use firmware::loopback::{Duty, Level};
use firmware::network::{N_ACTIONS, OBS_DIM};
use firmware::rig::Rig;
use firmware::startup::{Sequencer, Startup};

use crate::rig::CartpoleRig;

mod init;
mod input;
mod startup;
mod storage;

pub use init::*;
use input::{CScores as _, Handed};
pub use startup::*;
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
/// An envelope with a bound that is NaN, infinite or negative; the runtime monitor and the
/// refinement together (`cartpole_controller_monitor` on a refined instance, or
/// `cartpole_controller_refine` on a monitored one): its envelope is measured for the
/// policy's plain levels.
pub const CARTPOLE_ERR_ENVELOPE: c_int = -6;
/// Duty levels the firmware refuses ([`firmware::controller::check_levels`]): not one per
/// output, beyond `[-1000, 1000]` thousandths, or not strictly increasing; refinement asked
/// of a policy of two outputs, which has no level between its ends.
pub const CARTPOLE_ERR_LEVELS: c_int = -7;
/// `cartpole_controller_phase` on an instance without a start-up.
pub const CARTPOLE_ERR_NO_STARTUP: c_int = -8;
/// `cartpole_controller_startup` flags other than `CARTPOLE_STARTUP_*`, or
/// `cartpole_controller_refine` asked for other than 0 or 1.
pub const CARTPOLE_ERR_FLAGS: c_int = -9;

/// `CARTPOLE_POLICY_F32`: the shipped float policy (`shipped::policy`).
pub const CARTPOLE_POLICY_F32: c_int = 1;
/// `CARTPOLE_POLICY_INT`: the shipped integer policy (`shipped::policy_int`), integer
/// arithmetic from the observer's estimate to the decision.
pub const CARTPOLE_POLICY_INT: c_int = 2;

/// `cartpole_command_t`: what one period decided and drove.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CartpoleCommand {
    /// The sign of the duty commanded: `-1` a push left, `0` coast (a rejected reading, or
    /// a level of zero duty), `1` a push right.
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
    /// The duty commanded, in thousandths of the full push, `+` towards +x: the chosen
    /// output's level (`-1000` or `1000` for a two-output policy), `0` coasting.
    pub signed_duty: i32,
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
    /// Runs the controller's next periods inside `startup` on `rig`; refused if `rig` is
    /// not the instance's, or the instance has read states.
    fn start_up(&mut self, startup: Startup, rig: &Rig) -> Result<(), c_int>;
    /// The start-up's phase and transitions, if it has one.
    fn startup(&self) -> Option<&Sequencer>;
    /// Refines the policy's chosen level from the next period on, or stops; refused as
    /// the firmware refuses it ([`RefineRefused`]).
    fn refine(&mut self, on: bool) -> Result<(), c_int>;
}

impl<K: Kind> Run for Slot<K> {
    fn step(&mut self, handed: Handed) -> Option<CartpoleCommand> {
        let c = &mut self.controller;
        let during_startup = matches!(handed, Handed::State(_)) && self.startup.is_some();
        if during_startup || !c.sensor_mut().hand(handed) {
            return None;
        }
        let command = match (&mut self.startup, handed) {
            (Some(s), Handed::Counts(cart, pole)) => s.run((cart, pole), c),
            _ => c.step(),
        };
        let (&Level(direction), &Duty(duty)) = c.actuator().pins();
        // `step` has just recorded its period: the fallback is never taken.
        let (step, q, faults) = c
            .last()
            .map_or((c.steps(), Scores::UNSCORED, FaultFlags::default()), |r| {
                (r.step, r.q, r.faults)
            });
        let (q, q_int) = q.pairs();
        let signed_duty = match command {
            Command::Drive(d) => d.thousandths(),
            Command::Coast => 0,
        };
        Some(CartpoleCommand {
            command: signed_duty.signum().into(),
            direction: direction.into(),
            duty: duty.into(),
            faults: faults.0.into(),
            q,
            q_int,
            step,
            signed_duty: signed_duty.into(),
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
        // The envelope is measured for the policy's plain levels.
        if self.controller.refines() {
            return Err(CARTPOLE_ERR_ENVELOPE);
        }
        self.controller.sensor_mut().watch();
        self.controller.set_monitor(assurance);
        Ok(())
    }

    fn start_up(&mut self, startup: Startup, rig: &Rig) -> Result<(), c_int> {
        if firmware::link::digest::rig(rig) != self.rig {
            return Err(CARTPOLE_ERR_RIG);
        }
        if self.controller.sensor().reads_states() {
            return Err(CARTPOLE_ERR_INPUT);
        }
        self.startup = Some(Sequencer::new(startup, rig).map_err(|_| CARTPOLE_ERR_RIG)?);
        Ok(())
    }

    fn startup(&self) -> Option<&Sequencer> {
        self.startup.as_ref()
    }

    fn record_overruns(&mut self, ticks: u32) {
        self.controller.record_overruns(ticks);
    }

    fn refine(&mut self, on: bool) -> Result<(), c_int> {
        self.controller.refine(on).map_err(|why| match why {
            RefineRefused::NoInnerLevel => CARTPOLE_ERR_LEVELS,
            RefineRefused::Monitored => CARTPOLE_ERR_ENVELOPE,
        })
    }

    fn period_us(&self) -> u32 {
        self.period_us
    }
}

/// The instance in `c` and, mutably, of whichever kind initialised it: one pair for every
/// shape of either format.
macro_rules! instances {
    ($($h:literal x $a:literal => $($c:ident)/+,)*) => {
        /// The instance in `c`, whichever kind initialised it.
        fn instance(c: &CartpoleController) -> Result<&dyn Run, c_int> {
            $(
                if let Some(s) = slot::<Float<$h, $a>>(c) {
                    return Ok(s);
                }
                if let Some(s) = slot::<Int<$h, $a>>(c) {
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
                if m == Float::<$h, $a>::MAGIC {
                    slot_mut::<Float<$h, $a>>(c).map(|s| s as _)
                } else if m == Int::<$h, $a>::MAGIC {
                    slot_mut::<Int<$h, $a>>(c).map(|s| s as _)
                } else
            )* {
                None
            };
            run.ok_or(CARTPOLE_ERR_UNINITIALISED)
        }
    };
}
firmware::for_each_shape!(instances);

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
/// bounds on `|reading|`; NULL: the shipped policy's, `shipped::envelope`), bang-bang LQR
/// designed for `rig` outside it and after runs of faulty readings, a latched stop beyond
/// what LQR can recover; the observer watches for frozen encoders. `rig` must be the machine
/// `c` was initialised for (NULL: the shipped policies'). Solves the LQR gain: call it at
/// start-up. Refused, writing nothing: an envelope bound NaN, infinite or negative, or an
/// instance whose levels are refined ([`CARTPOLE_ERR_ENVELOPE`]), a rig no machine has or not the instance's
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
        None => shipped::envelope::ENVELOPE,
        Some(Ok(e)) => e,
        Some(Err(_)) => return CARTPOLE_ERR_ENVELOPE,
    };
    let Ok(rig) = rig_or_shipped(rig) else {
        return CARTPOLE_ERR_RIG;
    };
    let Ok(assurance) = rig.lqr_assurance(envelope) else {
        return CARTPOLE_ERR_RIG;
    };
    let digest = firmware::link::digest::rig(&rig);
    status(instance_mut(c).and_then(|r| r.monitor(assurance, digest)))
}

/// With `on` 1, `c`'s policy drives from its next period the duty between its levels where
/// its scores peak (`firmware::controller::Refined`: the parabola through the chosen
/// output's score and its neighbours'); with 0, its levels again. Refused, writing nothing:
/// [`CARTPOLE_ERR_FLAGS`] (`on` neither 0 nor 1); with `on` 1, [`CARTPOLE_ERR_LEVELS`] (a
/// policy of two outputs, both ends, which drive themselves) and [`CARTPOLE_ERR_ENVELOPE`]
/// (under the runtime monitor).
// SAFETY: as for `cartpole_controller_init`: one definition per C name.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn cartpole_controller_refine(
    c: Option<&mut CartpoleController>,
    on: c_int,
) -> c_int {
    let Some(c) = c else {
        return CARTPOLE_ERR_NULL;
    };
    let on = match on {
        0 => false,
        1 => true,
        _ => return CARTPOLE_ERR_FLAGS,
    };
    status(instance_mut(c).and_then(|r| r.refine(on)))
}

/// The machine of `rig` (NULL: the shipped policies'); refused as one no machine has.
fn rig_or_shipped(rig: Option<&CartpoleRig>) -> Result<Rig, c_int> {
    match rig.map(CartpoleRig::to_rig) {
        None => Ok(shipped::policy::RIG),
        Some(Some(rig)) => Ok(rig),
        Some(None) => Err(CARTPOLE_ERR_RIG),
    }
}

#[cfg(test)]
mod tests;
