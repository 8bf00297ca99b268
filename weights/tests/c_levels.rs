//! A policy of five duty levels through the C headers, float and int8, compiled by the
//! system's C compiler (`CC`, else `cc`): the program computes the network from the
//! header's arrays and takes `NAME_duty`, and the duty it chooses is the one an f64
//! forward pass of the same weights chooses, for thousands of observations; and headers
//! named just outside the names the C library takes compile beside its headers and a `main`.

use std::fmt::Write;
use std::path::Path;
use std::process::Command;

use firmware::controller::Duty;
use firmware::fixed::from_state;
use firmware::rig::Rig;
use weights::Weights;
use weights::quant::{self, Granularity};

const LEVELS: [f32; 5] = [-1.0, -0.4, 0.0, 0.3, 1.0];
const GAIN: [f32; 4] = [-0.5, -1.0, -20.0, -3.0];

/// Observations around upright, far enough out that every level is chosen: a fixed
/// pseudo-random sequence.
fn observations(n: usize) -> Vec<[f32; 4]> {
    let mut seed = 7u64;
    let mut next = move |scale: f32| {
        seed = seed
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((seed >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0) * scale
    };
    (0..n)
        .map(|_| [next(0.5), next(0.8), next(0.08), next(0.5)])
        .collect()
}

/// The Q-values of `w` for `obs` in f64, from its tensors: the reference.
fn q_f64(w: &Weights, obs: &[f64; 4]) -> Vec<f64> {
    let t = w.tensors();
    let layer = |wt: &[f32], b: &[f32], x: &[f64], relu: bool| -> Vec<f64> {
        wt.chunks(x.len())
            .zip(b)
            .map(|(row, b)| {
                let v = row
                    .iter()
                    .zip(x)
                    .map(|(w, x)| f64::from(*w) * x)
                    .sum::<f64>()
                    + f64::from(*b);
                if relu { v.max(0.0) } else { v }
            })
            .collect()
    };
    let h1 = layer(&t[0], &t[1], obs, true);
    let h2 = layer(&t[2], &t[3], &h1, true);
    layer(&t[4], &t[5], &h2, false)
}

/// The output the reference chooses, and its margin over the runner-up.
fn choice(q: &[f64]) -> (usize, f64) {
    let best = firmware::network::argmax(q);
    let margin = (0..q.len())
        .filter(|&i| i != best)
        .fold(f64::INFINITY, |m, i| m.min(q[best] - q[i]));
    (best, margin)
}

/// The C program: for each observation, the float header's duty (the network in double from
/// its arrays) and the integer header's outputs and duty (the network in integers from the
/// requantisation its comment states).
const MAIN: &str = r#"
#include <stdio.h>
#include "gentle.h"
#include "gentle_int.h"

static uint8_t requant(int32_t acc, struct cartpole_requant r) {
    uint32_t t, y;
    if (acc <= 0) return 0;
    t = (uint32_t)acc >> r.pre_shift;
    if (t > 32767u) t = 32767u;
    y = (t * r.multiplier + ((1u << r.post_shift) >> 1)) >> r.post_shift;
    return (uint8_t)(y > 255u ? 255u : y);
}

int main(void) {
    size_t n, o, i, k;
    for (n = 0; n < sizeof obs / sizeof obs[0]; n++) {
        double h1[64], h2[64];
        float q[5];
        uint8_t u1[64], u2[64];
        int32_t qi[5];
        for (o = 0; o < 64; o++) {
            double v = gentle.fc1_bias[o];
            for (i = 0; i < 4; i++) v += (double)gentle.fc1_weight[o][i] * obs[n][i];
            h1[o] = v > 0.0 ? v : 0.0;
        }
        for (o = 0; o < 64; o++) {
            double v = gentle.fc2_bias[o];
            for (i = 0; i < 64; i++) v += (double)gentle.fc2_weight[o][i] * h1[i];
            h2[o] = v > 0.0 ? v : 0.0;
        }
        for (o = 0; o < 5; o++) {
            double v = gentle.fc3_bias[o];
            for (i = 0; i < 64; i++) v += (double)gentle.fc3_weight[o][i] * h2[i];
            q[o] = (float)v;
        }
        for (o = 0; o < 64; o++) {
            int32_t acc = gentle_int.fc1_bias[o];
            for (i = 0; i < 4; i++) acc += (int32_t)gentle_int.fc1_weight[o][i] * fixed[n][i];
            u1[o] = requant(acc, gentle_int.fc1_requant[o]);
        }
        for (o = 0; o < 64; o++) {
            int32_t acc = gentle_int.fc2_bias[o];
            for (i = 0; i < 64; i++) acc += (int32_t)gentle_int.fc2_weight[o][i] * u1[i];
            u2[o] = requant(acc, gentle_int.fc2_requant[o]);
        }
        for (o = 0; o < 5; o++) {
            qi[o] = gentle_int.fc3_bias[o];
            for (i = 0; i < 64; i++) qi[o] += (int32_t)gentle_int.fc3_weight[o][i] * u2[i];
        }
        printf("%d %d", gentle_duty(q), gentle_int_duty(qi));
        for (k = 0; k < 5; k++) printf(" %ld", (long)qi[k]);
        printf("\n");
    }
    return 0;
}
"#;

/// Compiles `dir/main.c` strictly as C99 and runs it; its standard output.
fn compile_and_run(dir: &Path) -> String {
    let cc = std::env::var("CC").unwrap_or_else(|_| "cc".into());
    let exe = dir.join("levels");
    let out = Command::new(&cc)
        .args([
            "-std=c99",
            "-pedantic",
            "-Wall",
            "-Wextra",
            "-Werror",
            "-O1",
        ])
        .arg("-I")
        .arg(dir)
        .arg(dir.join("main.c"))
        .arg("-o")
        .arg(&exe)
        .output()
        .unwrap_or_else(|e| panic!("running {cc}: {e}"));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let run = Command::new(&exe).output().unwrap();
    assert!(run.status.success());
    String::from_utf8(run.stdout).unwrap()
}

#[test]
fn five_levels_in_c_choose_the_duty_the_f64_network_chooses() {
    let w = weights::feedback::state_feedback(64, &LEVELS, GAIN).unwrap();
    let states = observations(3000);
    let q = quant::quantise(&w, &states, Granularity::PerChannel).unwrap();
    let int = q.to_qmlp::<64, 5>().unwrap();
    let dir = std::env::temp_dir().join(format!("weights-c-levels-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let float_h = weights::source::c_header(&w, "gentle", &[], &Rig::GYMNASIUM).unwrap();
    let int_h = quant::c_header(&q, "gentle_int", &[], &Rig::GYMNASIUM).unwrap();
    std::fs::write(dir.join("gentle.h"), float_h).unwrap();
    std::fs::write(dir.join("gentle_int.h"), int_h).unwrap();
    let (mut floats, mut fixed) = (String::new(), String::new());
    for s in &states {
        let _ = writeln!(
            floats,
            "    {{{:?}, {:?}, {:?}, {:?}}},",
            s[0], s[1], s[2], s[3]
        );
        let f = from_state(s);
        let _ = writeln!(fixed, "    {{{}, {}, {}, {}}},", f[0], f[1], f[2], f[3]);
    }
    let main = format!(
        "static const double obs[][4] = {{\n{floats}}};\n\
         static const short fixed[][4] = {{\n{fixed}}};\n{MAIN}"
    );
    std::fs::write(dir.join("main.c"), main).unwrap();
    let out = compile_and_run(&dir);
    std::fs::remove_dir_all(&dir).unwrap();

    let duty = |i: usize| Duty::from_fraction(LEVELS[i]).unwrap().thousandths();
    let (mut clear, mut int_kept, mut chosen) = (0, 0, [0usize; 5]);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), states.len());
    for (s, line) in states.iter().zip(lines) {
        let v: Vec<i64> = line.split(' ').map(|t| t.parse().unwrap()).collect();
        let (best, margin) = choice(&q_f64(&w, &s.map(f64::from)));
        // The float header: the f64 choice wherever rounding cannot decide it.
        if margin > 1e-4 {
            assert_eq!(v[0], i64::from(duty(best)), "{s:?}: margin {margin}");
        }
        // The integer header: Rust's integer network bit for bit, and its duty that of its
        // outputs; the f64 choice where int8's rounding cannot decide it.
        let want: Vec<i64> = int.forward(&from_state(s)).map(i64::from).to_vec();
        assert_eq!(v[2..], want[..], "{s:?}");
        let int_best = firmware::network::argmax(&want);
        assert_eq!(v[1], i64::from(duty(int_best)), "{s:?}");
        if margin >= 0.02 {
            clear += 1;
            int_kept += usize::from(int_best == best);
        }
        chosen[best] += 1;
    }
    assert!(
        chosen.iter().all(|&c| c > 100),
        "every level chosen: {chosen:?}"
    );
    assert!(
        clear > 2500 && int_kept * 100 >= clear * 99,
        "{int_kept} of {clear}"
    );
}

#[test]
fn a_five_level_header_carries_its_duties_and_names_the_library_functions() {
    let w = weights::feedback::state_feedback(64, &LEVELS, GAIN).unwrap();
    let h = weights::source::c_header(&w, "gentle", &[], &Rig::GYMNASIUM).unwrap();
    assert!(h.contains("static const int16_t gentle_levels[5] = {-1000, -400, 0, 300, 1000};"));
    assert!(h.contains("static inline int16_t gentle_duty(const float q[5]) {"));
    assert!(h.contains("struct cartpole_mlp64x5 {"));
    assert!(h.contains(
        "void cartpole_mlp64x5_forward(const struct cartpole_mlp64x5 *w, const float obs[4], float q[5]);"
    ));
    assert!(h.contains(
        "cartpole_controller_init_mlp64x5(&ctl, &gentle, gentle_levels, 5, &gentle_rig)"
    ));
}

/// Names just outside each class the C library takes: of `<stdint.h>` (`INT` or `UINT` with
/// `_MAX`, `_MIN`, `_WIDTH` or `_C` needs both), of `<stddef.h>`, `errno` and `main`, and of
/// what the GNU dialects declare (a `_MAX` ending is no POSIX limit's).
const NEAR_NAMES: [&str; 16] = [
    "MY_INT8_MAX",
    "INT8_MAXIMUM",
    "UINT64_CONST",
    "INT_WIDTHS",
    "SIZE_MAX_",
    "MY_SIZE_MAX",
    "Null",
    "offset_of",
    "unreachable_",
    "Errno",
    "errno_",
    "main_",
    "y2",
    "random_",
    "POLICY_MAX",
    "SA_restart",
];

#[test]
fn names_just_outside_those_the_c_library_takes_compile_beside_it() {
    let w = weights::feedback::state_feedback(64, &LEVELS, GAIN).unwrap();
    let q = quant::quantise(&w, &observations(100), Granularity::PerChannel).unwrap();
    let dir = std::env::temp_dir().join(format!("weights-c-names-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut main = String::from(
        "#include <stdint.h>\n#include <stddef.h>\n#include <errno.h>\n#include <stdio.h>\n\
         #include <stdlib.h>\n#include <string.h>\n",
    );
    let mut sum = String::new();
    for (i, name) in NEAR_NAMES.iter().enumerate() {
        // Float and int8 headers in turn: both writers check the name alike.
        let header = if i % 2 == 0 {
            weights::source::c_header(&w, name, &[], &Rig::GYMNASIUM)
        } else {
            quant::c_header(&q, name, &[], &Rig::GYMNASIUM)
        };
        std::fs::write(dir.join(format!("{name}.h")), header.unwrap()).unwrap();
        let _ = writeln!(main, "#include \"{name}.h\"");
        let _ = write!(
            sum,
            " + (long){name}.fc3_bias[0] + {name}_levels[0] + (long){name}_rig.dead_time"
        );
    }
    let _ = write!(
        main,
        "int main(void) {{\n    printf(\"%ld\\n\", 0L{sum});\n    return 0;\n}}\n"
    );
    std::fs::write(dir.join("main.c"), main).unwrap();
    let out = compile_and_run(&dir);
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(out.lines().count(), 1, "{out}");
}
