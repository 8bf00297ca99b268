//! A second core for the shares of each update: a helper thread that takes one share while
//! the learner computes the other.
//!
//! An update's shares take tens of microseconds each and come one update after another, a
//! few microseconds apart: waking a sleeping thread for each (a thread pool's `join`) costs
//! more than the share saves. The helper spins for its next share instead, and parks once
//! none has come for a while (an evaluation, the end of an episode), so an idle helper costs
//! nothing. A share the helper has not yet taken when the learner finishes its own is taken
//! back and run by the learner: on a machine busy with other work the helper may wait
//! milliseconds for a core, and the update must not wait with it. No share's arithmetic
//! depends on which thread runs it.
#![allow(unsafe_code)]

use std::panic::{AssertUnwindSafe, catch_unwind, resume_unwind};
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

/// How long the helper spins for its next half before it parks.
const SPIN: Duration = Duration::from_micros(200);

const IDLE: u8 = 0;
const POSTED: u8 = 1;
const DONE: u8 = 2;
const EXIT: u8 = 3;
/// The helper has taken the posted job and is running it.
const TAKEN: u8 = 4;

type Job = Box<dyn FnOnce() + Send + 'static>;

struct Shared {
    state: AtomicU8,
    job: Mutex<Option<Job>>,
    /// The job's panic, handed back to the caller.
    panic: Mutex<Option<Box<dyn std::any::Any + Send>>>,
}

/// The helper thread; it exits when this is dropped.
pub(super) struct Pair {
    shared: Arc<Shared>,
    thread: Option<JoinHandle<()>>,
}

impl Pair {
    /// A helper thread, waiting.
    pub fn new() -> Pair {
        let shared = Arc::new(Shared {
            state: AtomicU8::new(IDLE),
            job: Mutex::new(None),
            panic: Mutex::new(None),
        });
        let s = Arc::clone(&shared);
        let thread = thread::Builder::new()
            .name("learner-half".into())
            .spawn(move || serve(&s))
            .expect("spawning the learner's helper thread");
        Pair {
            shared,
            thread: Some(thread),
        }
    }

    /// Runs `b` on the helper while this thread runs `a`; both results, once both ran.
    pub fn join<A, B: Send>(&self, a: impl FnOnce() -> A, b: impl FnOnce() -> B + Send) -> (A, B) {
        let mut out: Option<B> = None;
        let slot = &mut out;
        let job: Box<dyn FnOnce() + Send + '_> = Box::new(move || *slot = Some(b()));
        // SAFETY: the job borrows from this call's frame (`b`'s captures and `out`). Either
        // this thread takes it back before the helper takes it and runs it here, or the
        // helper runs it and sets DONE before anything else; in that case this function does
        // not return, even by unwinding from `a`, until it has seen DONE. Either way every
        // borrow outlives the job's use of it.
        let job: Job = unsafe { std::mem::transmute::<Box<dyn FnOnce() + Send + '_>, Job>(job) };
        *self
            .shared
            .job
            .lock()
            .expect("the helper never panics holding the lock") = Some(job);
        self.shared.state.store(POSTED, Ordering::Release);
        if let Some(t) = &self.thread {
            t.thread().unpark();
        }
        let ra = catch_unwind(AssertUnwindSafe(a));
        let reclaimed = self
            .shared
            .state
            .compare_exchange(POSTED, IDLE, Ordering::AcqRel, Ordering::Acquire)
            .is_ok();
        if reclaimed {
            let job = self.shared.job.lock().expect("not poisoned").take();
            if let Some(job) = job
                && let Err(p) = catch_unwind(AssertUnwindSafe(job))
            {
                *self.shared.panic.lock().expect("not poisoned") = Some(p);
            }
        } else {
            let mut spins = 0u32;
            while self.shared.state.load(Ordering::Acquire) != DONE {
                pause(&mut spins);
            }
            self.shared.state.store(IDLE, Ordering::Relaxed);
        }
        let panicked = self.shared.panic.lock().expect("not poisoned").take();
        if let Some(p) = panicked {
            resume_unwind(p);
        }
        match ra {
            Ok(ra) => (ra, out.expect("the helper ran the job")),
            Err(p) => resume_unwind(p),
        }
    }
}

impl Drop for Pair {
    fn drop(&mut self) {
        self.shared.state.store(EXIT, Ordering::Release);
        if let Some(t) = self.thread.take() {
            t.thread().unpark();
            let _ = t.join();
        }
    }
}

/// Spins a while, then yields its core at every call: where the other thread has a core of
/// its own it answers within the spins, and where it waits for one (the machine busy with
/// other work) a spinning thread would hold the core it waits for.
#[inline]
fn pause(spins: &mut u32) {
    *spins = spins.wrapping_add(1);
    if *spins < 4096 {
        std::hint::spin_loop();
    } else {
        thread::yield_now();
    }
}

/// The helper's loop: spin for a posted job, run it, report; park when none comes.
fn serve(s: &Shared) {
    loop {
        let since = Instant::now();
        let mut spins = 0u32;
        loop {
            match s.state.load(Ordering::Acquire) {
                POSTED => {
                    let take = (s.state).compare_exchange(
                        POSTED,
                        TAKEN,
                        Ordering::AcqRel,
                        Ordering::Acquire,
                    );
                    if take.is_ok() {
                        break;
                    }
                }
                EXIT => return,
                _ => {
                    // The clock is read now and then: reading it is slower than a spin.
                    if spins.is_multiple_of(1024) && since.elapsed() > SPIN {
                        thread::park_timeout(Duration::from_millis(50));
                    } else {
                        pause(&mut spins);
                    }
                }
            }
        }
        let job = s.job.lock().expect("not poisoned").take();
        if let Some(job) = job
            && let Err(p) = catch_unwind(AssertUnwindSafe(job))
        {
            *s.panic.lock().expect("not poisoned") = Some(p);
        }
        s.state.store(DONE, Ordering::Release);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_sides_run_and_borrow_from_the_caller() {
        let pair = Pair::new();
        let data: Vec<u64> = (0..1000).collect();
        for k in 0..200u64 {
            let (a, b) = pair.join(
                || data[..500].iter().sum::<u64>() + k,
                || data[500..].iter().sum::<u64>() * k,
            );
            assert_eq!((a, b), (124_750 + k, 374_750 * k));
        }
    }

    /// A helper that never takes its job (a core it waits for, here no thread at all): the
    /// caller takes the job back and runs it itself.
    #[test]
    fn a_job_the_helper_has_not_taken_is_taken_back() {
        let idle = Pair {
            shared: Arc::new(Shared {
                state: AtomicU8::new(IDLE),
                job: Mutex::new(None),
                panic: Mutex::new(None),
            }),
            thread: None,
        };
        let me = thread::current().id();
        for k in 0..20u64 {
            let (a, (b, on)) = idle.join(|| k, || (k * 2, thread::current().id()));
            assert_eq!((a, b, on), (k, 2 * k, me));
        }
        let r = catch_unwind(AssertUnwindSafe(|| idle.join(|| 1, || panic!("share"))));
        assert!(r.is_err());
    }

    #[test]
    fn a_panic_on_the_helper_reaches_the_caller_and_the_helper_goes_on() {
        let pair = Pair::new();
        let r = catch_unwind(AssertUnwindSafe(|| pair.join(|| 1, || panic!("half"))));
        assert!(r.is_err());
        assert_eq!(pair.join(|| 2, || 3), (2, 3));
    }
}
