//! The start-up from power-on for C (`firmware::startup`), declared in
//! `capi/include/cartpole_policy.h`:
//!
//! ```c
//! int cartpole_controller_startup(cartpole_controller_t *c, const struct cartpole_rig *rig,
//!                                 int flags);
//! int cartpole_controller_phase(const cartpole_controller_t *c, cartpole_phase_t *out);
//! ```

use core::ffi::c_int;

use firmware::startup::{Homing, Phase, Startup};

use super::{
    CARTPOLE_ERR_FLAGS, CARTPOLE_ERR_NO_STARTUP, CARTPOLE_ERR_NULL, CARTPOLE_ERR_RIG,
    CartpoleController, instance, instance_mut, rig_or_shipped, status,
};
use crate::rig::CartpoleRig;

/// `cartpole_phase_t`: where the start-up is, and its transitions so far.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CartpolePhase {
    /// `CARTPOLE_PHASE_*`.
    pub phase: u32,
    /// Zeros taken.
    pub zeroed: u32,
    /// Entries into the catch region.
    pub entered: u32,
    /// Hand-overs to the balance controller.
    pub caught: u32,
    /// Catches abandoned before the hand-over.
    pub missed: u32,
    /// Falls while balancing.
    pub fell: u32,
    /// The zero refined while balancing so far, rad ([`Startup::trim_rate`]).
    pub trim: f32,
    /// Centres found by homing.
    pub homed: u32,
}

/// [`Phase::Zeroing`]: motor off, taking the pole's hanging zero.
pub const CARTPOLE_PHASE_ZEROING: u32 = 0;
/// [`Phase::Waiting`]: motor off until a hand lifts the pole into the catch region.
pub const CARTPOLE_PHASE_WAITING: u32 = 1;
/// [`Phase::SwingingUp`]: the energy-based swing-up drives.
pub const CARTPOLE_PHASE_SWINGING_UP: u32 = 2;
/// [`Phase::Catching`]: inside the catch region, not yet for long enough.
pub const CARTPOLE_PHASE_CATCHING: u32 = 3;
/// [`Phase::Balancing`]: the balance controller drives.
pub const CARTPOLE_PHASE_BALANCING: u32 = 4;
/// [`Phase::Fallen`]: motor off until the pole is below horizontal.
pub const CARTPOLE_PHASE_FALLEN: u32 = 5;
/// [`Phase::Homing`]: the cart driven against the -x end stop, then to the centre.
pub const CARTPOLE_PHASE_HOMING: u32 = 6;

/// `cartpole_controller_startup`'s flag: swing the pole up rather than wait for a hand.
pub const CARTPOLE_STARTUP_SWING_UP: c_int = 1;
/// `cartpole_controller_startup`'s flag: home the cart first ([`Homing::suggested`]).
pub const CARTPOLE_STARTUP_HOME: c_int = 2;

/// The C constant of `phase`.
fn code(phase: Phase) -> u32 {
    match phase {
        Phase::Zeroing => CARTPOLE_PHASE_ZEROING,
        Phase::Waiting => CARTPOLE_PHASE_WAITING,
        Phase::SwingingUp => CARTPOLE_PHASE_SWINGING_UP,
        Phase::Catching => CARTPOLE_PHASE_CATCHING,
        Phase::Balancing => CARTPOLE_PHASE_BALANCING,
        Phase::Fallen => CARTPOLE_PHASE_FALLEN,
        Phase::Homing => CARTPOLE_PHASE_HOMING,
    }
}

/// Runs `c`'s next periods inside the start-up suggested for `rig`
/// ([`Startup::suggested`]; `rig` must be the machine `c` was initialised for, NULL the
/// shipped policies'): from power-on the cart homed ([`CARTPOLE_STARTUP_HOME`] in `flags`),
/// the pole's zero taken hanging, then the pole swung up ([`CARTPOLE_STARTUP_SWING_UP`]) or
/// waited for until a hand lifts it, caught, balanced, and after a fall swung up or waited
/// for again. Its steps take counts (raw, as the encoders count from power-on). Refused,
/// writing nothing: other bits in `flags` ([`CARTPOLE_ERR_FLAGS`]), a rig no machine has or
/// not the instance's ([`CARTPOLE_ERR_RIG`]), an instance that has read states
/// ([`super::CARTPOLE_ERR_INPUT`]).
// SAFETY: as for `cartpole_controller_init`: one definition per C name.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn cartpole_controller_startup(
    c: Option<&mut CartpoleController>,
    rig: Option<&CartpoleRig>,
    flags: c_int,
) -> c_int {
    let Some(c) = c else {
        return CARTPOLE_ERR_NULL;
    };
    if flags & !(CARTPOLE_STARTUP_SWING_UP | CARTPOLE_STARTUP_HOME) != 0 {
        return CARTPOLE_ERR_FLAGS;
    }
    let Ok(rig) = rig_or_shipped(rig) else {
        return CARTPOLE_ERR_RIG;
    };
    let Ok(mut startup) = Startup::suggested(&rig) else {
        return CARTPOLE_ERR_RIG;
    };
    if flags & CARTPOLE_STARTUP_SWING_UP == 0 {
        startup.swing = None;
    }
    if flags & CARTPOLE_STARTUP_HOME != 0 {
        startup.homing = Some(Homing::suggested(rig.params.tau));
    }
    status(instance_mut(c).and_then(|r| r.start_up(startup, &rig)))
}

/// The start-up's phase after the last step, and its transitions, in `out`. Refused,
/// writing nothing: an instance without a start-up ([`CARTPOLE_ERR_NO_STARTUP`]).
// SAFETY: as for `cartpole_controller_init`: one definition per C name.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn cartpole_controller_phase(
    c: Option<&CartpoleController>,
    out: Option<&mut CartpolePhase>,
) -> c_int {
    let (Some(c), Some(out)) = (c, out) else {
        return CARTPOLE_ERR_NULL;
    };
    status(instance(c).and_then(|r| {
        let s = r.startup().ok_or(CARTPOLE_ERR_NO_STARTUP)?;
        let t = s.transitions();
        *out = CartpolePhase {
            phase: code(s.phase()),
            zeroed: t.zeroed,
            entered: t.entered,
            caught: t.caught,
            missed: t.missed,
            fell: t.fell,
            trim: s.trim(),
            homed: t.homed,
        };
        Ok(())
    }))
}
