//! Policy files: how a trained 4-H-H-2 Q-network travels from a trainer to a board.
//!
//! - [`Weights`]: the six tensors of a network of any supported shape, in PyTorch's layout,
//!   and the duty level each output drives.
//! - [`checkpoint`]: safetensors state dicts as PyTorch users save them (`fc1`/`fc2`/`fc3`,
//!   `nn.Sequential` indices, prefixes such as CleanRL's `network.` or Stable-Baselines3's
//!   `q_net.q_net.`), recognised by their chain of shapes; and the canonical file the trainer
//!   writes.
//! - [`levels`]: the duty levels an imported network drives, recorded in its file or given
//!   for one that records none.
//! - [`quant`]: post-training int8 quantisation for the integer network, and its Rust and C
//!   source.
//! - [`source`]: Rust modules and C headers that compile the weights into flash, bit for bit.
//! - [`files`]: reading only regular files, with a size cap, and writing outputs atomically
//!   without replacing anything that is not a regular file.
//! - [`shape`]: code for a network whose shape is known only at run time.
//! - [`feedback`]: a linear state feedback as a network of any shape, for testing the tools
//!   end to end without a trained policy.
//!
//! Both host tools use this crate: the trainer (`policy-export`) writes and exports policies,
//! the simulator (`host-sim`) loads them. It depends on `firmware` for the network's shape
//! and nothing else of the project. It is not a trainer and not a simulator.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod checkpoint;
pub mod feedback;
pub mod files;
pub mod json;
pub mod levels;
pub mod markdown;
mod numbers;
mod overflow;
pub mod quant;
pub mod shape;
pub mod source;

pub use numbers::{
    hidden_zero, hidden_zero_in_numbers, past_f32, plain, reads_as_zero, whole, zero_in_disguise,
};

use firmware::controller::{Levels, check_levels};
use firmware::network::{Mlp, SUPPORTED_SHAPES, TENSOR_NAMES, shapes};

/// What went wrong with a policy file or an output path.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The input is not what it should be: a missing or malformed file, a wrong shape, a
    /// non-finite value, an ambiguous checkpoint, a bad name. Command lines exit 2 on it.
    #[error("{0}")]
    Input(String),
    /// Reading or writing failed for a reason that is not the input's fault (a full disk).
    #[error("{0}")]
    Io(String),
}

impl Error {
    /// Whether the caller's input caused it (exit status 2) rather than the system (1).
    pub fn is_input(&self) -> bool {
        matches!(self, Error::Input(_))
    }
}

/// Shorthand for this crate's results.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Input text in a message is cut to this many characters (after escaping): enough to
/// recognise, short enough that a hostile input cannot flood the terminal.
pub const QUOTE_MAX: usize = 200;

/// `s` for an error message, in double quotes: at most [`QUOTE_MAX`] characters of it, then
/// `...` after the closing quote; every character that is not printable (control characters,
/// line and paragraph separators, bidirectional and other format characters) and the quote
/// and backslash escaped as Rust writes them (`\u{1b}`, `\n`, `\"`). One line, whatever `s` is.
pub fn quote(s: &str) -> String {
    let (text, cut) = escaped(s, true);
    format!("\"{text}\"{}", if cut { "..." } else { "" })
}

/// Another component's message about an input (a parser's, which may quote the input at
/// length and with its control characters): [`quote`]'s escaping and cut, without the quotes
/// (the message's own quotes stay as they are).
pub fn excerpt(s: &str) -> String {
    let (text, cut) = escaped(s, false);
    if cut { text + "..." } else { text }
}

/// A path as a message shows it: its text with [`excerpt`]'s escaping and cut, so that a
/// file named with a line break or an escape sequence is named on one line that moves no
/// cursor. Every message that names a file names it so.
pub fn shown(path: &std::path::Path) -> String {
    excerpt(&path.to_string_lossy())
}

/// A parser's refusal of `text` (a TOML file's, say) as `line L, column C: MESSAGE`, from
/// the byte range `at` it points to and its own `message` (cut and escaped): the reason comes
/// first, where a parser's display quotes the offending source line before it, and a long
/// line cut to [`QUOTE_MAX`] lost the reason.
pub fn located(text: &str, at: Option<std::ops::Range<usize>>, message: &str) -> String {
    // A parser quotes the offending value inside its reason (`invalid type: string "...",
    // expected f64`): a long one is cut in its middle, so both ends of the reason show.
    let chars: Vec<char> = message.trim().chars().collect();
    let message = if chars.len() > QUOTE_MAX {
        let (head, tail) = (
            &chars[..QUOTE_MAX / 2],
            &chars[chars.len() - QUOTE_MAX / 4..],
        );
        let (head, tail): (String, String) = (head.iter().collect(), tail.iter().collect());
        format!("{} ... {}", excerpt(&head), excerpt(&tail))
    } else {
        excerpt(&chars.iter().collect::<String>())
    };
    let Some(at) = at.filter(|r| text.is_char_boundary(r.start)) else {
        return message;
    };
    let before = &text[..at.start];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    format!("line {line}, column {column}: {message}")
}

/// The escaped beginning of `s`, at most [`QUOTE_MAX`] characters, and whether it was cut.
/// An escape is never split, and only what is shown is read: a 64 MiB name costs as much as a
/// short one.
fn escaped(s: &str, quotes: bool) -> (String, bool) {
    let mut out = String::new();
    let mut shown = 0;
    for c in s.chars() {
        let plain = matches!(c, '\'' | ' ') || (!quotes && matches!(c, '"' | '\\'));
        let esc = c.escape_debug();
        let len = if plain { 1 } else { esc.len() };
        if shown + len > QUOTE_MAX {
            return (out, true);
        }
        shown += len;
        if plain {
            out.push(c);
        } else {
            out.extend(esc);
        }
    }
    (out, false)
}

/// The first `max` of `items` joined by commas, then `and N more` if there are more: a list
/// from an input (tensors, prefixes, nodes) stays a few lines long however long it is.
pub fn few(items: impl IntoIterator<Item = String>, max: usize) -> String {
    let mut items = items.into_iter();
    let shown: Vec<String> = items.by_ref().take(max).collect();
    match items.count() {
        0 => shown.join(", "),
        more => format!("{} and {more} more", shown.join(", ")),
    }
}

/// Refuses a shape (hidden width, outputs) the tools are not built for.
pub fn check_shape(width: usize, outputs: usize) -> Result<()> {
    if SUPPORTED_SHAPES.contains(&(width, outputs)) {
        return Ok(());
    }
    Err(shape::unsupported(width, outputs))
}

/// The paper's two levels, full push left and right: what a two-output network's outputs
/// mean unless its file says otherwise.
pub const BANG_BANG: [f32; 2] = [-1.0, 1.0];

/// The parameters of a 4-H-H-A network as flat row-major tensors in [`TENSOR_NAMES`] order,
/// and the duty level each of its `A` outputs drives.
#[derive(Clone, Debug, PartialEq)]
pub struct Weights {
    /// Hidden width H.
    width: usize,
    /// Each output's duty level, a fraction of the full push ([`check_levels`]).
    levels: Vec<f32>,
    /// `fc1.weight`, `fc1.bias`, `fc2.weight`, `fc2.bias`, `fc3.weight`, `fc3.bias`.
    tensors: [Vec<f32>; 6],
}

impl Weights {
    /// Checked weights: a supported shape (width, one output per level), levels a policy
    /// may choose among, six tensors of the shape's sizes, every value finite.
    pub fn new(width: usize, levels: Vec<f32>, tensors: [Vec<f32>; 6]) -> Result<Weights> {
        check_levels(&levels)
            .map_err(|e| Error::Input(format!("the policy's duty levels {levels:?}: {e}")))?;
        check_shape(width, levels.len())?;
        for ((name, shape), t) in TENSOR_NAMES
            .iter()
            .zip(shapes(width, levels.len()))
            .zip(&tensors)
        {
            if t.len() != shape.len() {
                return Err(Error::Input(format!(
                    "tensor `{name}`: expected {} values for shape {:?}, found {}",
                    shape.len(),
                    shape.dims(),
                    t.len()
                )));
            }
            if let Some(i) = t.iter().position(|v| !v.is_finite()) {
                return Err(Error::Input(format!(
                    "tensor `{name}`: element {i} is {}, expected a finite value",
                    t[i]
                )));
            }
        }
        Ok(Weights {
            width,
            levels,
            tensors,
        })
    }

    /// Copies a network's parameters and its levels (checked like [`Weights::new`]).
    pub fn from_mlp<const H: usize, const A: usize>(
        net: &Mlp<H, A>,
        levels: &Levels<A>,
    ) -> Result<Weights> {
        let tensors = net.tensors().map(<[f32]>::to_vec);
        Weights::new(H, levels.fractions().to_vec(), tensors)
    }

    /// The network, if its shape is `H` x `A`; on the heap (an `Mlp<128>` is 70 KB).
    pub fn to_mlp<const H: usize, const A: usize>(&self) -> Result<Box<Mlp<H, A>>> {
        self.expect_shape(H, A)?;
        let mut net = Box::new(Mlp::<H, A>::zeroed());
        for (dst, src) in net.tensors_mut().into_iter().zip(&self.tensors) {
            dst.copy_from_slice(src);
        }
        Ok(net)
    }

    /// The network's levels, if it has `A` outputs.
    pub fn to_levels<const A: usize>(&self) -> Result<Levels<A>> {
        self.expect_shape(self.width, A)?;
        let fractions: [f32; A] = core::array::from_fn(|i| self.levels[i]);
        Levels::new(fractions).map_err(|e| Error::Input(e.to_string()))
    }

    /// Refuses a policy of another shape than `width` x `outputs`: a file with seven
    /// outputs is never read as a two-level policy.
    pub fn expect_shape(&self, width: usize, outputs: usize) -> Result<()> {
        if (self.width, self.outputs()) == (width, outputs) {
            return Ok(());
        }
        Err(Error::Input(format!(
            "the policy is a network of hidden width {} with {} outputs (levels {:?}), \
             expected width {width} with {outputs}",
            self.width,
            self.outputs(),
            self.levels
        )))
    }

    /// Hidden width H.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Outputs A: one per duty level.
    pub fn outputs(&self) -> usize {
        self.levels.len()
    }

    /// Each output's duty level, a fraction of the full push.
    pub fn levels(&self) -> &[f32] {
        &self.levels
    }

    /// The six tensors, flat and row-major, in [`TENSOR_NAMES`] order.
    pub fn tensors(&self) -> &[Vec<f32>; 6] {
        &self.tensors
    }

    /// Number of parameters.
    pub fn params(&self) -> usize {
        firmware::network::params(self.width, self.outputs())
    }

    /// Checks that the network's Q-values are finite on [`probe_states`]: finite weights can
    /// still overflow f32 on the way (weights of 1e30 do), and a policy whose every output
    /// is infinite or NaN decides nothing.
    pub fn check_outputs(&self) -> Result<()> {
        struct Probe<'a>(&'a Weights);
        impl shape::ForShape for Probe<'_> {
            type Output = Result<()>;
            fn run<const H: usize, const A: usize>(self) -> Result<()> {
                let net = self.0.to_mlp::<H, A>()?;
                for obs in probe_states() {
                    let q = net.forward(&obs);
                    if !q.iter().all(|v| v.is_finite()) {
                        return Err(Error::Input(format!(
                            "expected finite Q-values on the start states and a grid of the \
                             track, found {q:?} at state {obs:?}: the weights overflow f32"
                        )));
                    }
                }
                Ok(())
            }
        }
        shape::by_shape(self.width, self.outputs(), Probe(self))?
    }
}

/// The states a policy is checked on before it is used or exported: the corners of
/// Gymnasium's start box (every variable within 0.05 of zero), and a grid of the track's
/// and the angle's limits and zero with velocities of -2, 0 and 2 (m/s and rad/s).
pub fn probe_states() -> impl Iterator<Item = [f32; 4]> {
    let p = firmware::cartpole::GYMNASIUM;
    let (x, th) = (p.x_threshold as f32, p.theta_threshold_radians as f32);
    let corners =
        (0..16).map(|i: u32| core::array::from_fn(|k| if i >> k & 1 == 1 { 0.05 } else { -0.05 }));
    let grid = (0..81).map(move |i: u32| {
        let level = |k: u32| (i / 3u32.pow(k) % 3) as f32 - 1.0;
        [level(0) * x, level(1) * 2.0, level(2) * th, level(3) * 2.0]
    });
    corners.chain(grid)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn new_checks_width_lengths_and_values() {
        let ok = shapes(16, 2).map(|s| vec![0.5; s.len()]);
        let two = || BANG_BANG.to_vec();
        assert_eq!(Weights::new(16, two(), ok.clone()).unwrap().params(), 386);
        let e = Weights::new(24, two(), ok.clone()).unwrap_err().to_string();
        assert!(e.contains("hidden width 24 with 2 outputs"), "{e}");
        let e = Weights::new(64, vec![-1.0, 0.0, 1.0], ok.clone()).unwrap_err();
        assert!(
            e.to_string()
                .contains("expected 256 values for shape [64, 4]"),
            "{e}"
        );
        let e = Weights::new(16, vec![1.0, -1.0], ok.clone()).unwrap_err();
        assert!(
            e.to_string().contains("expected strictly increasing"),
            "{e}"
        );
        let mut short = ok.clone();
        short[3].pop();
        let e = Weights::new(16, two(), short).unwrap_err().to_string();
        assert!(e.contains("`fc2.bias`: expected 16 values"), "{e}");
        let mut nan = ok;
        nan[4][7] = f32::NAN;
        let e = Weights::new(16, two(), nan).unwrap_err().to_string();
        assert!(e.contains("`fc3.weight`: element 7 is NaN"), "{e}");
    }

    #[test]
    fn a_policy_of_more_outputs_is_never_read_as_a_two_level_one() {
        let five = vec![-1.0, -0.2, 0.0, 0.2, 1.0];
        let t = shapes(64, 5).map(|s| vec![0.25; s.len()]);
        let w = Weights::new(64, five.clone(), t).unwrap();
        let e = w.to_mlp::<64, 2>().unwrap_err().to_string();
        assert!(
            e.contains("hidden width 64 with 5 outputs (levels [-1.0, -0.2, 0.0, 0.2, 1.0])")
                && e.contains("expected width 64 with 2"),
            "{e}"
        );
        assert!(w.to_levels::<2>().is_err() && w.to_levels::<7>().is_err());
        let levels = w.to_levels::<5>().unwrap();
        assert_eq!(levels.fractions().to_vec(), five);
        // Every parameter 0.25, the reading 0: each first-layer unit is its bias, 0.25; each
        // second 0.25 + 64 * 0.25 * 0.25 = 4.25; each output 0.25 + 64 * 0.25 * 4.25, exact.
        let q = w.to_mlp::<64, 5>().unwrap().forward(&[0.0; 4]);
        assert_eq!(q, [68.25; 5]);
    }

    #[test]
    fn outputs_that_overflow_are_refused() {
        let ok = shapes(16, 2).map(|s| vec![0.5; s.len()]);
        Weights::new(16, BANG_BANG.to_vec(), ok.clone())
            .unwrap()
            .check_outputs()
            .unwrap();
        // Each weight is finite; the first layer's outputs (about 1e38 at the track's end)
        // overflow in the second.
        let mut huge = ok;
        huge[0].fill(1e38);
        huge[2].fill(1e38);
        let w = Weights::new(16, BANG_BANG.to_vec(), huge).unwrap();
        let e = w.check_outputs().unwrap_err();
        assert!(
            e.is_input() && e.to_string().contains("expected finite Q-values"),
            "{e}"
        );
        assert_eq!(probe_states().count(), 97);
    }

    #[test]
    fn a_parsers_refusal_is_located_with_its_reason_first() {
        let text = "a = 1\nbé = \"xx\"\n";
        let at = text.find('"').unwrap();
        assert_eq!(
            located(
                text,
                Some(at..at + 4),
                " invalid type: string \"xx\", expected f64\n"
            ),
            "line 2, column 6: invalid type: string \"xx\", expected f64"
        );
        assert_eq!(located(text, None, "\u{1b}[2J"), "\\u{1b}[2J");
        // A range inside a character is not a place; the message stays.
        assert_eq!(located("é", Some(1..2), "m"), "m");
        let long = format!(
            "invalid type: string \"{}\", expected f64",
            "x".repeat(5000)
        );
        let m = located("", None, &long);
        assert!(m.starts_with("invalid type: string \"xx") && m.ends_with("x\", expected f64"));
        assert!(m.len() < 2 * QUOTE_MAX, "{m}");
    }

    #[test]
    fn quotes_are_cut_and_escaped() {
        assert_eq!(quote("ab"), "\"ab\"");
        assert_eq!(quote("a\"b\\c 'd'"), r#""a\"b\\c 'd'""#);
        assert_eq!(excerpt("a\"b\\c"), "a\"b\\c");
        // ESC, BEL, a newline, DEL, a C1 control, the bidirectional override and the line
        // separator: each an escape, none raw.
        let hostile = "\u{1b}[2J\u{7}x\n\u{7f}\u{85}\u{202e}\u{2028}";
        let want = r"\u{1b}[2J\u{7}x\n\u{7f}\u{85}\u{202e}\u{2028}";
        assert_eq!(quote(hostile), format!("\"{want}\""));
        assert_eq!(excerpt(hostile), want);
        let long = "x".repeat(10_000);
        assert_eq!(quote(&long), format!("\"{}\"...", "x".repeat(QUOTE_MAX)));
        assert_eq!(excerpt(&long), "x".repeat(QUOTE_MAX) + "...");
        // Multi-byte characters are cut between characters, counted as characters.
        let wide = "é€😀".repeat(100);
        let q = excerpt(&wide);
        assert_eq!(q.chars().count(), QUOTE_MAX + 3);
        assert!(wide.starts_with(q.trim_end_matches("...")), "{q}");
        // An escape is kept whole or left out: 199 characters, then ESC (6 as an escape).
        let edge = "y".repeat(QUOTE_MAX - 1) + "\u{1b}";
        assert_eq!(excerpt(&edge), "y".repeat(QUOTE_MAX - 1) + "...");
        let fits = "y".repeat(QUOTE_MAX - 6) + "\u{1b}";
        assert_eq!(excerpt(&fits), "y".repeat(QUOTE_MAX - 6) + r"\u{1b}");
        // Every output is one line of printable characters.
        for s in [hostile, &long, &wide, "\0\r\t"] {
            assert!(!quote(s).chars().any(|c| c.is_control()), "{s:?}");
        }
        // A path likewise; a name that is not UTF-8 shows the replacement character.
        let path = std::path::Path::new("dir").join(hostile);
        assert_eq!(shown(&path), format!("dir/{want}"));
        assert_eq!(shown(std::path::Path::new(&long)), excerpt(&long));
        use std::os::unix::ffi::OsStrExt;
        let bytes = std::ffi::OsStr::from_bytes(b"a\xff\x1b");
        assert_eq!(shown(std::path::Path::new(bytes)), "a\u{fffd}\\u{1b}");
    }

    #[test]
    fn lists_name_a_few_and_count_the_rest() {
        let items = |n: usize| {
            (0..n)
                .map(|i| i.to_string())
                .collect::<Vec<_>>()
                .into_iter()
        };
        assert_eq!(few(items(0), 3), "");
        assert_eq!(few(items(3), 3), "0, 1, 2");
        assert_eq!(few(items(250_000), 3), "0, 1, 2 and 249997 more");
    }
}
