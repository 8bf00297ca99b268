"""Policies, export and evaluation: the arguments Python users pass, turned into what the
native module (the commands' own code) takes."""

import collections.abc
import itertools
import json
import numbers
import operator
import os
import reprlib
import sys

import numpy as np

from . import _native

_SHORT = reprlib.Repr()
_SHORT.maxstring = _SHORT.maxother = _SHORT.maxlong = 200


def _short(value):
    """``repr(value)`` cut to about 200 characters, never built whole: a refusal of a huge
    argument (a set of 10**8 levels) would build a repr of a gigabyte to show 200 of it."""
    return _SHORT.repr(value)


# The most episodes of a row, periods of an episode and rows of one evaluation: `host-sim eval`'s.
MAX_EPISODES = _native.MAX_EPISODES
MAX_HORIZON = _native.MAX_HORIZON
MAX_ROWS = _native.MAX_ROWS

# NumPy dtypes a state dict's tensors may have, by safetensors' name for them.
_DTYPES = {np.dtype(np.float32): "F32", np.dtype(np.float64): "F64", np.dtype(np.float16): "F16"}


class Policy:
    """A Q-network: ``q_values(obs)`` for readings ``[..., 4]`` gives ``[..., A]``, one
    column per duty level (``levels``); ``act(obs)`` the controller's actions, the index of
    the level it drives (with the paper's two, 1 right, 0 left)."""

    def __init__(self, native):
        self._native = native

    def q_values(self, obs):
        source, given = _readings(obs)
        q = _by_range(source, given, (len(self.levels),), np.float32, self._native)
        return q.reshape(given.shape[:-1] + q.shape[-1:])

    @property
    def levels(self):
        """The duty level each output drives, a fraction of the full push."""
        return self._native.levels

    @property
    def reading_bound(self):
        """The largest reading, each channel within +- it, past which a network sum can leave float32."""
        return self._native.reading_bound

    def act(self, obs):
        source, given = _readings(obs)
        actions = _by_range(source, given, (), np.int64, self._native, act=True).reshape(given.shape[:-1])
        return int(actions) if actions.ndim == 0 else actions

    def __repr__(self):
        return f"Policy({self._native.describe})"


_NOT_REAL = "obs: expected readings that are real numbers; found"

# Readings converted, checked and run between two looks at Ctrl-C: the native network's
# range, a few milliseconds of work.
_ROWS = _native.ROWS_PER_CHECK


def _readings(obs):
    """``obs`` as given (``source``) and as real numbers (``given``, the same array but for an
    object array's items as float64), shaped ``[..., 4]``: refused with ValueError naming
    ``obs`` where they are no real numbers (None, text, complex)."""
    source = np.asarray(obs)
    if source.ndim == 0 or source.shape[-1] != 4:
        raise ValueError(
            f"obs: expected readings shaped [..., 4] ([x, x_dot, theta, theta_dot]); found shape {source.shape}"
        )
    given = _real_items(source) if source.dtype == object else source
    # A bool is no reading: True would be read as 1 metre.
    if given.dtype.kind not in "iuf":
        first = f", the first {_item(given, 0)} at {[0] * given.ndim}" if given.size else ""
        raise ValueError(f"{_NOT_REAL} {given.dtype} readings{first}")
    return source, given


def _by_range(source, given, tail, dtype, native, act=False):
    """The network's native call (``act`` or ``q_values`` of ``native`` on float32 readings
    ``[m, 4]``, giving ``[m, *tail]``) on every reading of ``given``, into one array ``[n, *tail]`` of ``dtype``
    (MemoryError if it cannot be allocated). The readings are converted and checked
    ``_ROWS`` at a time, as the network runs them: a pass over a batch of 10^8 before the
    first range heard Ctrl-C only seconds later, and held a float32 copy of it whole."""
    n = given.size // 4
    out = np.empty((n, *tail), dtype=dtype)
    run = native.act if act else native.q_values
    for start in range(0, n, _ROWS):
        end = min(start + _ROWS, n)
        out[start:end] = run(_checked(source, given, start, end, native.reading_bound))
    return out


def _checked(source, given, start, end, bound):
    """Readings ``start..end`` of ``given`` (in C order) as the network takes them, float32
    ``[m, 4]``, refused with ValueError naming ``obs`` and the first as ``source`` holds it
    where they are not finite in float32 (NaN, an infinity, 1e300) or past ``bound``, where
    the network's sums can leave float32's range: the network answered them all the same,
    and NaN turns every ReLU off, so its answer was a constant no state chose."""
    # Past float32's range a value becomes an infinity: refused below, shown as given.
    with np.errstate(over="ignore"):
        readings = given.flat[4 * start : 4 * end].astype(np.float32, copy=False).reshape(-1, 4)
    finite = np.isfinite(readings)
    if not finite.all():
        k = 4 * start + int(np.argmin(finite))
        raise ValueError(f"obs: expected readings finite in float32; found {_item(source, k)} at {_at(source, k)}")
    within = np.abs(readings) <= bound
    if not within.all():
        k = 4 * start + int(np.argmin(within))
        raise ValueError(
            f"obs: expected readings within +-{bound:.3e}, past which the network's sums can leave "
            f"float32's range; found {_item(source, k)} at {_at(source, k)}"
        )
    return readings


def _item(array, k):
    """The ``k``-th item of ``array`` (in C order) as Python shows it, cut."""
    v = array.flat[k]
    return _short(v.item() if isinstance(v, np.generic) else v)


def _at(array, k):
    return list(map(int, np.unravel_index(k, array.shape)))


def _real_items(source):
    """An object array's items as float64, each a real number (None, a str or any other
    object is refused with ValueError); an int past float64's range as an infinity, refused
    as past float32's."""
    values = np.empty(source.shape, dtype=np.float64)
    flat = values.reshape(-1)
    for k, v in enumerate(source.flat):
        if not isinstance(v, numbers.Real):
            raise ValueError(f"{_NOT_REAL} {_item(source, k)} at {_at(source, k)}")
        try:
            flat[k] = v
        except OverflowError:
            flat[k] = np.inf
    return values


def load(path, prefix=None, rig=None, levels=None):
    """The network in a policy file or run directory (whatever formats the project reads),
    ``prefix`` choosing among several networks in one file; ``rig`` a rig file for the
    machine it runs on (without one, the rig the file records, or Gymnasium's); ``levels``
    the duty level of each output (fractions of the full push, increasing) for a file that
    records none, as PyTorch's, Stable-Baselines3's and ONNX files do."""
    return Policy(_native.load(os.fspath(path), prefix, _path(rig), _levels(levels)))


def shipped(rig=None):
    """The policy compiled into the firmware."""
    return Policy(_native.shipped(_path(rig)))


def _path(p):
    return None if p is None else os.fspath(p)


# The most levels there can be: they rise by a thousandth at least within [-1, 1].
_MAX_LEVELS = 2001


def _listlike(value, name, expected):
    """``value``, refused with TypeError if it iterates but is no list of items: a str or
    bytes would be read character by character ("01" as the levels 0 and 1), a set in no
    order, a dict by its keys (its values dropped)."""
    if isinstance(value, (str, bytes, bytearray, memoryview, collections.abc.Set, collections.abc.Mapping)):
        raise _not_a_list(value, name, expected)
    return value


def _not_a_list(value, name, expected):
    return TypeError(f"{name} must be {expected}; found {type(value).__name__} {_short(value)}")


def _items(value, name, expected):
    """An iterator over a list argument's items (``_listlike``); TypeError for what does not
    iterate at all."""
    value = _listlike(value, name, expected)
    try:
        return iter(value)
    except TypeError:
        raise _not_a_list(value, name, expected) from None


_LEVELS = "a list of duty levels, numbers (fractions of the full push)"


def _level(v):
    # float() would parse a str ("0.5") and drop a NumPy complex's imaginary part.
    text = isinstance(v, (str, bytes, bytearray))
    if not text and not (isinstance(v, numbers.Complex) and not isinstance(v, numbers.Real)):
        try:
            f = float(v)
        except OverflowError:
            raise ValueError(f"levels must be {_LEVELS} within float's range; found the item {_short(v)}") from None
        except (TypeError, ValueError):
            pass
        else:
            # A Decimal("1e-400") or a Fraction that small becomes 0 in a float, a level the
            # caller did not write.
            if f == 0 and v != 0:
                raise ValueError(f"levels: the item {_short(v)} reads as 0 in a float; expected 0 written as 0, or a level a float holds")
            return f
    raise TypeError(f"levels must be {_LEVELS}; found the item {_short(v)} ({type(v).__name__})")


def _levels(levels):
    if levels is None:
        return None
    items = _items(levels, "levels", _LEVELS)
    # Read to one past the most there can be: a range of ten billion builds no list.
    return [_level(v) for v in itertools.islice(items, _MAX_LEVELS + 1)]


def _array(value):
    """A tensor as a NumPy array: PyTorch tensors detached and copied to the CPU first,
    bfloat16 widened to float32 (exactly)."""
    if hasattr(value, "detach"):
        value = value.detach().cpu()
        if str(getattr(value, "dtype", "")) == "torch.bfloat16":
            value = value.float()
        value = value.numpy()
    return np.asarray(value)


def _check_dtype(name, dtype):
    """Refuses a tensor whose dtype, NumPy's or PyTorch's (named as NumPy's after
    ``torch.``), is not a float the importer reads; PyTorch's bfloat16 is read widened."""
    text = str(dtype)
    if text == "torch.bfloat16":
        return
    try:
        found = np.dtype(text.removeprefix("torch.") if text.startswith("torch.") else dtype)
        ok = found.newbyteorder("=") in _DTYPES
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"tensor {_short(name)}: expected float32, float64 or float16 values; found {_short(text)}")


def _shape(name, value):
    """A state dict tensor's shape, its name and dtype checked, read from its ``shape`` and
    ``dtype`` without converting its values: the importer chooses the network's tensors by
    name and shape, and only those are converted (``_tensor``)."""
    if not isinstance(name, str):
        raise ValueError(f"expected tensor names as str; found {type(name).__name__}")
    dtype, shape = getattr(value, "dtype", None), getattr(value, "shape", None)
    if dtype is None or shape is None:
        # A list could be measured only by converting it, and a list sharing one inner list
        # a thousand times converts to a thousand copies: a state dict holds arrays.
        raise ValueError(
            f"tensor {_short(name)}: expected an array or a tensor (with a dtype and a shape); "
            f"found {type(value).__name__}"
        )
    _check_dtype(name, dtype)
    try:
        dims = [operator.index(d) for d in shape]
    except TypeError:
        dims = None
    # No NumPy or PyTorch dimension passes sys.maxsize, and the native side takes none that does.
    if dims is None or not all(0 <= d <= sys.maxsize for d in dims):
        raise ValueError(f"tensor {_short(name)}: expected a shape of whole numbers; found {_short(shape)}")
    return dims


def _tensor(name, value):
    """One tensor as the importer reads it: (safetensors dtype, shape, little-endian bytes)."""
    array = np.ascontiguousarray(_array(value))
    _check_dtype(name, array.dtype)
    # Big-endian values are the same numbers: looked up in native order, written little.
    dtype = _DTYPES[array.dtype.newbyteorder("=")]
    return dtype, list(array.shape), array.astype(array.dtype.newbyteorder("<")).tobytes()


def export(source, out, fmt="rust", quant=None, name=None, rig=None, prefix=None, granularity=None, label=None, levels=None):
    """Writes the network of ``source`` (a policy file or run directory's path, or a state
    dict of NumPy arrays or PyTorch tensors) to ``out`` as ``policy-export export`` does:
    Rust (``fmt="rust"``) or C (``"c"``) source, float or ``quant="int8"``, written
    atomically. ``label`` names an in-memory source in the file's provenance comment (as a
    file's name does; default ``state dict``); ``levels`` are the duty levels of a network
    whose source records none (as ``load``). Returns ``out``."""
    kwargs = dict(
        quant=quant, name=name, rig=_path(rig), prefix=prefix, granularity=granularity, levels=_levels(levels)
    )
    if isinstance(source, dict):
        shapes = {key: _shape(key, value) for key, value in source.items()}
        _native.export(os.fspath(out), fmt, shapes=shapes, tensor=lambda key: _tensor(key, source[key]),
                       label=label, **kwargs)
    elif isinstance(source, (str, os.PathLike)):
        if label is not None:
            raise ValueError("expected no label for a file source (its name is the label); found one")
        _native.export(os.fspath(out), fmt, path=os.fspath(source), **kwargs)
    else:
        raise ValueError(
            f"expected a policy file's path or a state dict as the source; found {type(source).__name__}"
        )
    return out


# What a list argument of evaluate's may be alone, one item. A float alone is one horizon
# too, refused by name where horizons are read (_horizon).
_ONE = (str, int, float, np.integer, np.floating)


def _count(value):
    """How many items a list argument holds (a str or a whole number alone is one), by
    ``len()`` where it has one; None where only iterating would tell."""
    if isinstance(value, _ONE):
        return 1
    try:
        return len(value)
    # OverflowError: a length past sys.maxsize, which iterating bounds as well.
    except (TypeError, OverflowError):
        return None


def _listed(value, what):
    """A list argument of evaluate's as given: one item alone, or a list refused as
    ``_listlike`` refuses (a set's order would be the rows')."""
    return value if isinstance(value, _ONE) else _listlike(value, what, f"a {what} or a list of them")


def _list(value, what):
    """A list argument's items, at most one more than ``MAX_ROWS``: more make too many rows
    whatever the other lists hold, and a ``len()`` that lies builds no more."""
    if isinstance(value, _ONE):
        return [value]
    values = list(itertools.islice(value, MAX_ROWS + 1))
    if not values:
        raise ValueError(f"expected at least one {what}; found none")
    return values


def _names(values, what):
    """A list of names, each a str: str() would name bytes by their repr (b'lqr')."""
    for v in values:
        if not isinstance(v, str):
            raise TypeError(f"{what} must be a {what} or a list of them (str); found the item {_short(v)}")
    return values


def _horizon(h):
    """A horizon as a whole number of periods in [1, MAX_HORIZON]: 200.7 is refused, not cut
    to 200, and 2**40 named with the range, where the native conversion's OverflowError
    named neither."""
    try:
        # True is an int to Python, and ran as a horizon of 1.
        if isinstance(h, (bool, np.bool_)):
            raise TypeError
        whole = operator.index(h)
    except TypeError:
        raise ValueError(f"horizon must be a whole number of periods; found {_short(h)}") from None
    if not 1 <= whole <= MAX_HORIZON:
        raise ValueError(f"horizon must be in [1, {MAX_HORIZON}]; found {whole}")
    return whole


# The native worlds take a seed as an unsigned 64-bit integer.
_SEEDS = 2**64


def _whole(value, name, least, most, kind="a whole number", bools=False):
    """``value``, a Python int or a NumPy integer, as a Python int in [least, most]:
    TypeError for what is no int, as a float is refused, not truncated, and for a bool
    unless ``bools`` (an int to Python, it ran as a count of 1; Gymnasium takes one as a
    seed); ValueError naming the range for an int outside
    it, before the native module's conversion would raise an OverflowError that names
    neither."""
    try:
        if isinstance(value, (bool, np.bool_)) and not bools:
            raise TypeError
        whole = operator.index(value)
    except TypeError:
        raise TypeError(f"{name} must be an int ({kind}); found {_short(value)} ({type(value).__name__})") from None
    if not least <= whole <= most:
        raise ValueError(f"{name} must be in [{least}, {most}]; found {whole}")
    return whole


def _steps(max_episode_steps):
    """An environment's ``max_episode_steps`` (None: no truncation), checked here: 2**64
    raised the native conversion's OverflowError, naming nothing."""
    if max_episode_steps is None:
        return None
    return _whole(max_episode_steps, "max_episode_steps", 1, MAX_HORIZON, "a whole number of periods")


def _seed(seed, most=_SEEDS - 1, name="seed"):
    """A seed as Gymnasium's ``reset(seed=)`` takes one, an int of at least 0, returned as a
    Python int for Gymnasium's seeding: 1.7 would replay seed 1's episodes."""
    return _whole(seed, name, 0, most, "a whole number, as Gymnasium takes one", bools=True)


def evaluate(policy=None, scenario="nominal", episodes=1000, horizon=500, seed=0, controller="policy", rig=None,
             levels=None):
    """The rows ``host-sim eval --json`` prints for the same arguments, as dicts: success
    rate with its Wilson interval, failures, RMS of angle and position, the motor figures
    (``reversals_per_s``, ``mean_abs_duty``, ``duty_tv_per_s``, ``heat``) and the rest.
    ``policy`` is a loaded Policy (the shipped one by default), which drives its own duty
    levels (``levels``, if given, must be those); ``scenario``, ``horizon`` and
    ``controller`` may be lists (``controller`` among ``host-sim eval``'s controllers:
    policy, policy-int, either refined between its levels, the monitored and LQR baselines,
    rule, random); a policy or levels none of them reads is refused (``ValueError``), as
    the command refuses them. At most ``MAX_EPISODES`` episodes of
    ``MAX_HORIZON`` periods; Ctrl-C (``KeyboardInterrupt``) stops it within a fraction of
    a second."""
    if policy is not None and not isinstance(policy, Policy):
        raise TypeError(f"policy: expected a Policy from cartpole_ddqn.load, or None; found {type(policy).__name__}")
    episodes = _whole(episodes, "episodes", 1, MAX_EPISODES)
    seed = _seed(seed)
    given = ((horizon, "horizon"), (scenario, "scenario"), (controller, "controller"))
    named = [(_listed(v, w), w) for v, w in given]
    # Counted before any list is built: a range of thirty million horizons is refused as
    # it is, not as a list of them. A list counted only by iterating holds one item at least
    # (none is refused), and is read to one item past the limit at most.
    counts = [_count(v) for v, _ in named]
    _native.check_count(*[1 if c is None else c for c in counts])
    lists = [_list(v, w) for v, w in named]
    _native.check_count(*[len(v) for v in lists])
    horizons, scenarios, controllers = lists
    rows = _native.evaluate_json(
        None if policy is None else policy._native,
        _names(scenarios, "scenario"),
        _names(controllers, "controller"),
        episodes,
        [_horizon(h) for h in horizons],
        seed,
        _path(rig),
        _levels(levels),
    )
    return json.loads(rows)


# The most a command line can hold: Linux's execve takes 6 MiB of arguments at most (three
# quarters of its 8 MiB stack limit; 2 MiB under the default stack rlimit), each counted
# with its NUL and its 8-byte pointer, so no process was ever given more arguments than
# _MAX_ARGS. Past them an argv records no run, and reading it whole could take gigabytes.
_ARGV_BYTES = 6 * 2**20
_ARG_OVERHEAD = 9
_MAX_ARGS = _ARGV_BYTES // _ARG_OVERHEAD


def _argument(a):
    """One argument as text: sys.argv holds a byte that is not UTF-8 as a lone surrogate,
    which JSON cannot carry; it is recorded as U+FFFD, as the tools record their own."""
    if isinstance(a, (bytes, bytearray)):
        # str() would record the repr, b'...', not the argument.
        raise TypeError(f"argv must be a list of arguments as str; found the item {_short(a)}")
    text = a if isinstance(a, str) else str(a)
    try:
        return text.encode("utf-8", "surrogateescape").decode("utf-8", "replace")
    except UnicodeEncodeError:
        raise ValueError(
            f"argv: expected arguments as text, a surrogate only for a byte sys.argv escapes; found {_short(text)}"
        ) from None


def _argv(argv):
    """The arguments, refused with ValueError once they pass what a command line holds,
    read no further than one past the most there can be (``range(10**10)`` builds no list)."""
    items = _items(argv, "argv", "a list of arguments (str)")
    args, size = [], 0
    for a in itertools.islice(items, _MAX_ARGS + 1):
        # A str's characters bound its bytes from below: one longer than a command line is
        # refused before it is copied to be encoded.
        long = isinstance(a, str) and len(a) > _ARGV_BYTES
        text = "" if long else _argument(a)
        size = _ARGV_BYTES + 1 if long else size + _ARG_OVERHEAD + len(text.encode("utf-8"))
        args.append(text)
        if len(args) > _MAX_ARGS or size > _ARGV_BYTES:
            found = f"over {_MAX_ARGS} arguments" if len(args) > _MAX_ARGS else f"more by argument {len(args)}"
            raise ValueError(
                f"argv must fit a command line: at most {_ARGV_BYTES} bytes, each argument's UTF-8 and "
                f"{_ARG_OVERHEAD} more (its NUL and pointer), so at most {_MAX_ARGS} arguments; found {found}"
            )
    return args


def provenance(tool, argv):
    """The record a results file keeps of the run that wrote it, as the command-line tools
    write it: ``tool`` (a script's path from the repository's root) and ``argv`` (its
    arguments, at most what a Linux command line holds), the date, the git revision,
    ``nproc`` and the CPU model."""
    return json.loads(_native.provenance_json(str(tool), _argv(argv)))
