//! The names an export refuses because its own source or the C library already uses them:
//! every item a written Rust module defines beside its static, and every name the C library
//! takes from a header's object, checked against the macros the system's C compiler
//! (`CC`, else `cc`) defines, an implementation nobody here wrote.

use std::collections::BTreeSet;
use std::process::Command;

use firmware::rig::Rig;
use weights::quant::{self, Granularity, Quantised};
use weights::source::{c_header, check_c_name, check_rust_name, rust_module};
use weights::{BANG_BANG, Weights};

/// Float and int8 policies of two and of five levels: every branch of the writers.
fn policies() -> Vec<(Weights, Quantised)> {
    let five = [-1.0, -0.4, 0.0, 0.3, 1.0];
    [(16, &BANG_BANG[..]), (64, &five[..])]
        .into_iter()
        .map(|(h, levels)| {
            let w = weights::feedback::state_feedback(h, levels, [-0.5, -1.0, -20.0, -3.0]);
            let w = w.unwrap();
            let states = [[0.1, -0.2, 0.05, 0.3], [-0.1, 0.2, -0.05, -0.3]];
            let q = quant::quantise(&w, &states, Granularity::PerChannel).unwrap();
            (w, q)
        })
        .collect()
}

/// The names a Rust module defines at its top level: each item starts in the first column
/// (comments, attributes and closing brackets do not start with a letter), its name the
/// first word after its keywords.
fn top_level_items(module: &str) -> Vec<&str> {
    let keywords = [
        "pub", "const", "static", "mut", "fn", "struct", "enum", "type",
    ];
    module
        .lines()
        .filter(|line| line.starts_with(|c: char| c.is_ascii_alphabetic()))
        .map(|line| {
            line.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .find(|w| !w.is_empty() && !keywords.contains(w))
                .unwrap_or_else(|| panic!("no name in {line:?}"))
        })
        .collect()
}

#[test]
fn every_item_a_rust_module_defines_beside_its_static_is_refused_as_its_name() {
    let mut refused = BTreeSet::new();
    for (w, q) in policies() {
        for module in [
            rust_module(&w, "GENTLE", &[], &Rig::GYMNASIUM).unwrap(),
            quant::rust_module(&q, "GENTLE", &[], &Rig::GYMNASIUM).unwrap(),
        ] {
            let items = top_level_items(&module);
            assert!(items.contains(&"GENTLE"), "{items:?}");
            for item in items.into_iter().filter(|item| *item != "GENTLE") {
                let e = check_rust_name(item).unwrap_err();
                assert!(
                    e.is_input() && e.to_string().contains("the module defines"),
                    "{item}: {e}"
                );
                refused.insert(item.to_string());
            }
        }
    }
    // The items the hostile tester's LEVELS clashed with, and RIG, found by the parse.
    assert!(
        refused.contains("LEVELS") && refused.contains("RIG"),
        "{refused:?}"
    );
    for ok in ["LEVELS_2", "POLICY_LEVELS", "RIGS"] {
        check_rust_name(ok).unwrap();
    }
}

/// Names the C library takes, by what takes them, as the refusal says it.
const LIBRARY_CLASSES: [(&str, &[&str]); 23] = [
    (
        "a macro name of <stdint.h>, which the header includes",
        &[
            "INT8_MAX",
            "UINT64_C",
            "INT_LEAST16_MIN",
            "UINTPTR_WIDTH",
            "INTERVAL_MAX",
            "INTMAX_C",
            "UINTMAX_C",
            "SIZE_MAX",
            "PTRDIFF_MIN",
            "PTRDIFF_MAX",
            "SIG_ATOMIC_MIN",
            "SIG_ATOMIC_MAX",
            "WCHAR_MIN",
            "WCHAR_MAX",
            "WINT_MIN",
            "WINT_MAX",
            "SIZE_WIDTH",
        ],
    ),
    (
        "a macro of <stddef.h>",
        &["NULL", "offsetof", "unreachable"],
    ),
    ("the macro of <errno.h>", &["errno"]),
    ("the function every C program defines", &["main"]),
    ("default GNU dialects predefine", &["unix", "linux", "i386"]),
    ("a release build defines", &["NDEBUG"]),
    // The standard headers a program includes beside the header: each name failed to
    // compile there, in strict C99 and C++17.
    (
        "<stdio.h>",
        &[
            "EOF", "stdout", "stdin", "stderr", "BUFSIZ", "SEEK_SET", "printf",
        ],
    ),
    (
        "<math.h>",
        &["INFINITY", "NAN", "HUGE_VAL", "round", "roundf", "sqrtl"],
    ),
    (
        "<math.h>",
        &["math_errhandling", "FP_NAN", "isnan", "isinf"],
    ),
    ("<stdlib.h>", &["abs", "EXIT_SUCCESS", "RAND_MAX", "malloc"]),
    (
        "<limits.h>",
        &["CHAR_BIT", "LLONG_MAX", "MB_LEN_MAX", "SCHAR_MIN"],
    ),
    ("<signal.h>", &["SIGINT", "signal", "SIGTERM", "SIG_DFL"]),
    (
        "<float.h>",
        &["FLT_MAX", "DBL_MAX", "LDBL_EPSILON", "DECIMAL_DIG"],
    ),
    ("<time.h>", &["CLOCKS_PER_SEC", "time"]),
    ("<complex.h>", &["I", "complex", "cabsf"]),
    ("<stdnoreturn.h>", &["noreturn"]),
    ("<setjmp.h>", &["setjmp", "longjmp"]),
    ("POSIX's <math.h>", &["M_PI", "M_2_PI"]),
    // What C11 7.31 reserves for the library's future, by pattern.
    ("<errno.h>", &["ENOMEM", "E2BIG", "EVERYTHING"]),
    ("<ctype.h>", &["isalpha", "toupper"]),
    ("<string.h>", &["memcpy", "strlen", "strtok"]),
    ("<stdlib.h>", &["strtod"]),
    // What glibc declares beyond C11 in gnu17 and C++: each compiled under -std=c99 only.
    (
        "declares in the GNU dialect C compilers default to (-std=gnu17)",
        &[
            "y0",
            "y1",
            "yn",
            "j0",
            "j1",
            "jn",
            "y0f",
            "jnl",
            "gamma",
            "lgamma_r",
            "signgam",
            "random",
            "srandom",
            "drand48",
            "erand48",
            "lrand48",
            "mrand48",
            "srand48",
            "rand_r",
            "setenv",
            "mkstemp",
            "realpath",
            "fileno",
            "popen",
            "pclose",
            "fdopen",
            "getline",
            "strdup",
            "strndup",
            "strtok_r",
            "bzero",
            "index",
            "strcasecmp",
            "isascii",
            "tzset",
            "timezone",
            "kill",
            "sigaction",
            "PATH_MAX",
            "SA_RESTART",
            "CLOCK_MONOTONIC",
            "WNOHANG",
            "BYTE_ORDER",
            "uint",
            "P_tmpdir",
        ],
    ),
];

#[test]
fn c_names_the_c_library_takes_are_refused_by_class_saying_why() {
    for (why, names) in LIBRARY_CLASSES {
        for name in names {
            let e = check_c_name(name).unwrap_err().to_string();
            assert!(
                e.contains("expected a name the C library leaves to programs") && e.contains(why),
                "{name}: {e}"
            );
        }
    }
    // The names the C API's macros paste together for some shape, which its header's text
    // spells only in part.
    for name in [
        "cartpole_mlp64x9_forward",
        "cartpole_mlp64_forward",
        "cartpole_qmlp64x9_forward",
        "cartpole_controller_init_mlp64x9",
    ] {
        let e = check_c_name(name).unwrap_err().to_string();
        assert!(e.contains("macros declare names beginning"), "{name}: {e}");
    }
    // Beside the patterns, outside them: is, to, str and mem before a lowercase letter but
    // no function of today's, no capital after E, an M_ constant's form with a lowercase
    // letter.
    for ok in [
        "cartpole_policy",
        "torque",
        "total",
        "string",
        "memory",
        "isready",
        "is_up",
        "toBalance",
        "strPolicy",
        "E",
        "Eval",
        "M_pi",
        "PI",
        "y2",
        "Gamma",
        "randomize",
        "duty_max",
    ] {
        check_c_name(ok).unwrap_or_else(|e| panic!("{ok}: {e}"));
    }
    // Every macro an exported header defines, another export's include guard included.
    for (w, q) in policies() {
        for header in [
            c_header(&w, "cartpole_policy", &[], &Rig::GYMNASIUM).unwrap(),
            quant::c_header(&q, "cartpole_policy_int", &[], &Rig::GYMNASIUM).unwrap(),
        ] {
            let defined = header.lines().filter_map(|l| l.strip_prefix("#define "));
            for name in defined.map(|l| l.split(['(', ' ']).next().unwrap()) {
                let e = check_c_name(name).unwrap_err().to_string();
                assert!(e.contains("outside the headers' macros"), "{name}: {e}");
            }
        }
    }
    // C23's keywords beyond C++'s: `typeof` is one in GCC's default dialect too.
    for keyword in ["typeof", "typeof_unqual"] {
        check_c_name(keyword).unwrap_err();
    }
}

#[test]
fn every_macro_of_the_headers_a_header_includes_is_refused_as_its_name() {
    let mut includes = BTreeSet::new();
    for (w, q) in policies() {
        for header in [
            c_header(&w, "gentle", &[], &Rig::GYMNASIUM).unwrap(),
            quant::c_header(&q, "gentle", &[], &Rig::GYMNASIUM).unwrap(),
        ] {
            let found = header.lines().filter_map(|l| l.strip_prefix("#include "));
            includes.extend(found.map(String::from));
        }
    }
    // A header the writers come to include brings macros `check_c_name` must refuse.
    assert_eq!(includes, BTreeSet::from(["<stdint.h>".to_string()]));
    // C23, whose <stdint.h> adds the widths; strict, so no `linux` or `unix` of GNU's dialects.
    let macros = macros_of("c2x", "stdint stddef");
    assert!(macros.iter().any(|m| m == "SIZE_MAX") && macros.iter().any(|m| m == "NULL"));
    let accepted: Vec<&String> = macros.iter().filter(|m| check_c_name(m).is_ok()).collect();
    assert!(accepted.is_empty(), "accepted as names: {accepted:?}");
}

/// Every C11 header a program may include beside an exported one.
const C11_HEADERS: &str = "assert complex ctype errno fenv float inttypes iso646 limits locale \
    math setjmp signal stdalign stdarg stdatomic stdbool stddef stdint stdio stdlib \
    stdnoreturn string tgmath threads time uchar wchar wctype";

#[test]
fn every_macro_of_the_c11_headers_is_refused_as_a_name() {
    let macros = macros_of("c11", C11_HEADERS);
    assert!(macros.iter().any(|m| m == "EOF") && macros.iter().any(|m| m == "CHAR_BIT"));
    let accepted: Vec<&String> = macros.iter().filter(|m| check_c_name(m).is_ok()).collect();
    assert!(accepted.is_empty(), "accepted as names: {accepted:?}");
}

/// The macros the C compiler's preprocessor defines in the dialect `std` (strict) with each
/// of `headers` (`stdio` for `<stdio.h>`) included.
fn macros_of(std: &str, headers: &str) -> Vec<String> {
    let dir = std::env::temp_dir().join(format!("weights-names-{std}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("macros.c");
    let includes: String = headers
        .split_whitespace()
        .map(|h| format!("#include <{h}.h>\n"))
        .collect();
    std::fs::write(&file, includes).unwrap();
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let out = Command::new(&cc)
        .args([&format!("-std={std}"), "-dM", "-E"])
        .arg(&file)
        .output()
        .unwrap_or_else(|e| panic!("running {cc}: {e}"));
    std::fs::remove_dir_all(&dir).unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .filter_map(|l| l.strip_prefix("#define "))
        .map(|l| l.split(['(', ' ']).next().unwrap().to_string())
        .collect()
}
