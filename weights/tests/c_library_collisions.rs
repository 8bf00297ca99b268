//! The names an exported header's object may not have because a program compiled in the
//! compilers' default GNU dialect cannot declare them beside the standard headers: found by
//! the system's C compiler (`CC`, else `cc`), an implementation nobody here wrote, not by a
//! list of ours. POSIX's and the BSDs' names (`y0`, `random`, `fileno`, `popen`, `drand48`)
//! compile under `-std=c11` but not under `-std=gnu17`, where the C library declares them;
//! glibc's `_GNU_SOURCE` names (`read`, `fork`, `mempcpy`, `sincos`) fail where a C program
//! defines it and in every C++ program, since g++ defines it: probed with the system's C++
//! compiler too (`CXX`, else `c++`), as `scripts/gnu_names.py` probed them to write the list
//! that refuses them (`weights/src/source/names/gnu_library.rs`; rerun it where this fails).

use std::path::Path;
use std::process::{Command, Output};

use weights::source::check_c_name;

/// Every C11 header a program may include beside an exported one.
const C11_HEADERS: &str = "assert complex ctype errno fenv float inttypes iso646 limits locale \
    math setjmp signal stdalign stdarg stdatomic stdbool stddef stdint stdio stdlib \
    stdnoreturn string tgmath threads time uchar wchar wctype";

/// How an exported header declares its object, to the compiler: a name the headers declare
/// as anything else (a function, an object of another type, a typedef, an enumerator, a
/// macro) is an error on its line.
fn declaration(name: &str) -> String {
    format!("extern const struct cartpole_probe {name};\n")
}

/// A compiler of the system's and its flags: the C compiler (`CC`, else `cc`) or the C++
/// one (`CXX`, else `c++`), with the extension of the sources it is given.
struct Compiler {
    command: String,
    flags: &'static [&'static str],
    ext: &'static str,
}

impl Compiler {
    fn c(flags: &'static [&'static str]) -> Self {
        let command = std::env::var("CC").unwrap_or_else(|_| "cc".into());
        Compiler {
            command,
            flags,
            ext: "c",
        }
    }

    fn cxx(flags: &'static [&'static str]) -> Self {
        let command = std::env::var("CXX").unwrap_or_else(|_| "c++".into());
        Compiler {
            command,
            flags,
            ext: "cc",
        }
    }

    /// The compiler run with its flags and `args` on `file`.
    fn run(&self, args: &[&str], file: &Path) -> Output {
        Command::new(&self.command)
            .args(self.flags)
            .args(args)
            .arg(file)
            .output()
            .unwrap_or_else(|e| panic!("running {}: {e}", self.command))
    }

    /// The flag that lifts the compiler's limit on errors reported, so that every colliding
    /// name is: Clang stops after 20 unless told (`-ferror-limit`), GCC takes `-fmax-errors`.
    fn no_error_limit(&self) -> &'static str {
        let version = Command::new(&self.command)
            .arg("--version")
            .output()
            .map(|o| String::from_utf8_lossy(&o.stdout).into_owned())
            .unwrap_or_default();
        if version.contains("clang") {
            "-ferror-limit=0"
        } else {
            "-fmax-errors=0"
        }
    }
}

/// The identifiers of the C11 headers as `cc` compiles them (each word of their preprocessed
/// text and each macro they define) that it refuses as the object's name.
fn colliding(cc: &Compiler) -> Vec<String> {
    let dir = std::env::temp_dir().join(format!(
        "weights-collide-{}-{}",
        cc.flags.concat(),
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let includes: String = C11_HEADERS
        .split_whitespace()
        .map(|h| format!("#include <{h}.h>\n"))
        .collect();
    let headers = dir.join(format!("headers.{}", cc.ext));
    std::fs::write(&headers, &includes).unwrap();
    let text = |args: &[&str]| {
        let out = cc.run(args, &headers);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout).unwrap()
    };
    let mut words: Vec<String> = [text(&["-E", "-P"]), text(&["-dM", "-E"])]
        .concat()
        .split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .filter(|w| w.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_'))
        .map(String::from)
        .collect();
    words.sort();
    words.dedup();
    let probe = dir.join(format!("probe.{}", cc.ext));
    let first = includes.lines().count() + 1;
    let body: String = words.iter().map(|w| declaration(w)).collect();
    std::fs::write(&probe, includes + &body).unwrap();
    let out = cc.run(&["-fsyntax-only", cc.no_error_limit()], &probe);
    let err = String::from_utf8_lossy(&out.stderr);
    std::fs::remove_dir_all(&dir).unwrap();
    let shown = probe.to_string_lossy().into_owned();
    let mut refused: Vec<String> = err
        .lines()
        .filter_map(|l| l.strip_prefix(&format!("{shown}:")))
        .filter(|l| l.contains(": error:"))
        .filter_map(|l| l.split(':').next()?.parse::<usize>().ok())
        .filter_map(|line| words.get(line.checked_sub(first)?).cloned())
        .collect();
    refused.dedup();
    refused
}

/// The names of `refused` that the export accepts.
fn accepted(refused: &[String]) -> Vec<&String> {
    refused.iter().filter(|m| check_c_name(m).is_ok()).collect()
}

#[test]
fn every_name_the_c11_headers_declare_in_gnu17_is_refused() {
    for cc in [Compiler::c(&["-std=c11"]), Compiler::c(&["-std=gnu17"])] {
        let refused = colliding(&cc);
        let std = cc.flags[0];
        // The probe refuses what the headers declare, not every word of them: a struct's tag
        // is no object's name in C.
        let has = |name: &str| refused.iter().any(|r| r == name);
        assert!(["printf", "EOF", "sqrt"].into_iter().all(has), "{std}");
        assert!(!has("tm") && !has("timespec"), "{std}: {refused:?}");
        for posix in ["y0", "j1", "gamma", "random", "fileno", "popen", "drand48"] {
            assert_eq!(has(posix), std == "-std=gnu17", "{std}: {posix}");
        }
        for gnu in ["read", "fork", "mempcpy", "sincos"] {
            assert!(!has(gnu), "{std}: {gnu}");
        }
        let accepted = accepted(&refused);
        assert!(
            accepted.is_empty(),
            "{std}: accepted as names: {accepted:?}"
        );
    }
}

#[test]
fn every_name_the_c11_headers_declare_under_gnu_source_or_to_cxx_is_refused() {
    for cc in [
        Compiler::c(&["-std=gnu17", "-D_GNU_SOURCE"]),
        Compiler::cxx(&["-std=c++17"]),
    ] {
        let refused = colliding(&cc);
        let has = |name: &str| refused.iter().any(|r| r == name);
        let dialect = cc.flags.join(" ");
        for gnu in [
            "read", "fork", "mempcpy", "sincos", "qsort_r", "printf", "y0",
        ] {
            assert!(has(gnu), "{dialect}: {gnu}");
        }
        let accepted = accepted(&refused);
        assert!(
            accepted.is_empty(),
            "{dialect}: accepted as names (rerun scripts/gnu_names.py): {accepted:?}"
        );
    }
}
