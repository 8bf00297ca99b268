//! What a target holds, as 64-bit FNV-1a digests (Fowler, Noll and Vo; the IETF draft
//! "The FNV Non-Cryptographic Hash Algorithm"): the host computes them of the policy and the
//! rig it means to run and compares them with the target's [`super::Info`], so a run never
//! checks a board that holds another policy or models another machine. Not a defence against
//! anyone; a check against mistakes. Every value is digested as its little-endian bytes, in
//! the order of its type's fields.

use crate::controller::Levels;
use crate::network::Mlp;
use crate::network::int::QMlp;
use crate::rig::Rig;

/// A digest in progress.
#[derive(Clone, Copy, Debug)]
pub struct Fnv(u64);

impl Default for Fnv {
    fn default() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv {
    /// `bytes` digested.
    pub fn bytes(self, bytes: &[u8]) -> Fnv {
        Fnv(bytes.iter().fold(self.0, |h, &b| {
            (h ^ b as u64).wrapping_mul(0x0000_0100_0000_01b3)
        }))
    }

    /// Every value of `values` digested, each as `to_bytes` gives it.
    fn all<T: Copy, const N: usize>(self, values: &[T], to_bytes: fn(T) -> [u8; N]) -> Fnv {
        values.iter().fold(self, |h, &v| h.bytes(&to_bytes(v)))
    }

    /// The digest.
    pub fn finish(self) -> u64 {
        self.0
    }
}

/// The digest of a float network's parameters.
pub fn mlp<const H: usize, const A: usize>(m: &Mlp<H, A>) -> u64 {
    let f = f32::to_le_bytes;
    Fnv::default()
        .all(m.fc1_weight.as_flattened(), f)
        .all(&m.fc1_bias, f)
        .all(m.fc2_weight.as_flattened(), f)
        .all(&m.fc2_bias, f)
        .all(m.fc3_weight.as_flattened(), f)
        .all(&m.fc3_bias, f)
        .finish()
}

/// The digest of an integer network's parameters.
pub fn qmlp<const H: usize, const A: usize>(m: &QMlp<H, A>) -> u64 {
    let (i, w) = (i32::to_le_bytes, i8::to_le_bytes);
    let requant = |h: Fnv, r: &[crate::network::int::Requant]| {
        r.iter().fold(h, |h, r| {
            h.bytes(&r.multiplier.to_le_bytes())
                .bytes(&[r.pre_shift, r.post_shift])
        })
    };
    let h = Fnv::default()
        .all(&m.fc1_bias, i)
        .all(&m.fc2_bias, i)
        .all(&m.fc3_bias, i);
    requant(requant(h, &m.fc1_requant), &m.fc2_requant)
        .all(m.fc1_weight.as_flattened(), w)
        .all(m.fc2_weight.as_flattened(), w)
        .all(m.fc3_weight.as_flattened(), w)
        .finish()
}

/// A network's digest ([`mlp`] or [`qmlp`]) continued over the duty levels its outputs
/// drive, in thousandths of the full push: what a target's [`super::Info`] names as its
/// policy. The same network driving other duties is another policy: it pushes the cart
/// otherwise.
pub fn policy<const A: usize>(network: u64, levels: &Levels<A>) -> u64 {
    let thousandths: [i16; A] = core::array::from_fn(|i| levels.duties()[i].thousandths());
    Fnv(network).all(&thousandths, i16::to_le_bytes).finish()
}

/// The digest of a rig: every number a board's observer, predictor and limits are built
/// from.
pub fn rig(r: &Rig) -> u64 {
    // Destructured, so that a field added to the rig cannot be left out (and
    // `Params::values` is every field of the physics).
    let Rig {
        params,
        encoders,
        dead_time,
        end_stop_margin,
        tuning,
    } = *r;
    let counts = [
        encoders.cart_counts_per_m,
        encoders.pole_counts_per_rev,
        dead_time,
    ];
    let tuning = [
        end_stop_margin,
        tuning.force_sd,
        tuning.accel_sd[0],
        tuning.accel_sd[1],
    ];
    Fnv::default()
        .all(&params.values(), f64::to_le_bytes)
        .all(&counts, u32::to_le_bytes)
        .all(&tuning, f64::to_le_bytes)
        .finish()
}
