//! The caller-allocated `cartpole_controller_t`: opaque bytes that hold one controller of
//! one network format and shape, and the magic word that tells an initialised one from any
//! other memory. The only `unsafe` of the controller's API is here: reading the magic from
//! memory C hands over, and viewing the bytes as the controller the magic names.

use core::ffi::c_void;
use core::mem::{MaybeUninit, align_of, size_of};

use firmware::ConfigError;
use firmware::controller::{Controller, Greedy, Policy, Refinable};
use firmware::estimator::{Estimate, ObserverSensor};
use firmware::loopback::{self, Latest, Pins};
use firmware::network::Mlp;
use firmware::network::int::QMlp;
use firmware::rig::{Options, Rig};
use firmware::startup::Sequencer;

use super::input::{CScores, Input};

/// `CARTPOLE_CONTROLLER_SIZE`: the bytes of `cartpole_controller_t`, one value for every
/// target so that C code can allocate it statically without knowing the library's layout.
pub const CONTROLLER_SIZE: usize = 1152;

/// `cartpole_controller_t`: aligned as the union of the C header (`uint64_t`, `double`,
/// `void *`) aligns it, which C99 can say without `_Alignas`.
#[repr(C)]
pub struct CartpoleController {
    opaque: Opaque,
}

#[repr(C)]
union Opaque {
    bytes: [MaybeUninit<u8>; CONTROLLER_SIZE],
    align_u64: u64,
    align_double: f64,
    align_pointer: *mut c_void,
}

/// A network format and shape, with the reading format its controller runs in.
pub(crate) trait Kind: 'static {
    /// The reading format of its controller.
    type Reading: Estimate;
    /// The network on its levels, as the controller holds it.
    type Policy: Policy<Self::Reading, Scores: CScores>;
    /// What the first word of an instance of this kind holds.
    const MAGIC: u32;
}

/// The float network of width `H` with `A` outputs (`firmware::network::Mlp`).
pub(crate) struct Float<const H: usize, const A: usize>;
/// The integer network of width `H` with `A` outputs (`firmware::network::int::QMlp`).
pub(crate) struct Int<const H: usize, const A: usize>;

/// `prefix` then a byte that tells the shapes apart: the width's (a power of two) exponent
/// in the low four bits, the outputs beyond two in the high four, so that a two-output
/// network's magic is the one it had before networks had more outputs.
const fn magic_of(prefix: [u8; 3], width: usize, outputs: usize) -> u32 {
    let shape = width.trailing_zeros() as usize | ((outputs - 2) << 4);
    u32::from_be_bytes([prefix[0], prefix[1], prefix[2], shape as u8])
}

impl<const H: usize, const A: usize> Kind for Float<H, A> {
    type Reading = [f32; 4];
    type Policy = Greedy<&'static Mlp<H, A>, A>;
    const MAGIC: u32 = magic_of(*b"CPf", H, A);
}

impl<const H: usize, const A: usize> Kind for Int<H, A> {
    type Reading = [i16; 4];
    type Policy = Greedy<&'static QMlp<H, A>, A>;
    const MAGIC: u32 = magic_of(*b"CPi", H, A);
}

/// The controller C runs, its policy refined as C asks (`cartpole_controller_refine`): one
/// telemetry record, the period's own, is all C reads back.
pub(crate) type Running<K> =
    Controller<Refinable<<K as Kind>::Policy>, Input<<K as Kind>::Reading>, Pins>;

/// What an initialised `cartpole_controller_t` holds; `magic` first, where [`magic`] reads
/// it whichever kind wrote it.
#[repr(C)]
pub(crate) struct Slot<K: Kind> {
    magic: u32,
    /// The rig's control period, rounded to microseconds.
    pub(crate) period_us: u32,
    /// The rig's digest ([`firmware::link::digest::rig`]): the monitor's fallback must be
    /// designed for the machine the controller was built for.
    pub(crate) rig: u64,
    pub(crate) controller: Running<K>,
    /// The start-up around it, once C asked for one (`cartpole_controller_startup`).
    pub(crate) startup: Option<Sequencer>,
}

impl<K: Kind> Slot<K> {
    /// Fails to compile for a kind whose slot the C type cannot hold.
    const FITS: () = {
        assert!(size_of::<Slot<K>>() <= size_of::<CartpoleController>());
        assert!(align_of::<Slot<K>>() <= align_of::<CartpoleController>());
    };

    /// A controller of `policy` for `rig` as every Rust board builds one: the rig's
    /// observer behind the encoders, its predictor if it has dead time, its limits, pins not
    /// yet driven, its levels not refined. Solves the observer's gain: once, at start-up.
    /// Refused as the firmware refuses the rig's observer, limits or predictor.
    pub(crate) fn new(policy: K::Policy, rig: &Rig) -> Result<Self, ConfigError> {
        let encoders = ObserverSensor::new(rig.observer()?, Latest::default());
        let options = Options {
            predict: true,
            monitor: None,
        };
        let policy = Refinable {
            policy,
            refine: false,
        };
        let controller = rig.controller(policy, Input::new(encoders), loopback::pins(), options)?;
        Ok(Slot {
            magic: K::MAGIC,
            // `as` saturates: a nonsense period reads as 0 or the largest, never wraps.
            period_us: (rig.params.tau * 1e6 + 0.5) as u32,
            rig: firmware::link::digest::rig(rig),
            controller,
            startup: None,
        })
    }

    /// Puts `self` in `c`, which from now on is an instance of this policy.
    pub(crate) fn store(self, c: &mut CartpoleController) {
        let () = Self::FITS;
        let at = (c as *mut CartpoleController).cast::<Slot<K>>();
        // SAFETY: `FITS` holds at compile time, so `c` has room for a `Slot<K>` and is
        // aligned for it; `write` drops nothing of what `c` held (bytes, or an earlier slot,
        // which owns nothing: its policy is a shared reference).
        #[allow(unsafe_code)]
        unsafe {
            at.write(self)
        };
    }
}

/// The magic word in `c`: one of the kinds' only if `c` was initialised for it.
pub(crate) fn magic(c: &CartpoleController) -> u32 {
    let at = (c as *const CartpoleController).cast::<u32>();
    // SAFETY: `c` spans `CONTROLLER_SIZE` (at least four) bytes aligned for a u64, so for
    // a u32, and any four bytes are a u32. Memory C never wrote holds bytes of unknown
    // value, not Rust's uninitialised ones: it reaches Rust through a pointer the compiler
    // cannot see behind, and Rust code outside this crate cannot make a
    // `CartpoleController` (its field is private).
    #[allow(unsafe_code)]
    unsafe {
        at.read()
    }
}

/// `c` as the slot of the kind `K`, if its magic says it is one.
pub(crate) fn slot<K: Kind>(c: &CartpoleController) -> Option<&Slot<K>> {
    let () = Slot::<K>::FITS;
    let at = (c as *const CartpoleController).cast::<Slot<K>>();
    // SAFETY: the magic of `K` is only ever written by `Slot::<K>::store`, which wrote a
    // whole `Slot<K>` there (room and alignment by `FITS`); a slot owns nothing and points
    // only at its weights, the shipped ones or those C promised to keep for the controller's
    // life and its copies' (`cartpole_controller_init_mlpH`), so a C copy of the bytes is a
    // valid slot too.
    #[allow(unsafe_code)]
    (magic(c) == K::MAGIC).then(|| unsafe { &*at })
}

/// [`slot`], to change it.
pub(crate) fn slot_mut<K: Kind>(c: &mut CartpoleController) -> Option<&mut Slot<K>> {
    let () = Slot::<K>::FITS;
    let is_k = magic(c) == K::MAGIC;
    let at = (c as *mut CartpoleController).cast::<Slot<K>>();
    // SAFETY: as for `slot`; `c` is borrowed mutably for as long as the slot is.
    #[allow(unsafe_code)]
    is_k.then(|| unsafe { &mut *at })
}

#[cfg(test)]
impl CartpoleController {
    /// Memory C might hand over without initialising it: every byte `byte`.
    pub(crate) fn filled(byte: u8) -> Self {
        CartpoleController {
            opaque: Opaque {
                bytes: [MaybeUninit::new(byte); CONTROLLER_SIZE],
            },
        }
    }
}
