//! What the C tests share: the host build of the static library and the system's C and C++
//! compilers, strict.

use std::path::{Path, PathBuf};
use std::process::Command;

/// This package's directory.
pub fn manifest() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Cargo builds this package's static library beside this test, in target/<profile>/deps,
/// as libcartpole_policy-<hash>.a; the newest is the one of this build.
pub fn static_lib() -> PathBuf {
    let deps = std::env::current_exe()
        .unwrap()
        .parent()
        .unwrap()
        .to_path_buf();
    std::fs::read_dir(&deps)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            let name = p.file_name().unwrap().to_string_lossy();
            name.starts_with("libcartpole_policy-") && name.ends_with(".a")
        })
        .max_by_key(|p| p.metadata().and_then(|m| m.modified()).ok())
        .unwrap_or_else(|| panic!("no libcartpole_policy-*.a in {}", deps.display()))
}

/// A compiler of the system and its strict flags.
pub struct Compiler {
    /// The variable that names it, and the command without one.
    env: (&'static str, &'static str),
    /// The language, as `-x` names it.
    pub lang: &'static str,
    /// The standard it holds the source to.
    pub std: &'static str,
}

/// C99, the C the headers are written to.
pub const C99: Compiler = Compiler {
    env: ("CC", "cc"),
    lang: "c",
    std: "-std=c99",
};

/// C++11: Arduino sketches are C++ and include the headers too.
pub const CXX11: Compiler = Compiler {
    env: ("CXX", "c++"),
    lang: "c++",
    std: "-std=c++11",
};

/// C++17, the C++ of most current embedded toolchains.
pub const CXX17: Compiler = Compiler {
    env: ("CXX", "c++"),
    lang: "c++",
    std: "-std=c++17",
};

/// Every standard the header is written to hold.
pub const EVERY: [&Compiler; 3] = [&C99, &CXX11, &CXX17];

impl Compiler {
    /// The compiler, strict: every warning an error.
    pub fn command(&self) -> (String, Command) {
        let (var, default) = self.env;
        let cc = std::env::var(var).unwrap_or_else(|_| default.into());
        let mut cmd = Command::new(&cc);
        cmd.args([self.std, "-pedantic", "-Wall", "-Wextra", "-Werror"]);
        (cc, cmd)
    }
}

/// Compiles `sources` with `compiler` against the library, and runs the program with
/// `args`; its standard output.
pub fn compile_and_run(
    compiler: &Compiler,
    name: &str,
    sources: &[&Path],
    include: &[&Path],
    args: &[String],
) -> String {
    let exe = std::env::temp_dir().join(format!("cartpole-c-{name}-{}", std::process::id()));
    let (cc, mut cmd) = compiler.command();
    for dir in include {
        cmd.arg("-I").arg(dir);
    }
    // `-x` so that a C++ compiler reads `.c` files as C++ too, and `-x none` so that the
    // library is linked, not compiled.
    let status = cmd
        .args(["-x", compiler.lang])
        .args(sources)
        .args(["-x", "none"])
        .arg(static_lib())
        .args(["-lpthread", "-ldl", "-lm", "-o"])
        .arg(&exe)
        .status()
        .unwrap_or_else(|e| panic!("running the compiler `{cc}`: {e}"));
    assert!(status.success(), "compile of {name} failed");
    let run = Command::new(&exe).args(args).output().unwrap();
    assert!(
        run.status.success(),
        "{name}: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    std::fs::remove_file(&exe).unwrap();
    String::from_utf8(run.stdout).unwrap()
}
