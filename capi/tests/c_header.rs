//! C against the static library, compiled by the system C compiler: the shipped policy through
//! `cartpole_policy.h`, and headers written by `policy-export export --format c` through
//! `cartpole_mlpH_forward`, and the same for the integer network (`cartpole_policy_forward_int`,
//! `export --quant int8` headers through `cartpole_qmlpH_forward`). Their literals are parsed
//! by the C compiler and the outputs computed by the library; both must equal Rust's, bit for
//! bit.
//! The library's header must declare what the exported headers declare, and both must
//! compile and link as C++ too.

mod common;

use std::io::Write;
use std::process::Stdio;

use cartpole_policy::CARTPOLE_ERR_NULL;
use common::{C99, CXX11, Compiler, EVERY, compile_and_run, manifest};

use firmware::network::int::QMlp;
use firmware::network::{Mlp, SUPPORTED_SHAPES, SUPPORTED_WIDTHS, shapes};
use firmware::rig::Rig;
use shipped::policy::POLICY;
use shipped::policy_int::POLICY_INT;
use weights::Weights;
use weights::quant::{self, Granularity};
use weights::source::{c_header, c_rig_struct, c_struct};

/// Observations the C programs are run on: a balanced state, leaning states, the edges of
/// the failure box, large rates, and values with long mantissas.
const PROBES: [[f32; 4]; 6] = [
    [0.0, 0.0, 0.0, 0.0],
    [0.01, -0.02, 0.03, 0.04],
    [2.4, 0.0, 0.2094395, 0.0],
    [-2.4, -1.5, -0.2094395, -2.0],
    [1.0e-7, -3.3333333, 0.12345679, -0.9876543],
    [-1.1754944e-38, 19.99, -0.41, 19.99],
];

/// The integer network's: the float probes in Q3.12 and the format's extremes.
const INT_PROBES: [[i16; 4]; 5] = [
    [0, 0, 0, 0],
    [41, -82, 123, 164],
    [9830, 0, 858, 0],
    [32767, -32768, 32767, -32768],
    [-1, 1, -32768, 32767],
];

/// The probes as exact decimal arguments (`{:e}` is the shortest form that reads back).
fn probe_args() -> Vec<String> {
    PROBES.iter().flatten().map(|v| format!("{v:e}")).collect()
}

fn q_line(q: [f32; 2]) -> String {
    format!("{:08x} {:08x}\n", q[0].to_bits(), q[1].to_bits())
}

#[test]
fn a_c_program_gets_the_shipped_policys_q_values_through_the_header() {
    let out = compile_and_run(
        &C99,
        "shipped",
        &[&manifest().join("tests/main.c")],
        &[&manifest().join("include")],
        &probe_args(),
    );
    let expected: String = PROBES.iter().map(|o| q_line(POLICY.forward(o))).collect();
    assert_eq!(out, expected);
}

/// A NaN anywhere in a reading gives finite Q-values, as the header says: every first-layer
/// unit's input is NaN, which ReLU takes to 0, so the scores are the second and third layers'
/// answer to the second layer's biases alone (computed here in f64 from the tensors).
#[test]
fn a_nan_reading_gives_the_biases_answer_through_the_header() {
    let args: Vec<String> = ["nan", "0", "0", "0", "0", "0", "0", "nan"]
        .map(String::from)
        .to_vec();
    let out = compile_and_run(
        &C99,
        "nan",
        &[&manifest().join("tests/main.c")],
        &[&manifest().join("include")],
        &args,
    );
    let p = &POLICY;
    let h2: Vec<f64> = p.fc2_bias.iter().map(|&b| f64::from(b).max(0.0)).collect();
    let q: Vec<f64> = (0..2)
        .map(|a| {
            let dot: f64 = (p.fc3_weight[a].iter().zip(&h2))
                .map(|(&w, h)| f64::from(w) * h)
                .sum();
            dot + f64::from(p.fc3_bias[a])
        })
        .collect();
    for line in out.lines() {
        let bits: Vec<u32> = line
            .split(' ')
            .map(|h| u32::from_str_radix(h, 16).unwrap())
            .collect();
        for (a, b) in bits.iter().enumerate() {
            let got = f64::from(f32::from_bits(*b));
            assert!(
                got.is_finite() && (got - q[a]).abs() < 1e-4,
                "{line}: {q:?}"
            );
        }
    }
    assert_eq!(out.lines().count(), 2);
}

/// The tokens `compiler`'s preprocessor makes of `source`, after `stdint.h` (which the
/// headers include) and with the library's header on the include path.
fn preprocessed(compiler: &Compiler, source: &str) -> Vec<String> {
    let (cc, mut cmd) = compiler.command();
    let mut child = cmd
        .args(["-x", compiler.lang, "-E", "-P", "-I"])
        .arg(manifest().join("include"))
        .arg("-")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("running the preprocessor `{cc}`: {e}"));
    let mut stdin = child.stdin.take().unwrap();
    write!(stdin, "#include <stdint.h>\n{source}\n").unwrap();
    drop(stdin);
    let out = child.wait_with_output().unwrap();
    assert!(out.status.success(), "preprocessing failed:\n{source}");
    tokens(&String::from_utf8(out.stdout).unwrap())
}

/// C's tokens as far as the headers use them: string literals, identifiers and numbers, and
/// punctuation one character at a time.
fn tokens(text: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = text.trim_start();
    while let Some(c) = rest.chars().next() {
        let len = if c == '"' {
            rest[1..].find('"').map_or(rest.len(), |i| i + 2)
        } else if c.is_ascii_alphanumeric() || c == '_' {
            rest.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
                .unwrap_or(rest.len())
        } else {
            c.len_utf8()
        };
        out.push(rest[..len].to_string());
        rest = rest[len..].trim_start();
    }
    out
}

/// Every shape's blocks of the exported headers, float then integer, then the rig's, each as
/// it preprocesses after the ones before it (so the integer blocks after the first lose the shared struct to
/// its guard, as they would in one translation unit), must stand in the library's header one
/// after another, token for token, in C and in C++.
#[test]
fn the_library_header_declares_every_shape_as_exported_headers_do() {
    let blocks = SUPPORTED_SHAPES
        .iter()
        .map(|&(h, a)| (format!("block for shape {h}x{a}"), c_struct(h, a)))
        .chain(SUPPORTED_SHAPES.iter().map(|&(h, a)| {
            (
                format!("integer block for shape {h}x{a}"),
                quant::c_struct(h, a),
            )
        }))
        .chain([("rig block".to_string(), c_rig_struct())]);
    for compiler in EVERY {
        let header = preprocessed(compiler, "#include \"cartpole_policy.h\"");
        let mut source = String::new();
        let mut before = preprocessed(compiler, &source);
        let mut at: Option<usize> = None;
        for (what, block) in blocks.clone() {
            source.push_str(&block);
            source.push('\n');
            let after = preprocessed(compiler, &source);
            let want = &after[before.len()..];
            let found = match at {
                None => header.windows(want.len()).position(|w| w == want),
                Some(i) => header[i..].starts_with(want).then_some(i),
            };
            let Some(i) = found else {
                panic!(
                    "include/cartpole_policy.h, preprocessed as {}, lacks (or differs from) the \
                     exporter's {what}; it should declare, token for token:\n{}",
                    compiler.lang,
                    want.join(" ")
                );
            };
            at = Some(i + want.len());
            before = after;
        }
    }
}

#[test]
fn a_cpp_program_links_every_function_of_the_header() {
    let dir = std::env::temp_dir().join(format!("cartpole-cpp-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    // Without C linkage a call would name a mangled symbol the library lacks; with NULL
    // weights each call writes nothing, so the shipped policy's outputs stand, and each init
    // refuses, for every shape.
    let calls: String = SUPPORTED_WIDTHS
        .iter()
        .map(|h| {
            format!(
                "        cartpole_mlp{h}_forward(nullptr, obs, q);\n\
                 \x20       cartpole_qmlp{h}_forward(nullptr, iobs, qi);\n\
                 \x20       refused += cartpole_controller_init_mlp{h}(nullptr, nullptr, nullptr);\n\
                 \x20       refused += cartpole_controller_init_qmlp{h}(nullptr, nullptr, nullptr);\n"
            )
        })
        .chain(SUPPORTED_SHAPES.iter().filter(|&&(_, a)| a > 2).map(|&(h, a)| {
            format!(
                "        cartpole_mlp{h}x{a}_forward(nullptr, obs, nullptr);\n\
                 \x20       cartpole_qmlp{h}x{a}_forward(nullptr, iobs, nullptr);\n\
                 \x20       refused += cartpole_controller_init_mlp{h}x{a}(nullptr, nullptr, nullptr, {a}, nullptr);\n\
                 \x20       refused += cartpole_controller_init_qmlp{h}x{a}(nullptr, nullptr, nullptr, {a}, nullptr);\n"
            )
        }))
        .collect();
    let main = format!(
        "#include <cstdio>\n#include <cstdlib>\n#include <cstring>\n\
         #include \"cartpole_policy.h\"\n\
         int main(int argc, char **argv) {{\n\
         \x20   for (int k = 1; k + 3 < argc; k += 4) {{\n\
         \x20       float obs[4], q[2];\n\
         \x20       const int16_t iobs[4] = {{0, 0, 0, 0}};\n\
         \x20       int32_t qi[2];\n\
         \x20       int refused = 0;\n\
         \x20       unsigned int bits[2];\n\
         \x20       for (int j = 0; j < 4; j++) obs[j] = std::strtof(argv[k + j], nullptr);\n\
         \x20       cartpole_policy_forward(obs, q);\n\
         \x20       cartpole_policy_forward_int(iobs, qi);\n\
         {calls}\
         \x20       std::memcpy(bits, q, sizeof bits);\n\
         \x20       std::printf(\"%08x %08x\\n%ld %ld\\n%d\\n\", bits[0], bits[1], (long)qi[0], (long)qi[1], refused);\n\
         \x20   }}\n\
         \x20   return 0;\n}}\n"
    );
    std::fs::write(dir.join("main.cpp"), main).unwrap();
    let out = compile_and_run(
        &CXX11,
        "cpp",
        &[&dir.join("main.cpp")],
        &[&manifest().join("include")],
        &probe_args(),
    );
    let int = int_line(POLICY_INT.forward(&[0; 4]));
    let refused = format!(
        "{}\n",
        2 * SUPPORTED_SHAPES.len() as i32 * CARTPOLE_ERR_NULL
    );
    let expected: String = PROBES
        .iter()
        .map(|o| q_line(POLICY.forward(o)) + &int + &refused)
        .collect();
    assert_eq!(out, expected);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Weights whose decimal forms are awkward for a parser: subnormals, extremes, signed zeros
/// and values that need nine significant digits.
fn awkward(width: usize) -> Weights {
    let special = [
        f32::MIN_POSITIVE,
        -f32::MAX,
        -0.0,
        1e-45,
        0.1,
        16_777_217.0,
        2.718_281_7,
        1.175_494_2e-38,
        f32::from_bits(0x8000_0005),
    ];
    let tensors = shapes(width, 2).map(|s| {
        (0..s.len())
            .map(|i| {
                special
                    .get(i)
                    .copied()
                    .unwrap_or(((i * 7919) % 1000) as f32 * -0.000_987_654_3 + 0.25)
            })
            .collect()
    });
    Weights::new(width, weights::BANG_BANG.to_vec(), tensors).unwrap()
}

/// A name beside the standard headers' reserved patterns (`str` and a lowercase letter),
/// outside them: it compiles beside the headers that reserve them.
const NEAR_RESERVED: &str = "strPolicy";

fn exported_header_case<const H: usize>() {
    let w = awkward(H);
    let dir = std::env::temp_dir().join(format!("cartpole-export-c-{H}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("exported.h"),
        c_header(
            &w,
            NEAR_RESERVED,
            &["source: the capi test".into()],
            &Rig::GYMNASIUM,
        )
        .unwrap(),
    )
    .unwrap();
    // Both headers in one translation unit: their shared definitions are guarded.
    let main = format!(
        "#include <stdio.h>\n#include <stdlib.h>\n#include <string.h>\n\
         #include <math.h>\n#include <limits.h>\n#include <float.h>\n#include <errno.h>\n\
         #include <signal.h>\n#include <time.h>\n#include <ctype.h>\n\
         #include \"cartpole_policy.h\"\n#include \"exported.h\"\n\
         int main(int argc, char **argv) {{\n\
         \x20   unsigned int bits[sizeof {NEAR_RESERVED} / 4];\n\
         \x20   size_t i;\n\
         \x20   int k;\n\
         \x20   memcpy(bits, &{NEAR_RESERVED}, sizeof bits);\n\
         \x20   for (i = 0; i < sizeof bits / 4; i++) printf(\"%08x\\n\", bits[i]);\n\
         \x20   for (k = 1; k + 3 < argc; k += 4) {{\n\
         \x20       float obs[4], q[2];\n\
         \x20       unsigned int qb[2];\n\
         \x20       int j;\n\
         \x20       for (j = 0; j < 4; j++) obs[j] = strtof(argv[k + j], NULL);\n\
         \x20       cartpole_mlp{H}_forward(&{NEAR_RESERVED}, obs, q);\n\
         \x20       memcpy(qb, q, sizeof qb);\n\
         \x20       printf(\"%08x %08x\\n\", qb[0], qb[1]);\n\
         \x20   }}\n\
         \x20   cartpole_mlp{H}_forward(NULL, NULL, NULL);\n\
         \x20   return 0;\n}}\n"
    );
    std::fs::write(dir.join("main.c"), main).unwrap();
    let mut want: String = w
        .tensors()
        .iter()
        .flatten()
        .map(|v| format!("{:08x}\n", v.to_bits()))
        .collect();
    let net: Box<Mlp<H>> = w.to_mlp().unwrap();
    want.extend(PROBES.iter().map(|o| q_line(net.forward(o))));
    // As C++ too: the initialisers are positional, which C++ before C++20 requires.
    for compiler in EVERY {
        let out = compile_and_run(
            compiler,
            &format!("export-{H}{}", compiler.std),
            &[&dir.join("main.c")],
            &[&manifest().join("include"), &dir],
            &probe_args(),
        );
        assert_eq!(out, want, "width {H}, {}", compiler.std);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn exported_headers_compile_and_run_the_rust_forward_pass_bit_for_bit() {
    exported_header_case::<16>();
    exported_header_case::<64>();
    exported_header_case::<128>();
}

/// The integer probes as arguments.
fn int_probe_args() -> Vec<String> {
    INT_PROBES.iter().flatten().map(i16::to_string).collect()
}

fn int_line(q: [i32; 2]) -> String {
    format!("{} {}\n", q[0], q[1])
}

/// A C program printing `sizeof` of `size_expr`, then `call` (which writes `q` from `obs`)
/// for every four integers on the command line.
fn int_program(includes: &str, size_expr: &str, call: &str) -> String {
    format!(
        "#include <stdio.h>\n#include <stdlib.h>\n{includes}\
         int main(int argc, char **argv) {{\n\
         \x20   int k;\n\
         \x20   printf(\"%lu\\n\", (unsigned long)sizeof({size_expr}));\n\
         \x20   for (k = 1; k + 3 < argc; k += 4) {{\n\
         \x20       int16_t obs[4];\n\
         \x20       int32_t q[2];\n\
         \x20       int j;\n\
         \x20       for (j = 0; j < 4; j++) obs[j] = (int16_t)atoi(argv[k + j]);\n\
         \x20       {call};\n\
         \x20       printf(\"%ld %ld\\n\", (long)q[0], (long)q[1]);\n\
         \x20   }}\n\
         \x20   return 0;\n}}\n"
    )
}

#[test]
fn a_c_program_gets_the_shipped_integer_policys_outputs_through_the_header() {
    let dir = std::env::temp_dir().join(format!("cartpole-int-c-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let main = int_program(
        "#include \"cartpole_policy.h\"\n",
        "struct cartpole_qmlp64",
        "cartpole_policy_forward_int(obs, q)",
    );
    std::fs::write(dir.join("main.c"), main).unwrap();
    let out = compile_and_run(
        &C99,
        "shipped-int",
        &[&dir.join("main.c")],
        &[&manifest().join("include")],
        &int_probe_args(),
    );
    let mut want = format!("{}\n", std::mem::size_of::<QMlp<64>>());
    want.extend(INT_PROBES.iter().map(|o| int_line(POLICY_INT.forward(o))));
    assert_eq!(out, want);
    std::fs::remove_dir_all(&dir).unwrap();
}

fn exported_int_header_case<const H: usize>(w: &Weights) {
    let states: Vec<[f32; 4]> = PROBES
        .iter()
        .copied()
        .filter(|p| p.iter().all(|v| v.abs() < 3.0))
        .collect();
    let q = quant::quantise(w, &states, Granularity::PerChannel).unwrap();
    let dir = std::env::temp_dir().join(format!("cartpole-export-int-{H}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(
        dir.join("exported.h"),
        quant::c_header(
            &q,
            "test_policy",
            &["source: the capi test".into()],
            &Rig::GYMNASIUM,
        )
        .unwrap(),
    )
    .unwrap();
    // With the library's header in the same translation unit: the shared blocks are guarded.
    let main = int_program(
        "#include \"cartpole_policy.h\"\n#include \"exported.h\"\n",
        "test_policy",
        &format!(
            "cartpole_qmlp{H}_forward(&test_policy, obs, q); cartpole_qmlp{H}_forward(NULL, obs, q)"
        ),
    );
    std::fs::write(dir.join("main.c"), main).unwrap();
    let net: Box<QMlp<H>> = q.to_qmlp().unwrap();
    let mut want = format!("{}\n", std::mem::size_of::<QMlp<H>>());
    want.extend(INT_PROBES.iter().map(|o| int_line(net.forward(o))));
    for compiler in EVERY {
        let out = compile_and_run(
            compiler,
            &format!("export-int-{H}{}", compiler.std),
            &[&dir.join("main.c")],
            &[&manifest().join("include"), &dir],
            &int_probe_args(),
        );
        assert_eq!(out, want, "width {H}, {}", compiler.std);
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn exported_integer_headers_compile_and_run_the_rust_forward_pass_bit_for_bit() {
    exported_int_header_case::<64>(
        &Weights::from_mlp(&POLICY, &firmware::controller::Levels::BANG_BANG).unwrap(),
    );
    let smooth = shapes(16, 2).map(|s| {
        (0..s.len())
            .map(|i| ((i * 7919) % 1000) as f32 * 0.002 - 1.0)
            .collect()
    });
    exported_int_header_case::<16>(&Weights::new(16, weights::BANG_BANG.to_vec(), smooth).unwrap());
}
