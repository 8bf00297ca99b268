//! A restricted reader of the pickle that `torch.save(state_dict)` writes (`data.pkl` in
//! PyTorch's zip): an `OrderedDict` of names to tensors, each rebuilt by
//! `torch._utils._rebuild_tensor_v2` from a storage the pickle names by a persistent id.
//!
//! Pickle is a program for a stack machine whose `GLOBAL` opcode imports any Python callable
//! and whose `REDUCE` calls it, so a general unpickler runs whatever the file asks. This one
//! runs nothing: it knows the opcodes a state dict uses (protocols 2 to 5) and four kinds of
//! global, `collections.OrderedDict`, `torch._utils._rebuild_tensor_v2`, `_rebuild_parameter`
//! (a dict of parameters) and the storage classes (floats for the network; integers and
//! booleans for buffers beside it, refused only if the network needs them), and refuses
//! every other opcode and global by name before reading further.
//!
//! Nothing the file names more than once is copied more than once: values are shared (`Rc`),
//! strings are borrowed from the pickle's bytes, and a tuple of integers (a shape) is
//! converted once however many tensors use it. With at most [`MAX_OPS`] opcodes, each
//! pushing one value of a fixed size, the machine's memory is bounded by a constant, and so
//! is its work: no opcode takes time beyond what it pushes or pops, but for marks (which
//! scan what they then pop).

mod machine;

use std::cell::{OnceCell, RefCell};
use std::rc::Rc;

use super::state_dict::Dtype;
use crate::{Error, Result, quote};

/// Opcodes read before the pickle must have ended: a state dict of six tensors takes ~150.
pub const MAX_OPS: usize = 1 << 16;

/// A tensor as the pickle describes it: which storage, and where in it.
#[derive(Clone, Debug, PartialEq)]
pub struct TensorRef<'a> {
    /// The storage's key: its file is `data/<key>` in the zip.
    pub key: &'a str,
    /// The storage's element type.
    pub dtype: Element,
    /// Elements in the storage.
    pub numel: u64,
    /// First element of the tensor in the storage.
    pub offset: u64,
    /// The tensor's shape, shared with every tensor of the same shape tuple.
    pub shape: Rc<[usize]>,
    /// Elements to step per index, per dimension, shared likewise.
    pub stride: Rc<[usize]>,
}

/// A storage's element type: a float the network may be stored in, or another one PyTorch
/// stores (an integer buffer such as a batch norm's count, a mask) by its name and size, read
/// so that a tensor of it is refused only if the network needs it.
pub type Element = std::result::Result<Dtype, (&'static str, usize)>;

/// The callables a state dict's pickle may name.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Global {
    OrderedDict,
    RebuildTensor,
    RebuildParameter,
    Storage(Element),
}

#[derive(Debug)]
enum Value<'a> {
    None,
    Bool,
    Int(i64),
    Str(&'a str),
    // Its items as non-negative integers, converted the first time a tensor asks.
    Tuple(Vec<Rc<Value<'a>>>, OnceCell<Option<Rc<[usize]>>>),
    // Mutable in place, as in Python: the memo shares a dict with the stack while SETITEMS
    // fills it.
    List(RefCell<Vec<Rc<Value<'a>>>>),
    Dict(RefCell<Vec<(Rc<Value<'a>>, Rc<Value<'a>>)>>),
    Global(Global),
    Storage {
        key: &'a str,
        dtype: Element,
        numel: u64,
    },
    Tensor(Box<TensorRef<'a>>),
    Mark,
}

impl<'a> Value<'a> {
    fn tuple(items: Vec<Rc<Value<'a>>>) -> Value<'a> {
        Value::Tuple(items, OnceCell::new())
    }
}

fn refuse<T>(why: String) -> Result<T> {
    Err(Error::Input(format!("PyTorch pickle: {why}")))
}

fn global(module: &str, name: &str) -> Result<Global> {
    Ok(match (module, name) {
        ("collections", "OrderedDict") => Global::OrderedDict,
        ("torch._utils", "_rebuild_tensor_v2") => Global::RebuildTensor,
        // A dict of parameters (`dict(module.named_parameters())`) wraps each tensor.
        ("torch._utils", "_rebuild_parameter") => Global::RebuildParameter,
        ("torch", "FloatStorage") => Global::Storage(Ok(Dtype::F32)),
        ("torch", "DoubleStorage") => Global::Storage(Ok(Dtype::F64)),
        ("torch", "HalfStorage") => Global::Storage(Ok(Dtype::F16)),
        ("torch", "BFloat16Storage") => Global::Storage(Ok(Dtype::BF16)),
        ("torch", "LongStorage") => Global::Storage(Err(("I64", 8))),
        ("torch", "IntStorage") => Global::Storage(Err(("I32", 4))),
        ("torch", "ShortStorage") => Global::Storage(Err(("I16", 2))),
        ("torch", "CharStorage") => Global::Storage(Err(("I8", 1))),
        ("torch", "ByteStorage") => Global::Storage(Err(("U8", 1))),
        ("torch", "BoolStorage") => Global::Storage(Err(("BOOL", 1))),
        _ => {
            return refuse(format!(
                "refused global {}: a state dict uses only collections.OrderedDict, \
                 torch._utils._rebuild_tensor_v2 and _rebuild_parameter and torch's \
                 storages, and nothing in the file is run",
                quote(&format!("{module}.{name}"))
            ));
        }
    })
}

/// Drops values one container at a time: a pickle can nest tuples as deep as it has
/// opcodes, and the recursive drop of such a chain would overflow the stack.
fn dismantle(mut work: Vec<Rc<Value>>) {
    while let Some(v) = work.pop() {
        match Rc::try_unwrap(v) {
            Ok(Value::Tuple(items, _)) => work.extend(items),
            Ok(Value::List(items)) => work.extend(items.into_inner()),
            Ok(Value::Dict(entries)) => {
                work.extend(entries.into_inner().into_iter().flat_map(|(k, v)| [k, v]));
            }
            // A leaf, or a value still held elsewhere in `work`.
            Ok(_) | Err(_) => {}
        }
    }
}

/// Reads `bytes` as a state dict's pickle: tensor names in the file's order, each with the
/// storage it views; names and keys are borrowed from `bytes`.
pub fn state_dict(bytes: &[u8]) -> Result<Vec<(&str, TensorRef<'_>)>> {
    let top = machine::run(bytes)?;
    let found = tensors(&top);
    dismantle(vec![top]);
    found
}

fn tensors<'a>(top: &Value<'a>) -> Result<Vec<(&'a str, TensorRef<'a>)>> {
    let Value::Dict(entries) = top else {
        return refuse(format!(
            "expected a state dict (a dict of names to tensors), found {}",
            kind(top)
        ));
    };
    entries
        .borrow()
        .iter()
        .map(|(k, v)| match (&**k, &**v) {
            (Value::Str(k), Value::Tensor(t)) => Ok((*k, (**t).clone())),
            (Value::Str(k), other) => refuse(format!(
                "expected a state dict of tensors, found {} under key {} (a training \
                 checkpoint? save the module's state_dict() alone)",
                kind(other),
                quote(k)
            )),
            (other, _) => refuse(format!(
                "expected a state dict's names to be strings, found {}",
                kind(other)
            )),
        })
        .collect()
}

fn kind(v: &Value) -> &'static str {
    match v {
        Value::None => "None",
        Value::Bool => "a bool",
        Value::Int(_) => "an int",
        Value::Str(_) => "a string",
        Value::Tuple(..) => "a tuple",
        Value::List(_) => "a list",
        Value::Dict(_) => "a dict",
        Value::Global(_) => "a class",
        Value::Storage { .. } => "a storage",
        Value::Tensor(_) => "a tensor",
        Value::Mark => "a mark",
    }
}

/// A persistent id: `('storage', StorageClass, key, location, numel)`.
fn persistent<'a>(pid: &Value<'a>) -> Result<Value<'a>> {
    let Value::Tuple(t, _) = pid else {
        return refuse(format!(
            "a persistent id is {}, expected a tuple",
            kind(pid)
        ));
    };
    match t.iter().map(|v| &**v).collect::<Vec<_>>()[..] {
        [
            Value::Str(tag),
            Value::Global(Global::Storage(dtype)),
            Value::Str(key),
            Value::Str(_),
            &Value::Int(numel),
        ] if *tag == "storage" && numel >= 0 => Ok(Value::Storage {
            key,
            dtype: *dtype,
            numel: numel as u64,
        }),
        _ => refuse(
            "a persistent id is not ('storage', a float storage class, key, location, size)".into(),
        ),
    }
}

/// Calls one of the known globals: no code runs, the result is built here.
fn reduce<'a>(f: &Value<'a>, args: &Value<'a>) -> Result<Value<'a>> {
    let Value::Tuple(args, _) = args else {
        return refuse(format!(
            "REDUCE's arguments are {}, expected a tuple",
            kind(args)
        ));
    };
    match f {
        Value::Global(Global::OrderedDict) if args.is_empty() => {
            Ok(Value::Dict(RefCell::default()))
        }
        Value::Global(Global::RebuildTensor) => rebuild_tensor(args),
        // `_rebuild_parameter(data, requires_grad, backward_hooks)`: the tensor itself.
        Value::Global(Global::RebuildParameter) => match args.first().map(|t| &**t) {
            Some(Value::Tensor(t)) if args.len() == 3 => Ok(Value::Tensor(t.clone())),
            _ => refuse(
                "_rebuild_parameter's arguments are not (tensor, requires_grad, hooks)".into(),
            ),
        },
        _ => refuse(format!(
            "REDUCE calls {} with {} arguments; only OrderedDict(), _rebuild_tensor_v2 and \
             _rebuild_parameter are called in a state dict",
            kind(f),
            args.len()
        )),
    }
}

/// A tuple's items as non-negative integers (a shape, strides), shared: converted once
/// however many tensors the file rebuilds with it.
fn ints(v: &Value) -> Option<Rc<[usize]>> {
    let Value::Tuple(items, ints) = v else {
        return None;
    };
    ints.get_or_init(|| {
        items
            .iter()
            .map(|x| match **x {
                Value::Int(i) => usize::try_from(i).ok(),
                _ => None,
            })
            .collect()
    })
    .clone()
}

/// `_rebuild_tensor_v2(storage, offset, size, stride, requires_grad, hooks[, metadata])`.
fn rebuild_tensor<'a>(args: &[Rc<Value<'a>>]) -> Result<Value<'a>> {
    let Some([storage, offset, size, stride, _grad, _hooks]) = args.get(..6) else {
        return refuse(format!(
            "_rebuild_tensor_v2 with {} arguments, expected 6 or 7",
            args.len()
        ));
    };
    let (Value::Storage { key, dtype, numel }, &Value::Int(offset), Some(shape), Some(stride)) =
        (&**storage, &**offset, ints(size), ints(stride))
    else {
        return refuse(
            "_rebuild_tensor_v2's arguments are not (storage, offset, sizes, strides, ...)".into(),
        );
    };
    if shape.len() != stride.len() || offset < 0 || args.len() > 7 {
        return refuse("_rebuild_tensor_v2's sizes, strides or offset do not fit together".into());
    }
    Ok(Value::Tensor(Box::new(TensorRef {
        key,
        dtype: *dtype,
        numel: *numel,
        offset: offset as u64,
        shape,
        stride,
    })))
}

#[cfg(test)]
#[path = "pickle_tests.rs"]
mod tests;
