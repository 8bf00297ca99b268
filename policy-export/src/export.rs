//! Turns a policy into source code that firmware compiles into flash.
//!
//! Every weight is written as the shortest decimal that parses back to the same f32 (Rust's
//! `{:?}`), which both rustc and C compilers round correctly, so the compiled constants equal
//! the trained weights bit for bit while the file stays readable and diffable.

use std::fmt::Write;

use firmware::network::TENSOR_NAMES;

use crate::weights::Weights;

/// The target language of an export.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// A Rust module defining `pub static POLICY: Mlp<H>` (what `firmware` compiles).
    Rust,
    /// A C header with `static const float` arrays, for C firmware.
    C,
}

/// Renders the weights as a Rust module. `provenance` lines go into its doc comment.
pub fn rust_module(w: &Weights, provenance: &[String]) -> String {
    let mut s = String::new();
    let h = w.width;
    s.push_str(&format!(
        "//! The shipped balance policy: a 4-{h}-{h}-2 Q-network trained by `policy-export`.\n"
    ));
    s.push_str("//!\n//! Generated; do not edit. Regenerate with the command in the README.\n");
    for line in provenance {
        s.push_str(&format!("//! - {line}\n"));
    }
    s.push_str("\nuse crate::network::Mlp;\n\n");
    s.push_str(&format!(
        "/// The policy's weights in PyTorch layout, {} parameters ({} bytes of flash).\n",
        firmware_params(h),
        4 * firmware_params(h)
    ));
    s.push_str("#[rustfmt::skip]\n");
    s.push_str(&format!("pub static POLICY: Mlp<{h}> = Mlp {{\n"));
    for ((name, shape), t) in TENSOR_NAMES.iter().zip(w.shapes()).zip(&w.tensors) {
        let field = name.replace('.', "_");
        s.push_str(&format!("    {field}: "));
        if shape.len() == 2 {
            s.push_str("[\n");
            for row in t.chunks(shape[1]) {
                s.push_str("        [");
                push_list(&mut s, row, "");
                s.push_str("],\n");
            }
            s.push_str("    ],\n");
        } else {
            s.push('[');
            push_list(&mut s, t, "");
            s.push_str("],\n");
        }
    }
    s.push_str("};\n");
    s
}

/// Renders the weights as a C header. `provenance` lines go into its opening comment.
pub fn c_header(w: &Weights, provenance: &[String]) -> String {
    let mut s = String::new();
    let h = w.width;
    s.push_str(&format!(
        "/* The cart-pole balance policy: a 4-{h}-{h}-2 Q-network trained by policy-export.\n"
    ));
    s.push_str(" * Generated; do not edit. Layout: PyTorch nn.Linear, weight[out][in].\n");
    s.push_str(" * Q = fc3(relu(fc2(relu(fc1(obs))))); obs = {x, x_dot, theta, theta_dot};\n");
    s.push_str(" * action 1 (push right) iff Q[1] > Q[0].\n");
    for line in provenance {
        s.push_str(&format!(" * - {line}\n"));
    }
    s.push_str(" */\n#ifndef CARTPOLE_POLICY_WEIGHTS_H\n#define CARTPOLE_POLICY_WEIGHTS_H\n\n");
    s.push_str(&format!("#define CARTPOLE_POLICY_HIDDEN {h}\n"));
    s.push_str(&format!(
        "#define CARTPOLE_POLICY_PARAMS {}\n\n",
        firmware_params(h)
    ));
    for ((name, shape), t) in TENSOR_NAMES.iter().zip(w.shapes()).zip(&w.tensors) {
        let ident = format!("cartpole_{}", name.replace('.', "_"));
        let dims: String = shape.iter().map(|d| format!("[{d}]")).collect();
        s.push_str(&format!("static const float {ident}{dims} = {{\n"));
        let row_len = shape.last().copied().unwrap_or(1);
        for row in t.chunks(row_len) {
            s.push_str(if shape.len() == 2 { "    {" } else { "    " });
            push_list(&mut s, row, "f");
            s.push_str(if shape.len() == 2 { "},\n" } else { "\n" });
        }
        s.push_str("};\n\n");
    }
    s.push_str("#endif /* CARTPOLE_POLICY_WEIGHTS_H */\n");
    s
}

fn firmware_params(h: usize) -> usize {
    4 * h + h + h * h + h + 2 * h + 2
}

fn push_list(s: &mut String, values: &[f32], suffix: &str) {
    for (i, v) in values.iter().enumerate() {
        if i > 0 {
            s.push_str(", ");
        }
        // `{:?}` is the shortest round-tripping form and always has a '.' or an exponent.
        write!(s, "{v:?}{suffix}").expect("writing to a String cannot fail");
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::weights::shapes;

    fn awkward(width: usize) -> Weights {
        // Subnormals, extremes, negative zero and values with 9 significant digits.
        let special = [
            f32::MIN_POSITIVE,
            -f32::MAX,
            -0.0,
            1e-45,
            0.1,
            16777217.0,
            2.718_281_7,
        ];
        let tensors = shapes(width).map(|s| {
            let n: usize = s.iter().product();
            (0..n)
                .map(|i| {
                    special
                        .get(i)
                        .copied()
                        .unwrap_or((i as f32).sqrt() * -0.012_345_679)
                })
                .collect()
        });
        Weights { width, tensors }
    }

    /// Every literal in the generated text, parsed with Rust's (correctly rounding) parser.
    fn literals(text: &str, suffix: char) -> Vec<f32> {
        text.lines()
            .filter(|l| {
                !l.trim_start().starts_with("//")
                    && !l.contains(" * ")
                    && !l.contains('#')
                    && !l.contains("static")
            })
            .flat_map(|l| {
                l.split(|c: char| {
                    c == '[' || c == ']' || c == ',' || c == '{' || c == '}' || c == '='
                })
            })
            .map(|t| t.trim().trim_end_matches(suffix))
            .filter(|t| t.starts_with(|c: char| c == '-' || c.is_ascii_digit()))
            .map(|t| t.parse().unwrap_or_else(|_| panic!("bad literal {t:?}")))
            .collect()
    }

    #[test]
    fn rust_and_c_literals_round_trip_bit_for_bit() {
        let w = awkward(16);
        let flat: Vec<u32> = w.tensors.iter().flatten().map(|v| v.to_bits()).collect();
        let rust = rust_module(&w, &["seed 3".into()]);
        assert!(rust.contains("pub static POLICY: Mlp<16> = Mlp {"));
        let got: Vec<u32> = literals(&rust, ' ').iter().map(|v| v.to_bits()).collect();
        assert_eq!(got, flat);
        let c = c_header(&w, &[]);
        assert!(c.contains("static const float cartpole_fc2_weight[16][16] = {"));
        let got: Vec<u32> = literals(&c, 'f').iter().map(|v| v.to_bits()).collect();
        assert_eq!(got, flat);
    }
}
