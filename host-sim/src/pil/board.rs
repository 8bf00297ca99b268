//! What a target's application holds: one of the shipped policies behind the link
//! (`shipped::target`, `shipped::desk_target`), and the same here as the reference.

use std::fmt;

use clap::ValueEnum;
use firmware::rig::Rig;

use super::link::{Local, Remote};

/// A shipped policy a `pil` application is built with.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum)]
pub enum Board {
    /// The shipped policy, two levels, with its envelope: the `pil` application.
    #[default]
    Shipped,
    /// The nine-level desk policy on the desk rig, without an envelope: `pil-desk`.
    Desk,
}

impl Board {
    /// The `selftest-app` binary that holds it.
    pub fn app(self) -> &'static str {
        match self {
            Board::Shipped => "pil",
            Board::Desk => "pil-desk",
        }
    }

    /// The rig it was built for, with the dead time it was built with.
    pub fn rig(self) -> Rig {
        match self {
            Board::Shipped => *shipped::target(1).rig(),
            Board::Desk => *shipped::desk_target(1).rig(),
        }
    }

    /// Whether its policy has levels between its ends, which a refined controller moves
    /// between (more than two outputs).
    pub fn refines(self) -> bool {
        match self {
            Board::Shipped => shipped::target(1).refines(),
            Board::Desk => shipped::desk_target(1).refines(),
        }
    }

    /// Whether it holds an envelope, for the runtime monitor.
    pub fn monitors(self) -> bool {
        match self {
            Board::Shipped => shipped::target(1).monitors(),
            Board::Desk => shipped::desk_target(1).monitors(),
        }
    }

    /// The same target in this process: the software-in-the-loop reference.
    pub fn reference(self) -> Box<dyn Remote> {
        match self {
            Board::Shipped => Box::new(Local(shipped::target(1))),
            Board::Desk => Box::new(Local(shipped::desk_target(1))),
        }
    }
}

/// The name `--pil-policy` gives it.
impl fmt::Display for Board {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.to_possible_value() {
            Some(v) => f.write_str(v.get_name()),
            None => Ok(()),
        }
    }
}
