"""Input the careful way, for the repository's Python scripts, by the rules the Rust tools
keep (docs/HOSTILE_INPUT.md, docs/FILES.md): files are read only if they are regular
files, without blocking on a FIFO and never past a size cap; every count has a bound;
anything malformed ends the script with exit status 2 and one line saying what was
expected and what was found, never a traceback.

Standard library only, so that a script can refuse bad input before it imports NumPy,
Gymnasium or Unicorn (and on a machine without them).
"""

import argparse
import os
import stat
import sys

# Input quoted in a message is cut to this many characters.
QUOTE_MAX = 200


class Refusal(Exception):
    """Bad input: what was expected and what was found, in one line."""


def quote(text):
    """`text` for a message: repr-quoted, cut at QUOTE_MAX characters."""
    q = repr(text)
    return q if len(q) <= QUOTE_MAX else q[:QUOTE_MAX] + "..."


def _kind(mode):
    for test, name in (
        (stat.S_ISDIR, "a directory"),
        (stat.S_ISFIFO, "a FIFO"),
        (stat.S_ISCHR, "a device"),
        (stat.S_ISBLK, "a device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return name
    return "something that is not a regular file"


def read_capped(path, cap):
    """The bytes of the regular file `path`, at most `cap` of them; Refusal otherwise."""
    try:
        mode = os.stat(path).st_mode
    except OSError as e:
        raise Refusal(f"{quote(str(path))}: expected a readable file, found {e.strerror}")
    if not stat.S_ISREG(mode):
        # Checked before opening: a socket cannot be opened, a FIFO would block.
        raise Refusal(f"{quote(str(path))}: expected a regular file, found {_kind(mode)}")
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as e:
        raise Refusal(f"{quote(str(path))}: expected a readable file, found {e.strerror}")
    try:
        # Checked again on what was opened: the path may have changed in between.
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise Refusal(f"{quote(str(path))}: expected a regular file, found {_kind(mode)}")
        chunks, size = [], 0
        while size <= cap:
            chunk = os.read(fd, min(1 << 20, cap + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    finally:
        os.close(fd)
    if size > cap:
        raise Refusal(f"{quote(str(path))}: expected at most {cap} bytes, found more")
    return b"".join(chunks)


def bounded_int(lo, hi):
    """An argparse type: an integer in [lo, hi]."""

    def parse(text):
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, found {quote(text)}")
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"expected an integer in [{lo}, {hi}], found {value}")
        return value

    return parse


class _Parser(argparse.ArgumentParser):
    """argparse with the scripts' refusal: one line, exit status 2."""

    def error(self, message):
        raise Refusal(message.splitlines()[0][: 3 * QUOTE_MAX])


def parser(prog, description):
    return _Parser(prog=prog, description=description)


def run(prog, main):
    """Runs `main()`; a Refusal, or any error a malformed input provokes in a parser, ends
    the script with one line on standard error and exit status 2."""
    try:
        main()
    except Refusal as e:
        print(f"{prog}: {e}", file=sys.stderr)
        sys.exit(2)
    except KeyboardInterrupt:
        sys.exit(130)
    except ImportError as e:
        print(f"{prog}: needs the Python module {e.name}: install the requirements its "
              "docstring names", file=sys.stderr)
        sys.exit(1)
    except BrokenPipeError:
        # The reader of the output has seen enough: quiet, as Unix tools are.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        sys.exit(0)
    except Exception as e:  # noqa: BLE001 -- the rule is: no traceback on any input
        line = f"{type(e).__name__}: {e}".splitlines()[0] if str(e) else type(e).__name__
        print(f"{prog}: expected well-formed input, found {line[: 3 * QUOTE_MAX]}", file=sys.stderr)
        sys.exit(2)
