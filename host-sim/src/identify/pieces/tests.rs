use super::*;
use crate::identify::{log, synthetic};

/// A cart log of `periods` periods with `per`-period pieces and made-up counts.
fn data(periods: usize, per: usize) -> CartData {
    let pieces = (periods / per).max(1);
    CartData {
        duty: (0..periods)
            .map(|k| if k % 3 == 0 { 1.0 } else { -1.0 })
            .collect(),
        counts: (0..periods).map(|k| k as f64).collect(),
        pole: (0..periods).map(|k| -(k as f64)).collect(),
        per_m: 15_000.0,
        per_rad: 2_400.0 / core::f64::consts::TAU,
        segments: (0..pieces)
            .map(|i| {
                i * per..if i + 1 == pieces {
                    periods
                } else {
                    (i + 1) * per
                }
            })
            .collect(),
    }
}

#[test]
fn prefixes_are_whole_pieces_in_the_order_given() {
    let carts = [data(550, 100), data(300, 100)];
    let four = prefix(&carts, 420);
    assert_eq!(four.len(), 1);
    assert_eq!(four[0].segments, [0..100, 100..200, 200..300, 300..400]);
    assert_eq!(four[0].counts, carts[0].counts[..400]);
    // The first log whole (its last piece 150 long), then 450 left: the second whole too.
    let all = prefix(&carts, 1_000);
    assert_eq!(all.len(), 2);
    assert_eq!(all[0].segments, carts[0].segments);
    assert_eq!(all[1].duty, carts[1].duty);
    // Less than a piece: the first piece.
    assert_eq!(prefix(&carts, 30)[0].segments, vec![0..100]);
}

#[test]
fn a_carried_vector_keeps_the_pieces_that_start_alike() {
    let from = vec![vec![0..100, 100..200]];
    // Shared 7, 8; piece 0's state 1..4, piece 1's 5..8.
    let x = [7.0, 8.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0];
    let mut to = [data(200, 50), data(100, 100)];
    to[0].segments = vec![0..50, 50..100, 100..200];
    // Counts' states: 10s for the first log's pieces, 20s for the second's.
    let start: Vec<f64> = [10.0, 11.0, 12.0, 20.0]
        .iter()
        .flat_map(|&v| [v; 4])
        .collect();
    let carried = carry((&from, &x), &to, 2, &start);
    let want: Vec<f64> = [7.0, 8.0, 1.0, 2.0, 3.0, 4.0, 11.0, 11.0, 11.0, 11.0]
        .into_iter()
        .chain([5.0, 6.0, 7.0, 8.0, 20.0, 20.0, 20.0, 20.0])
        .collect();
    assert_eq!(carried, want);
}

/// Counts simulated at a vector with the rounding's scatter on them, one piece's pole moved
/// a third of a revolution: that piece alone is cut, at its middle, and only while it is
/// at least twice the shortest.
#[test]
fn only_a_lost_piece_is_cut() {
    let truth = twin::rigfile::load(&std::path::PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../rigs/desk.toml"
    )))
    .unwrap();
    let [text, _] = synthetic::experiments(&truth, &truth.rig, 1, Default::default());
    let mut carts = vec![CartData::new(&log::parse(&text, "cart").unwrap()[0])];
    assert_eq!(carts[0].segments.len(), 5);
    let free = vec![model::FORCE, model::DAMPING, model::CART_FRICTION];
    let p = truth.rig.params;
    let setup = Setup::new(p, truth.integration, (&carts, &[]), 1, free.clone());
    let x: Vec<f64> = [p.force_mag, p.motor_damping, p.cart_friction]
        .into_iter()
        .chain(setup.nuisance_start())
        .collect();
    let [cart, pole] = setup.simulated(&x).0.remove(0);
    let wobble = |k: usize| if k.is_multiple_of(2) { 0.3 } else { -0.3 };
    carts[0].counts = cart
        .iter()
        .enumerate()
        .map(|(k, c)| c + wobble(k))
        .collect();
    carts[0].pole = pole
        .iter()
        .enumerate()
        .map(|(k, c)| c + wobble(k))
        .collect();
    for c in &mut carts[0].pole[200..300] {
        *c += 800.0;
    }
    let setup = Setup::new(p, truth.integration, (&carts, &[]), 1, free);
    let cut = cut_lost(&setup, &x, 20).unwrap();
    assert_eq!(
        cut,
        [vec![
            0..100,
            100..200,
            200..250,
            250..300,
            300..400,
            400..500
        ]]
    );
    assert!(
        cut_lost(&setup, &x, 51).is_none(),
        "a piece under twice the shortest"
    );
    carts[0].pole[200..300].iter_mut().for_each(|c| *c -= 800.0);
    let setup = Setup::new(p, truth.integration, (&carts, &[]), 1, vec![0, 1, 2]);
    assert!(cut_lost(&setup, &x, 20).is_none(), "nothing lost");
}
