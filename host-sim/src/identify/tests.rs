use super::*;
use firmware::rig::Rig;
use rand_core::Rng;
use rand_pcg::Pcg64Mcg;
use twin::machine::Integration;

fn uniform(rng: &mut Pcg64Mcg, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * firmware::cartpole::unit_f64(rng)
}

fn random_rig(rng: &mut Pcg64Mcg, tau: f64, half: f64) -> (Machine, Machine) {
    let masscart = uniform(rng, 0.3, 2.0);
    let masspole = uniform(rng, 0.05, 0.3);
    let length = uniform(rng, 0.1, 0.5);
    let sigma = uniform(rng, 0.01, 0.1);
    let params = Params {
        masscart,
        masspole,
        length,
        force_mag: uniform(rng, 2.0, 15.0),
        motor_damping: uniform(rng, 0.5, 6.0),
        tau,
        x_threshold: half,
        cart_friction: uniform(rng, 0.0, 0.05),
        pole_friction: 8.0 * masspole * length * length * sigma / 3.0,
        ..Params::default()
    };
    let dead = rng.next_u32() % 4;
    let rig = Rig {
        params,
        encoders: firmware::estimator::Encoders {
            cart_counts_per_m: 15_000,
            pole_counts_per_rev: 2_400,
        },
        dead_time: dead,
        end_stop_margin: 0.05,
        tuning: firmware::estimator::Tuning::DEFAULT,
    };
    let truth = Machine {
        rig,
        integration: Integration::rk4(tau, 0.0002),
    };
    let mut measured = Machine {
        rig,
        integration: Integration::rk4(tau, 0.001),
    };
    let p = &mut measured.rig.params;
    p.length *= uniform(rng, 0.9, 1.1);
    p.force_mag *= uniform(rng, 0.5, 2.0);
    p.motor_damping *= uniform(rng, 0.5, 2.0);
    p.cart_friction = 0.0;
    p.pole_friction = 0.0;
    measured.rig.dead_time = 1;
    (truth, measured)
}

#[test]
fn explore() {
    let mut rng = Pcg64Mcg::new(11);
    for i in 0..12u32 {
        let tau = if i % 2 == 0 { 0.02 } else { 0.01 };
        let (truth, measured) = random_rig(&mut rng, tau, 1.0);
        let zero = synthetic::Zero {
            cart: uniform(&mut rng, 0.0, 1.0),
            pole: uniform(&mut rng, 0.0, 1.0),
        };
        if std::env::var("ONLY").is_ok_and(|o| o != i.to_string()) {
            continue;
        }
        let periods = (10.0 / tau).round() as u32;
        let hold = (0.04 / tau).round() as u32;
        let cart = synthetic::cart_log(&truth, &measured.rig, periods, hold, i, zero);
        let swing = synthetic::swing_log(
            &truth,
            &measured.rig,
            20.0,
            [(0.3 / tau) as u32, (0.5 / tau) as u32],
            (20.0 / tau) as u32,
            zero,
        );
        let mut logs = log::parse(&cart, "cart").unwrap();
        logs.extend(log::parse(&swing, "swing").unwrap());
        if std::env::var("DUMP").is_ok() {
            std::fs::write(format!("/tmp/cart{i}.csv"), &cart).unwrap();
            eprintln!("truth {:?}", truth.rig.params);
        }
        let maxx = logs[0].cart.iter().map(|c| c.abs()).max().unwrap() as f64 / 15000.0;
        let t0 = std::time::Instant::now();
        let r = identify(&logs, &measured);
        let el = t0.elapsed().as_secs_f64();
        let p = &truth.rig.params;
        match r {
            Ok(f) => {
                let q = &f.params;
                println!(
                    "{i} tau {tau} maxx {maxx:.3} t {el:.2}s  F {:.2}/{:.2} ({:+.2}%) b {:.2}/{:.2} ({:+.2}%) l {:.3}/{:.3} ({:+.2}%) mu_c {:.4}/{:.4} mu_p {:.2e}/{:.2e} d {}/{} sse {:?} rms {:?}",
                    q.force_mag,
                    p.force_mag,
                    100.0 * (q.force_mag / p.force_mag - 1.0),
                    q.motor_damping,
                    p.motor_damping,
                    100.0 * (q.motor_damping / p.motor_damping - 1.0),
                    q.length,
                    p.length,
                    100.0 * (q.length / p.length - 1.0),
                    q.cart_friction,
                    p.cart_friction,
                    q.pole_friction,
                    p.pole_friction,
                    f.dead_time,
                    truth.rig.dead_time,
                    f.dead_time_sse
                        .iter()
                        .map(|s| format!("{s:.2e}"))
                        .collect::<Vec<_>>(),
                    f.traces
                        .iter()
                        .flat_map(|t| t.channels.iter().map(|c| format!("{:.2}", c.rms)))
                        .collect::<Vec<_>>()
                );
            }
            Err(e) => println!("{i} maxx {maxx:.3} error {e}  truth {:?}", p),
        }
    }
}

#[test]
fn explore_safety() {
    let mut rng = Pcg64Mcg::new(5);
    for half in [0.4, 0.6, 1.0] {
        let mut worst: Vec<f64> = Vec::new();
        for i in 0..200u32 {
            let tau = if i % 2 == 0 { 0.02 } else { 0.01 };
            let (truth, measured) = random_rig(&mut rng, tau, half);
            let periods = (10.0 / tau).round() as u32;
            let hold = (0.04 / tau).round() as u32;
            let cart = synthetic::cart_log(
                &truth,
                &measured.rig,
                periods,
                hold,
                i,
                synthetic::Zero::default(),
            );
            let l = &log::parse(&cart, "c").unwrap()[0];
            let maxx = l.cart.iter().map(|c| c.abs()).max().unwrap() as f64 / 15000.0;
            let span =
                (l.cart.iter().max().unwrap() - l.cart.iter().min().unwrap()) as f64 / 15000.0;
            worst.push(maxx / (half - 0.05));
            if maxx > half {
                let p = truth.rig.params;
                println!(
                    "half {half} OUT {:.2} F {:.1} b {:.2} M {:.2} d {} span {span:.2}",
                    maxx,
                    p.force_mag,
                    p.motor_damping,
                    p.masscart + p.masspole,
                    truth.rig.dead_time
                );
            }
        }
        worst.sort_by(f64::total_cmp);
        println!(
            "half {half}: median {:.2} p90 {:.2} max {:.2} min {:.2}",
            worst[100], worst[180], worst[199], worst[0]
        );
    }
}
