#!/usr/bin/env python3
"""Writes weights/src/source/names/gnu_library.rs: the names an exported C header's object
may not have because the standard headers declare them for a C++ program or a C program
that defines `_GNU_SOURCE`, beyond those they declare in the C compilers' default dialect.

    python3 scripts/gnu_names.py

g++ defines `_GNU_SOURCE` on glibc, and libstdc++'s headers bring more of glibc's (the C11
headers' C++ forms include <pthread.h>, hence <sched.h>'s `CLONE_` flags). No list of ours
says which: the compilers do. The C11 headers the program includes are the ones the test
probes (weights/tests/c_library_collisions.rs, read from there so they are written once);
every identifier of their preprocessed text and macros is declared after them as the exported
header would declare its object, and the names the compiler fails are kept: those failed by
`c++ -std=c++17` or `cc -std=gnu17 -D_GNU_SOURCE`, less those `cc -std=gnu17` already fails
(refused by the hand-written lists beside the file) and those starting with `_` (refused by
their form before any list is read). The compilers are $CC and $CXX (default cc and c++);
the list holds for the versions named in the file's first line, and the test fails on a
system whose headers declare a name it lacks: rerun this then.

The file is written whole or not at all (a temporary renamed into place). A missing compiler
or a failing run ends the script with exit status 2 and one line saying what was expected.
"""

import os
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TEST = os.path.join(ROOT, "weights", "tests", "c_library_collisions.rs")
OUT = os.path.join(ROOT, "weights", "src", "source", "names", "gnu_library.rs")
PROG = "gnu_names.py"


def die(message):
    print(f"{PROG}: {message}", file=sys.stderr)
    sys.exit(2)


def c11_headers():
    """The headers the test includes: its C11_HEADERS string, split on white space."""
    with open(TEST, encoding="utf-8") as f:
        text = f.read()
    found = re.search(r'const C11_HEADERS: &str = "([^"]*)";', text)
    if not found:
        die(f"expected `const C11_HEADERS: &str = \"...\";` in {TEST}, found none")
    return found.group(1).replace("\\\n", " ").split()


def run(cmd, stdin=""):
    """`cmd`'s standard output and error; the script stops if it cannot start."""
    try:
        out = subprocess.run(cmd, input=stdin, capture_output=True, text=True, check=False)
    except OSError as e:
        die(f"expected a compiler to run as {cmd[0]!r} (set CC or CXX), found: {e}")
    return out


def failing(cmd, ext, headers, work):
    """The identifiers of `headers`, preprocessed by `cmd`, that `cmd` fails as an object's
    name declared after them (one declaration a line, so an error's line names its name)."""
    includes = "".join(f"#include <{h}.h>\n" for h in headers)
    source = os.path.join(work, "headers" + ext)
    with open(source, "w", encoding="utf-8") as f:
        f.write(includes)
    text = ""
    for flags in (["-E", "-P"], ["-dM", "-E"]):
        out = run(cmd + flags + [source])
        if out.returncode != 0:
            die(f"expected {' '.join(cmd)} to preprocess the headers, found: {out.stderr[:400]}")
        text += out.stdout
    words = sorted(set(re.findall(r"\b[A-Za-z_][A-Za-z0-9_]*", text)))
    probe = os.path.join(work, "probe" + ext)
    first = includes.count("\n") + 1
    with open(probe, "w", encoding="utf-8") as f:
        f.write(includes)
        f.writelines(f"extern const struct cartpole_probe {w};\n" for w in words)
    # Every colliding name reported: Clang stops after 20 errors unless told, as GCC does not.
    no_limit = "-ferror-limit=0" if "clang" in version(cmd[0]) else "-fmax-errors=0"
    err = run(cmd + ["-fsyntax-only", no_limit, probe]).stderr
    at = re.compile(re.escape(probe) + r":(\d+):\d+: error:")
    lines = (int(m.group(1)) - first for m in map(at.match, err.splitlines()) if m)
    return {words[i] for i in lines if 0 <= i < len(words)}


def version(compiler):
    """The first line of `compiler --version`, which names it and its version."""
    out = run([compiler, "--version"])
    return out.stdout.splitlines()[0] if out.stdout else compiler


def libc(cc):
    """The C library's name and version, as its headers give them."""
    out = run([cc, "-E", "-P", "-include", "limits.h", "-x", "c", "-"], "__GLIBC__ __GLIBC_MINOR__")
    found = re.fullmatch(r"(\d+) (\d+)", out.stdout.strip().splitlines()[-1] if out.stdout else "")
    return f"glibc {found.group(1)}.{found.group(2)}" if found else "a C library other than glibc"


def main():
    cc = os.environ.get("CC", "cc")
    cxx = os.environ.get("CXX", "c++")
    headers = c11_headers()
    with tempfile.TemporaryDirectory() as work:
        base = failing([cc, "-std=gnu17"], ".c", headers, work)
        if "printf" not in base:
            die(f"expected {cc} -std=gnu17 to fail `printf` as a name, found it accepted")
        gnu = failing([cc, "-std=gnu17", "-D_GNU_SOURCE"], ".c", headers, work)
        cxx_fails = failing([cxx, "-std=c++17"], ".cc", headers, work)
    names = sorted(n for n in (gnu | cxx_fails) - base if not n.startswith("_"))
    body = "".join(f'    "{n}",\n' for n in names)
    text = (
        f"// Generated by scripts/gnu_names.py ({libc(cc)}; {version(cc)};"
        f" {version(cxx)}); do not edit.\n"
        "//! The names the standard C11 headers declare for a C++ program (g++ defines\n"
        "//! `_GNU_SOURCE` on glibc) or a C program defining `_GNU_SOURCE`, beyond those of\n"
        "//! `-std=gnu17` and outside names starting with `_`, as the compilers fail them.\n\n"
        "/// Sorted, for a binary search.\n"
        f"pub(super) static GNU_NAMES: [&str; {len(names)}] = [\n{body}];\n"
    )
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(OUT), prefix=".gnu_library.")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.chmod(tmp, 0o644)
        os.replace(tmp, OUT)
    except BaseException:
        os.unlink(tmp)
        raise
    print(f"{os.path.relpath(OUT, ROOT)}: {len(names)} names")


if __name__ == "__main__":
    main()
