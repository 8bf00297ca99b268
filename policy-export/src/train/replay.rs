//! The experience buffer: fixed capacity, oldest transition out first, sampled uniformly
//! without replacement.

use firmware::cartpole::Action;
use firmware::network::OBS_DIM;
use rand_core::Rng;

/// A FIFO experience buffer of fixed capacity; the oldest transition goes first.
pub struct ReplayBuffer {
    obs: Vec<[f32; OBS_DIM]>,
    next: Vec<[f32; OBS_DIM]>,
    action: Vec<u8>,
    reward: Vec<f32>,
    terminated: Vec<bool>,
    /// Per slot, which push filled it (1 = the first): tells a cache keyed by slot whether
    /// the slot still holds the transition it saw.
    write_ids: Vec<u64>,
    pushes: u64,
    capacity: usize,
    pos: usize,
}

impl ReplayBuffer {
    /// An empty buffer holding at most `capacity` transitions.
    pub fn new(capacity: usize) -> Self {
        ReplayBuffer {
            obs: Vec::with_capacity(capacity),
            next: Vec::with_capacity(capacity),
            action: Vec::with_capacity(capacity),
            reward: Vec::with_capacity(capacity),
            terminated: Vec::with_capacity(capacity),
            write_ids: Vec::with_capacity(capacity),
            pushes: 0,
            capacity,
            pos: 0,
        }
    }

    /// Transitions held.
    pub fn len(&self) -> usize {
        self.obs.len()
    }

    /// Whether nothing is stored yet.
    pub fn is_empty(&self) -> bool {
        self.obs.is_empty()
    }

    /// Stores a transition, overwriting the oldest once full.
    pub fn push(&mut self, obs: [f32; 4], action: Action, reward: f32, next: [f32; 4], term: bool) {
        let a = action.index() as u8;
        self.pushes += 1;
        if self.len() < self.capacity {
            self.obs.push(obs);
            self.next.push(next);
            self.action.push(a);
            self.reward.push(reward);
            self.terminated.push(term);
            self.write_ids.push(self.pushes);
        } else {
            self.obs[self.pos] = obs;
            self.next[self.pos] = next;
            self.action[self.pos] = a;
            self.reward[self.pos] = reward;
            self.terminated[self.pos] = term;
            self.write_ids[self.pos] = self.pushes;
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
        (
            self.obs[i],
            self.action[i],
            self.reward[i],
            self.next[i],
            self.terminated[i],
        )
    }

    /// Which push wrote slot `i`: unique over the buffer's life.
    pub fn write_id(&self, i: usize) -> u64 {
        self.write_ids[i]
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
            b.push(
                [i as f32; 4],
                Action::from_index(i % 2),
                i as f32,
                [0.0; 4],
                i == 4,
            );
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
