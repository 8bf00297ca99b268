//! A cart-pole of the tests' own, written from the log format's words
//! (`firmware::identify`) and Lagrange's equations rather than from the twin, with what the
//! fit's model leaves out: a motor whose force lags its duty, a pole of any mass
//! distribution, readings taken at uneven times, and a pole encoder wired either way.
//!
//! The pole's angle `phi` is measured from hanging, positive as the hanging pole's centre
//! of mass swings towards +x (it lies at `x + l sin phi`, `-l cos phi`). The log format
//! says the pole's counts grow as the pole turns the way that carries a hanging pole's tip
//! towards -x: a board wired by it counts `-phi`. The cart's counts grow towards +x, and a
//! duty of 1 pushes the cart towards +x.
//!
//! With the pole's centre of mass at `l`, its moment of inertia about the pivot `I`, the
//! cart and pole masses `M` and `m`, the motor's force `F` and the pivot's viscous friction
//! `mu`, the Lagrangian `(M + m) x_dot^2 / 2 + m l x_dot phi_dot cos phi + I phi_dot^2 / 2 +
//! m g l cos phi` gives
//!
//! ```text
//! (M + m) x_acc + m l cos phi phi_acc = F + m l sin phi phi_dot^2
//! m l cos phi x_acc + I phi_acc       = -m g l sin phi - mu phi_dot
//! ```

use firmware::identify::{Cart, Csv, Sink, Step, Swing};
use firmware::rig::Rig;

/// A machine as the tests build it.
#[derive(Clone, Copy, Debug)]
pub struct Bench {
    pub cart_kg: f64,
    pub pole_kg: f64,
    /// Pivot to the pole's centre of mass, m.
    pub com_m: f64,
    /// The pole's moment of inertia about the pivot, kg m^2: `4/3 m l^2` for a uniform rod
    /// whose centre of mass is at `l`.
    pub inertia: f64,
    pub stall_n: f64,
    pub damping_n_s_per_m: f64,
    pub pivot_n_m_s: f64,
    pub gravity: f64,
    /// Periods between a duty and the motor's answer.
    pub dead_periods: usize,
    /// The motor's electrical time constant, s: its force follows the duty through a
    /// first-order lag.
    pub lag_s: f64,
    /// The standard deviation of when a reading is taken about the period's start, s.
    pub timing_sd_s: f64,
    /// The pole's counts as the log format says (`-phi`), or the other way round.
    pub pole_as_documented: bool,
}

impl Bench {
    /// A uniform pole of `pole_kg` whose centre of mass is at `com_m`, the motor immediate,
    /// the readings on time, the pole counted as documented.
    pub fn uniform(cart_kg: f64, pole_kg: f64, com_m: f64, [stall_n, damping]: [f64; 2]) -> Bench {
        Bench {
            cart_kg,
            pole_kg,
            com_m,
            inertia: 4.0 / 3.0 * pole_kg * com_m * com_m,
            stall_n,
            damping_n_s_per_m: damping,
            pivot_n_m_s: 0.0,
            gravity: 9.8,
            dead_periods: 1,
            lag_s: 0.0,
            timing_sd_s: 0.0,
            pole_as_documented: true,
        }
    }
}

/// `[x, x_dot, phi, phi_dot, force fraction]`: the motor's force is `stall * u - damping *
/// x_dot` with `u` lagging the duty.
type Motion = [f64; 5];

impl Bench {
    /// `d/dt` of `s` under `duty`, the cart free or `held`.
    fn derivative(&self, s: &Motion, duty: f64, held: bool) -> Motion {
        let [_, v, phi, w, u] = *s;
        let (sin, cos) = phi.sin_cos();
        let ml = self.pole_kg * self.com_m;
        let torque = -ml * self.gravity * sin - self.pivot_n_m_s * w;
        let u_dot = if self.lag_s > 0.0 {
            (duty - u) / self.lag_s
        } else {
            0.0
        };
        if held {
            return [0.0, 0.0, w, torque / self.inertia, 0.0];
        }
        let u = if self.lag_s > 0.0 { u } else { duty };
        let force = self.stall_n * u - self.damping_n_s_per_m * v + ml * sin * w * w;
        // The 2 x 2 system by Cramer's rule.
        let (a, b, d) = (self.cart_kg + self.pole_kg, ml * cos, self.inertia);
        let det = a * d - b * b;
        let x_acc = (force * d - b * torque) / det;
        let phi_acc = (a * torque - b * force) / det;
        [v, x_acc, w, phi_acc, u_dot]
    }

    /// `s` after `dt` under `duty`, by classic Runge-Kutta steps of at most 0.25 ms.
    fn advance(&self, s: &Motion, duty: f64, held: bool, dt: f64) -> Motion {
        let n = (dt / 2.5e-4).ceil().max(1.0);
        let h = dt / n;
        let mut s = *s;
        for _ in 0..n as usize {
            let add = |a: &Motion, k: &Motion, f: f64| -> Motion {
                core::array::from_fn(|i| a[i] + f * k[i])
            };
            let k1 = self.derivative(&s, duty, held);
            let k2 = self.derivative(&add(&s, &k1, h / 2.0), duty, held);
            let k3 = self.derivative(&add(&s, &k2, h / 2.0), duty, held);
            let k4 = self.derivative(&add(&s, &k3, h), duty, held);
            s = core::array::from_fn(|i| s[i] + h / 6.0 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]));
        }
        s
    }
}

/// Normal deviates from a seeded generator of the tests' own (Box-Muller on a 64-bit LCG).
struct Noise(u64);

impl Noise {
    fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn normal(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (core::f64::consts::TAU * b).cos()
    }
}

/// The counts `board`'s encoders read of `s`: floor of the value over a count, taken
/// `noise`'s jitter late or early, the pole's sign as the bench is wired.
fn read(bench: &Bench, board: &Rig, s: &Motion, noise: &mut Noise) -> (i32, i32) {
    let late = bench.timing_sd_s * noise.normal();
    let x = s[0] + late * s[1];
    let phi = s[2] + late * s[3];
    let per_rad = f64::from(board.encoders.pole_counts_per_rev) / core::f64::consts::TAU;
    let pole = if bench.pole_as_documented { -phi } else { phi };
    (
        (x * f64::from(board.encoders.cart_counts_per_m)).floor() as i32,
        (pole * per_rad).floor() as i32,
    )
}

/// The cart experiment of `seconds` (bits held 0.04 s, sequence `seed`) as `board` logs it
/// on `bench`; the pole starting hanging at rest, the cart at rest at the centre.
pub fn cart_log(bench: &Bench, board: &Rig, seconds: f64, seed: u32) -> String {
    let tau = board.params.tau;
    let periods = (seconds / tau).round() as u32;
    let mut cart = Cart::new(board, periods, (0.04 / tau).round() as u32, seed);
    let mut text = Csv(String::new());
    let _ = text.header(&cart.header(board));
    let mut noise = Noise(u64::from(seed) + 17);
    let mut s: Motion = [0.0; 5];
    let mut line = vec![0.0; bench.dead_periods];
    loop {
        let (c, p) = read(bench, board, &s, &mut noise);
        let Step::Log(row) = cart.step(c, p) else {
            return text.0;
        };
        let _ = text.record(&row);
        line.push(f64::from(row.duty));
        let acting = line.remove(0);
        s = bench.advance(&s, acting, false, tau);
    }
}

/// The swing experiment as `board` logs it on `bench`, its cart held: the pole raised by
/// hand to 20 degrees over half a second, held a while and let go, `seconds` logged after.
pub fn swing_log(bench: &Bench, board: &Rig, seconds: f64) -> String {
    let tau = board.params.tau;
    let mut swing = Swing::new(board.encoders, (seconds / tau).round() as u32);
    let mut text = Csv(String::new());
    let _ = text.header(&swing.header(board));
    let mut noise = Noise(5);
    let (rest, lift) = ((0.3 / tau) as u32, (0.5 / tau) as u32);
    let mut s: Motion = [0.0; 5];
    for k in 0.. {
        if k < 2 * rest + lift {
            let raised = f64::from(k.saturating_sub(rest)) / f64::from(lift);
            s[2] =
                20f64.to_radians() * (0.5 - 0.5 * (core::f64::consts::PI * raised.min(1.0)).cos());
        }
        let (c, p) = read(bench, board, &s, &mut noise);
        match swing.step(c, p) {
            Step::Done => break,
            Step::Log(row) => {
                let _ = text.record(&row);
            }
            Step::Wait => {}
        }
        if k + 1 >= 2 * rest + lift {
            s = bench.advance(&s, 0.0, true, tau);
        }
    }
    text.0
}
