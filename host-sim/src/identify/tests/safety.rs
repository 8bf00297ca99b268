//! The cart experiment's safety rule on machines the board knows only by a wrong rig file:
//! however strong the motor, however light the cart, however long the dead time, the cart
//! stays inside the usable track.

use super::*;

/// The farthest the cart of a cart log gets from the centre, as a fraction of the usable
/// track: its counts, read the way the board reads them.
fn reach(log: &Log, rig: &Rig) -> f64 {
    let usable = rig.params.x_threshold - rig.end_stop_margin;
    let farthest = log.cart.iter().map(|c| c.unsigned_abs()).max().unwrap_or(0);
    (f64::from(farthest) + 1.0) / f64::from(rig.encoders.cart_counts_per_m) / usable
}

/// The strongest motor of a plausible rig, as the acceleration it gives the whole machine
/// from rest, in g: beyond it a hanging pole pumped over the top spins fast enough to throw
/// the cart about by more than the motor can hold.
const MAX_PUSH_G: f64 = 2.0;

/// On tracks of 0.25 to 0.95 m usable, both periods, every dead time up to two periods
/// longer than the board assumes.
#[test]
fn the_cart_never_passes_the_usable_track() {
    let mut rng = Pcg64Mcg::new(5);
    for half in [0.3, 0.5, 1.0] {
        for i in 0..200u32 {
            let tau = if i % 2 == 0 { 0.02 } else { 0.01 };
            let (truth, measured) = random_rig(&mut rng, tau, half);
            let p = &truth.rig.params;
            if p.force_mag / p.total_mass() > MAX_PUSH_G * p.gravity {
                continue;
            }
            let periods = (synthetic::CART_S / tau).round() as u32;
            let hold = (synthetic::HOLD_S / tau).round() as u32;
            let reading = random_reading(&mut rng, 0.5);
            let text = synthetic::cart_log(&truth, &measured.rig, [periods, hold, i], reading);
            let log = &log::parse(&text, "cart").unwrap()[0];
            let r = reach(log, &measured.rig);
            assert!(
                r < 1.0,
                "half {half}, rig {i}: the cart reached {r:.3} of the usable track: {:?}, \
                 dead time {}",
                truth.rig.params,
                truth.rig.dead_time
            );
        }
    }
}
