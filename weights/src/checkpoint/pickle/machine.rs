//! The pickle machine: a stack, marks on it and the memo, run one opcode at a time.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::rc::Rc;

use super::{MAX_OPS, Value, dismantle, global, persistent, reduce, refuse};
use crate::{Error, Result, quote};

/// The bytes of one pickle, read forwards.
pub(super) struct Ops<'a> {
    pub(super) bytes: &'a [u8],
    pub(super) pos: usize,
}

impl<'a> Ops<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8]> {
        match self.bytes.get(self.pos..self.pos.saturating_add(n)) {
            Some(s) if self.pos.checked_add(n).is_some() => {
                self.pos += n;
                Ok(s)
            }
            _ => refuse(format!(
                "ends inside an opcode's argument at byte {} (wanted {n} more bytes)",
                self.pos
            )),
        }
    }
    fn u8(&mut self) -> Result<u8> {
        Ok(self.take(1)?[0])
    }
    fn u16(&mut self) -> Result<u16> {
        Ok(u16::from_le_bytes(
            self.take(2)?.try_into().expect("2 bytes"),
        ))
    }
    fn u32(&mut self) -> Result<u32> {
        Ok(u32::from_le_bytes(
            self.take(4)?.try_into().expect("4 bytes"),
        ))
    }
    fn u64(&mut self) -> Result<u64> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().expect("8 bytes"),
        ))
    }
    fn text(&mut self, n: u64) -> Result<&'a str> {
        let n = usize::try_from(n).unwrap_or(usize::MAX);
        let at = self.pos;
        std::str::from_utf8(self.take(n)?)
            .or_else(|_| refuse(format!("a string at byte {at} is not UTF-8")))
    }
    /// A text line (GLOBAL's module and name), without its newline.
    fn line(&mut self) -> Result<&'a str> {
        let rest = &self.bytes[self.pos..];
        let Some(end) = rest.iter().position(|&b| b == b'\n') else {
            return refuse("a GLOBAL's name has no end of line".into());
        };
        let s = self.text(end as u64)?;
        self.pos += 1;
        Ok(s)
    }
}

/// The machine: a stack, marks on it, and the memo.
#[derive(Default)]
pub(super) struct Machine<'a> {
    stack: Vec<Rc<Value<'a>>>,
    memo: BTreeMap<u64, Rc<Value<'a>>>,
}

impl<'a> Machine<'a> {
    pub(super) fn pop(&mut self) -> Result<Rc<Value<'a>>> {
        match self.stack.pop() {
            Some(v) if !matches!(*v, Value::Mark) => Ok(v),
            _ => refuse("an opcode needs a value the stack does not have".into()),
        }
    }
    fn top(&self) -> Result<&Rc<Value<'a>>> {
        match self.stack.last() {
            Some(v) if !matches!(**v, Value::Mark) => Ok(v),
            _ => refuse("an opcode needs a value the stack does not have".into()),
        }
    }
    /// The values above the topmost mark, which is removed.
    fn pop_mark(&mut self) -> Result<Vec<Rc<Value<'a>>>> {
        let Some(m) = self.stack.iter().rposition(|v| matches!(**v, Value::Mark)) else {
            return refuse("an opcode needs a MARK the stack does not have".into());
        };
        let items = self.stack.split_off(m + 1);
        self.stack.pop();
        Ok(items)
    }
    fn push(&mut self, v: Value<'a>) {
        self.stack.push(Rc::new(v));
    }
    fn memo_get(&mut self, k: u64) -> Result<()> {
        match self.memo.get(&k) {
            Some(v) => {
                self.stack.push(v.clone());
                Ok(())
            }
            None => refuse(format!("memo entry {k} is read before it is written")),
        }
    }
    fn memo_put(&mut self, k: u64) -> Result<()> {
        let v = self.top()?.clone();
        self.memo.insert(k, v);
        Ok(())
    }
    /// Adds key-value pairs to the dict below them (SETITEM, SETITEMS).
    fn set_items(&mut self, items: Vec<Rc<Value<'a>>>) -> Result<()> {
        if !items.len().is_multiple_of(2) {
            return refuse("SETITEMS has a key without a value".into());
        }
        let Value::Dict(entries) = &**self.top()? else {
            return refuse("SETITEM on something that is not a dict".into());
        };
        entries.borrow_mut().extend(
            items
                .chunks_exact(2)
                .map(|kv| (kv[0].clone(), kv[1].clone())),
        );
        Ok(())
    }
}

impl Drop for Machine<'_> {
    fn drop(&mut self) {
        let mut all = std::mem::take(&mut self.stack);
        all.extend(std::mem::take(&mut self.memo).into_values());
        dismantle(all);
    }
}

/// Runs the opcodes up to STOP and returns what is left on the stack.
pub(super) fn run(bytes: &[u8]) -> Result<Rc<Value<'_>>> {
    let mut ops = Ops { bytes, pos: 0 };
    let mut m = Machine::default();
    for _ in 0..MAX_OPS {
        let at = ops.pos;
        let op = ops.u8()?;
        if op == b'.' {
            let top = m.pop()?;
            return match m.stack.is_empty() {
                true => Ok(top),
                false => refuse(format!(
                    "{} values left on the stack at STOP",
                    m.stack.len()
                )),
            };
        }
        step(op, &mut ops, &mut m).map_err(|e| match e {
            Error::Input(msg) => Error::Input(format!("{msg} (opcode 0x{op:02x} at byte {at})")),
            other => other,
        })?;
    }
    refuse(format!("no STOP within {MAX_OPS} opcodes"))
}

/// One opcode other than STOP.
fn step<'a>(op: u8, ops: &mut Ops<'a>, m: &mut Machine<'a>) -> Result<()> {
    if literal(op, ops, m)? || memo(op, ops, m)? || named(op, ops, m)? {
        return Ok(());
    }
    match op {
        0x80 => match ops.u8()? {
            2..=5 => {}
            v => return refuse(format!("protocol {v}, expected 2 to 5")),
        },
        0x95 => drop(ops.u64()?), // FRAME: a length hint
        b't' => {
            let items = m.pop_mark()?;
            m.push(Value::tuple(items));
        }
        0x85..=0x87 => {
            let n = usize::from(op - 0x84);
            let at = m.stack.len().checked_sub(n);
            let items = match at {
                Some(at) if m.stack[at..].iter().all(|v| !matches!(**v, Value::Mark)) => {
                    m.stack.split_off(at)
                }
                _ => return refuse("TUPLE1-3 without enough values".into()),
            };
            m.push(Value::tuple(items));
        }
        b'a' | b'e' => {
            let items = if op == b'a' {
                vec![m.pop()?]
            } else {
                m.pop_mark()?
            };
            let Value::List(list) = &**m.top()? else {
                return refuse("APPEND on something that is not a list".into());
            };
            list.borrow_mut().extend(items);
        }
        b's' => {
            let v = m.pop()?;
            let k = m.pop()?;
            m.set_items(vec![k, v])?;
        }
        b'u' => {
            let items = m.pop_mark()?;
            m.set_items(items)?;
        }
        b'Q' => {
            let pid = m.pop()?;
            m.push(persistent(&pid)?);
        }
        b'R' => {
            let args = m.pop()?;
            let f = m.pop()?;
            m.push(reduce(&f, &args)?);
        }
        b'b' => {
            // An OrderedDict's instance state (`_metadata`, module versions): kept by
            // PyTorch for loading into a module, not part of the tensors.
            m.pop()?;
            if !matches!(**m.top()?, Value::Dict(_)) {
                return refuse("BUILD on something other than an OrderedDict".into());
            }
        }
        other => {
            return refuse(format!(
                "opcode 0x{other:02x} ({}) is not one a state dict uses",
                quote(&char::from(other).to_string())
            ));
        }
    }
    Ok(())
}

/// Puts the top of the stack in the memo, or pushes a memo entry, if `op` says so; says
/// whether it did.
fn memo<'a>(op: u8, ops: &mut Ops<'a>, m: &mut Machine<'a>) -> Result<bool> {
    match op {
        b'q' => m.memo_put(u64::from(ops.u8()?))?,
        b'r' => m.memo_put(u64::from(ops.u32()?))?,
        0x94 => m.memo_put(m.memo.len() as u64)?,
        b'h' => m.memo_get(u64::from(ops.u8()?))?,
        b'j' => m.memo_get(u64::from(ops.u32()?))?,
        _ => return Ok(false),
    }
    Ok(true)
}

/// Pushes the global that GLOBAL or STACK_GLOBAL names, if `op` is one; says whether it
/// was.
fn named<'a>(op: u8, ops: &mut Ops<'a>, m: &mut Machine<'a>) -> Result<bool> {
    let (module, name) = match op {
        b'c' => (ops.line()?, ops.line()?),
        0x93 => {
            let name = m.pop()?;
            let module = m.pop()?;
            let (&Value::Str(module), &Value::Str(name)) = (&*module, &*name) else {
                return refuse("STACK_GLOBAL needs two strings".into());
            };
            (module, name)
        }
        _ => return Ok(false),
    };
    m.push(Value::Global(global(module, name)?));
    Ok(true)
}

/// Pushes a literal (a mark, None, a bool, an int, a string, an empty container) if `op`
/// is one; says whether it was.
fn literal<'a>(op: u8, ops: &mut Ops<'a>, m: &mut Machine<'a>) -> Result<bool> {
    match op {
        b'(' => m.push(Value::Mark),
        b'N' => m.push(Value::None),
        0x88 | 0x89 => m.push(Value::Bool),
        b'J' => m.push(Value::Int(i64::from(ops.u32()? as i32))),
        b'K' => m.push(Value::Int(i64::from(ops.u8()?))),
        b'M' => m.push(Value::Int(i64::from(ops.u16()?))),
        0x8a => long1(ops, m)?,
        b'X' => {
            let n = ops.u32()?;
            let s = ops.text(u64::from(n))?;
            m.push(Value::Str(s));
        }
        0x8c => {
            let n = ops.u8()?;
            let s = ops.text(u64::from(n))?;
            m.push(Value::Str(s));
        }
        b')' => m.push(Value::tuple(vec![])),
        b']' => m.push(Value::List(RefCell::default())),
        b'}' => m.push(Value::Dict(RefCell::default())),
        _ => return Ok(false),
    }
    Ok(true)
}

pub(super) fn long1<'a>(ops: &mut Ops<'a>, m: &mut Machine<'a>) -> Result<()> {
    let n = usize::from(ops.u8()?);
    let b = ops.take(n)?;
    if n > 8 {
        return refuse(format!("an integer of {n} bytes, expected at most 8"));
    }
    // Two's complement, little-endian, sign-extended from its last byte.
    let fill = if b.last().is_some_and(|&x| x >= 0x80) {
        0xff
    } else {
        0
    };
    let mut le = [fill; 8];
    le[..n].copy_from_slice(b);
    m.push(Value::Int(i64::from_le_bytes(le)));
    Ok(())
}
