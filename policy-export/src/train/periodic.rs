//! The periodic evaluations of a run, each while the learner goes on with its next episodes
//! where the run has a second core.
//!
//! An evaluation takes a snapshot of the weights and draws from its own streams, so the
//! episodes that follow it do not depend on its result; only whether the run stops there
//! does. The learner therefore need not wait for it: it learns on while the snapshot is
//! evaluated, and when the result says stop, the run is cut back to where the snapshot was
//! taken ([`Mark`]), the episodes learnt meanwhile dropped. The run's records, snapshots and
//! policy are the same bits as when every evaluation is waited for, which a run inside a
//! thread pool's worker (seeds side by side) still does: a worker that waits for an
//! evaluation needing the pool's threads could wait for ever.

use std::thread::{Scope, ScopedJoinHandle};

use firmware::network::Mlp;

use super::select::Selection;
use crate::config::Config;

/// Where a run stood when a snapshot was taken: what it is cut back to if the snapshot's
/// evaluation stops it.
#[derive(Clone, Copy, Debug)]
pub(super) struct Mark {
    /// Episodes run (the snapshot was taken after the last of them).
    pub episodes: usize,
    pub env_steps: u64,
    pub grad_steps: u64,
}

type Pending<'scope, 'a, const H: usize, const A: usize> =
    (ScopedJoinHandle<'scope, (Selection<'a, H, A>, bool)>, Mark);

/// The selection and the evaluation under way, if any.
pub(super) struct Periodic<'scope, 'env, 'a, const H: usize, const A: usize> {
    cfg: &'a Config,
    /// Where evaluations run beside the learner; `None`: each in its turn, waited for.
    scope: Option<&'scope Scope<'scope, 'env>>,
    /// The selection, while no evaluation holds it.
    selection: Option<Selection<'a, H, A>>,
    pending: Option<Pending<'scope, 'a, H, A>>,
    /// Periodic evaluations in a row that were perfect.
    settled: usize,
}

impl<'scope, 'env, 'a: 'scope, const H: usize, const A: usize> Periodic<'scope, 'env, 'a, H, A> {
    pub fn new(
        cfg: &'a Config,
        selection: Selection<'a, H, A>,
        scope: Option<&'scope Scope<'scope, 'env>>,
    ) -> Self {
        Periodic {
            cfg,
            scope,
            selection: Some(selection),
            pending: None,
            settled: 0,
        }
    }

    /// The episodes no evaluation under way can drop: those up to its mark, or all of
    /// `run` when none is under way.
    pub fn kept(&self, run: usize) -> usize {
        self.pending.as_ref().map_or(run, |(_, mark)| mark.episodes)
    }

    /// Evaluates `net`, the weights at `mark`, after waiting for the evaluation under way;
    /// the mark the run stops at if either says stop (the earlier one's, if it does).
    pub fn submit(&mut self, net: Box<Mlp<H, A>>, mark: Mark) -> Option<Mark> {
        if let Some(stop) = self.settle() {
            return Some(stop);
        }
        let mut selection = (self.selection.take())
            .expect("the selection is back once the evaluation under way is settled");
        match self.scope {
            Some(scope) => {
                let run = move || {
                    let perfect = selection.periodic(net, mark.episodes);
                    (selection, perfect)
                };
                self.pending = Some((scope.spawn(run), mark));
                None
            }
            None => {
                let perfect = selection.periodic(net, mark.episodes);
                self.selection = Some(selection);
                self.stops(perfect).then_some(mark)
            }
        }
    }

    /// Waits for the evaluation under way, if any; its mark if it says stop.
    pub fn settle(&mut self) -> Option<Mark> {
        let (handle, mark) = self.pending.take()?;
        let (selection, perfect) = handle
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        self.selection = Some(selection);
        self.stops(perfect).then_some(mark)
    }

    /// The selection; the caller has settled the last evaluation.
    pub fn into_selection(self) -> Selection<'a, H, A> {
        (self.selection).expect("the last evaluation is settled before the selection is taken")
    }

    /// Whether the run stops after an evaluation that was `perfect` or not: perfect and
    /// asked to stop then, no better snapshot for `patience` evaluations, or `settle`
    /// perfect ones in a row.
    fn stops(&mut self, perfect: bool) -> bool {
        let cfg = self.cfg;
        self.settled = if perfect { self.settled + 1 } else { 0 };
        let stale = self.selection.as_ref().map_or(0, Selection::stale);
        (perfect && cfg.stop_when_perfect)
            || (cfg.patience > 0 && stale >= cfg.patience)
            || (cfg.settle > 0 && self.settled >= cfg.settle)
    }
}
