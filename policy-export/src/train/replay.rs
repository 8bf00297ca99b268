//! The experience buffer: fixed capacity, oldest transition out first, sampled uniformly
//! without replacement.

use firmware::network::OBS_DIM;
use rand_core::Rng;

/// One stored transition, laid out to fill one cache line: a sampled row is one memory
/// access, where a column per field took six.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
struct Slot {
    obs: [f32; OBS_DIM],
    next: [f32; OBS_DIM],
    reward: f32,
    action: u8,
    terminated: bool,
    /// Which push filled the slot (1 = the first): tells a cache keyed by slot whether the
    /// slot still holds the transition it saw.
    write_id: u64,
}

/// A FIFO experience buffer of fixed capacity; the oldest transition goes first.
pub struct ReplayBuffer {
    slots: Vec<Slot>,
    pushes: u64,
    capacity: usize,
    pos: usize,
}

impl ReplayBuffer {
    /// An empty buffer holding at most `capacity` transitions.
    pub fn new(capacity: usize) -> Self {
        ReplayBuffer {
            slots: Vec::with_capacity(capacity),
            pushes: 0,
            capacity,
            pos: 0,
        }
    }

    /// Transitions held.
    pub fn len(&self) -> usize {
        self.slots.len()
    }

    /// Whether nothing is stored yet.
    pub fn is_empty(&self) -> bool {
        self.slots.is_empty()
    }

    /// Stores a transition, overwriting the oldest once full.
    pub fn push(&mut self, obs: [f32; 4], action: usize, reward: f32, next: [f32; 4], term: bool) {
        self.pushes += 1;
        let slot = Slot {
            obs,
            next,
            reward,
            action: action as u8,
            terminated: term,
            write_id: self.pushes,
        };
        if self.len() < self.capacity {
            self.slots.push(slot);
        } else {
            self.slots[self.pos] = slot;
        }
        self.pos = (self.pos + 1) % self.capacity;
    }

    /// `n` distinct indices, uniformly (as Python's `random.sample`); `n <= len()`.
    pub fn sample_indices<R: Rng>(&self, rng: &mut R, n: usize, out: &mut Vec<usize>) {
        out.clear();
        let len = self.len() as u64;
        while out.len() < n {
            // Lemire's multiply-shift: uniform enough for len << 2^32, no division.
            let i = ((u64::from(rng.next_u32()) * len) >> 32) as usize;
            if !out.contains(&i) {
                out.push(i);
            }
        }
    }

    /// The transition at index `i` (0 = oldest slot written first).
    pub fn get(&self, i: usize) -> ([f32; 4], u8, f32, [f32; 4], bool) {
        let s = &self.slots[i];
        (s.obs, s.action, s.reward, s.next, s.terminated)
    }

    /// Which push wrote slot `i`: unique over the buffer's life.
    pub fn write_id(&self, i: usize) -> u64 {
        self.slots[i].write_id
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::train::{Stream, rng};

    #[test]
    fn replay_buffer_wraps_around_oldest_first() {
        let mut b = ReplayBuffer::new(3);
        for i in 0..5 {
            b.push([i as f32; 4], i % 2, i as f32, [0.0; 4], i == 4);
        }
        assert_eq!(b.len(), 3);
        let rewards: Vec<f32> = (0..3).map(|i| b.get(i).2).collect();
        assert_eq!(
            rewards,
            [3.0, 4.0, 2.0],
            "slots 0 and 1 overwritten by the 4th and 5th"
        );
        assert!(b.get(1).4 && !b.get(0).4);
        let mut idx = Vec::new();
        let mut r = rng(1, Stream::Sample);
        for _ in 0..100 {
            b.sample_indices(&mut r, 3, &mut idx);
            let mut s = idx.clone();
            s.sort();
            assert_eq!(s, [0, 1, 2], "without replacement");
        }
    }
}
