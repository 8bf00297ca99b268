//! The line a C driver prints for a controller period that ran, made from the Rust
//! controller's record of the same period: what the C controller tests compare, period by
//! period (`c_controller.rs`, `c_exported.rs`).

use firmware::controller::Record;
use firmware::estimator::Estimate;
use firmware::loopback::{Duty, Level, Pins};

/// A reading format whose scores the drivers print as two floats, then two integers.
pub trait Scores: Estimate {
    /// The two-level policy's scores on readings of this format.
    type Scores: Copy;
    /// The scores as `(floats, integers)`, zeros for the kind the format has not.
    fn pair(q: Self::Scores) -> ([f32; 2], [i32; 2]);
}

impl Scores for [f32; 4] {
    type Scores = [f32; 2];
    fn pair(q: [f32; 2]) -> ([f32; 2], [i32; 2]) {
        (q, [0; 2])
    }
}

impl Scores for [i16; 4] {
    type Scores = [i32; 2];
    fn pair(q: [i32; 2]) -> ([f32; 2], [i32; 2]) {
        ([0.0; 2], q)
    }
}

/// `STATUS COMMAND DIRECTION DUTY FAULTS Q0 Q1 QI0 QI1 STEP` for the period `r` records, the
/// pins as it left them; the floats as their bits in hex.
pub fn step_line<R: Scores>(status: i32, r: &Record<R, R::Scores>, pins: &Pins) -> String {
    // The duty's sign, as the header's `command`: a partial duty (a level, a swing-up's push)
    // is a push too.
    let level = r.command.level();
    let command = i32::from(level > 0.0) - i32::from(level < 0.0);
    let (&Level(direction), &Duty(duty)) = pins.pins();
    let (q, qi) = R::pair(r.q);
    format!(
        "{status} {command} {} {duty} {} {:08x} {:08x} {} {} {}",
        u32::from(direction),
        r.faults.0,
        q[0].to_bits(),
        q[1].to_bits(),
        qi[0],
        qi[1],
        r.step
    )
}
