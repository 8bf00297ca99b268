//! The hostile suite's worlds: scenario specs and rig files no command can take, because
//! they are malformed, or because a value in them would be dropped, or meaningless, or would
//! make the physics NaN (counted as an episode that never fails).

use std::ffi::OsString;

use super::hostile::{Case, Scratch};
use super::{os, repo};

/// Scenario specs no command can take.
pub fn bad_specs() -> Vec<Case> {
    let mut cases = Vec::new();
    let long = "x".repeat(5_000);
    let specs = [
        "nominal+mass=2",
        "wind=3",
        "mass",
        "mass=abc",
        "mass=1e300",
        "length=999+length=999",
        "noise=-1",
        "delay=99",
        "+",
        "mass=1..0",
        "mass=2@7",
        &long,
        // A part given again replaced the first; only factors multiply.
        "noise=1+noise=2",
        "delay=1+delay=3",
        "encoder=128+encoder=512",
        "push=1/50+push=2/60",
        // Subnormal: a slip, lost in the physics.
        "noise=1e-320",
        // A pivot friction the steps cannot follow: NaN worlds counted as balanced.
        "friction=0/0.1+polemass=0.001+length=0.001",
        // Nothing, or nothing after a comma: not the nominal world, which has a name.
        "",
        "nominal,",
        // Parts at values that change nothing: the nominal world under another name.
        "nominal,zero=0",
        "push=0/9",
        "weak=1/5",
        "jitter=0",
        // At values that change nothing on the machine the episodes run on (Gymnasium's).
        "length=2+length=0.5",
        "delay=0",
        // Parts without what they need beside them: the same episodes under another name.
        "noise+jitter=0.5",
        "encoder=1024+zero=0.1/0.09",
        // A discount the board's f32 holds as a subnormal.
        "encoder=2400/15000/1e-40",
        // A stretch past its interval, which holds in every period whatever K; a weak motor
        // in every period, which is `force=F`.
        "stuck=10/5",
        "weak=0.5/600/500",
        "weak=0.5/500/500",
        // Sensing parts where no reading they touch reaches the board.
        "drop=1+noise",
        "stuck=3/3+glitch",
    ];
    for spec in specs {
        for cmd in [
            &["eval", "--episodes", "1"][..],
            &["render", "--horizon", "5", "--out", "r"],
        ] {
            let mut args: Vec<OsString> = cmd.iter().map(OsString::from).collect();
            args.extend([OsString::from("--scenario"), OsString::from(spec)]);
            let label: String = format!("{cmd:?} --scenario {spec}")
                .chars()
                .take(60)
                .collect();
            cases.push(Case::new(
                label,
                &args,
                &[
                    "expected",
                    "unknown part",
                    "needs",
                    "must be",
                    "comes to",
                    "changes nothing",
                ],
            ));
        }
    }
    cases
}

/// Rig files that were read with a value dropped or meaningless, and worlds whose physics
/// became NaN: each given as every rig a command takes.
pub fn bad_rigs(s: &Scratch) -> Vec<Case> {
    let desk = std::fs::read_to_string(repo("rigs/desk.toml")).unwrap();
    let edits: [(&str, &str, &str); 6] = [
        (
            "accel",
            "",
            "\n[observer]\nforce_sd = 1.0\naccel_sd = [1.0, 2.0, 3.0]\n",
        ),
        (
            "euler",
            "",
            "\n[world]\nintegration = \"euler\"\nsubstep_s = 0.0001\n",
        ),
        ("subnormal", "cart_coulomb = 0.0", "cart_coulomb = 5e-324"),
        (
            "gravity",
            "cart_mass_kg",
            "gravity_m_s2 = 1e-310\ncart_mass_kg",
        ),
        (
            "damping",
            "damping_n_s_per_m = 3.0",
            "damping_n_s_per_m = 3000.0",
        ),
        ("pivot", "pole_mass_kg = 0.08", "pole_mass_kg = 0.0001"),
    ];
    let measured = repo("rigs/desk-measured.toml");
    let mut cases = Vec::new();
    for (tag, from, to) in edits {
        let path = s.join(&format!("rig-{tag}.toml"));
        let text = match from {
            "" => format!("{desk}{to}"),
            _ => desk.replacen(from, to, 1),
        };
        let text = if tag == "pivot" {
            text.replacen("pivot_viscous_n_m_s = 0.0", "pivot_viscous_n_m_s = 0.1", 1)
        } else {
            text
        };
        std::fs::write(&path, text).unwrap();
        let eval = "eval --episodes 1 --horizon 5 --scenario nominal --controller lqr --rig";
        let mut args: Vec<OsString> = eval.split(' ').map(OsString::from).collect();
        args.push(path.clone().into());
        cases.push(Case::new(format!("eval --rig {tag}"), &args, &["expected"]));
        let out = s.join("rig-logs.log");
        let simulate = os(&[
            &"simulate-logs",
            &"--world",
            &path,
            &"--rig",
            &measured,
            &"--out",
            &out,
        ]);
        cases.push(Case::new(
            format!("simulate-logs --world {tag}"),
            &simulate,
            &["expected"],
        ));
    }
    cases.push(damping_scenario());
    cases
}

/// A motor damping the desk rig's steps cannot follow, through a scenario.
fn damping_scenario() -> Case {
    let damping = os(&[
        &"eval",
        &"--episodes",
        &"1",
        &"--horizon",
        &"5",
        &"--controller",
        &"lqr",
        &"--rig",
        &repo("rigs/desk.toml"),
        &"--scenario",
        &"damping=1000",
    ]);
    Case::new("eval damping=1000 on desk".into(), &damping, &["expected"])
}

/// Rows of `eval` asked for twice: the table showed one row twice.
pub fn bad_rows() -> Vec<Case> {
    let base = ["eval", "--episodes", "1", "--horizon", "3"];
    let twice: [&[&str]; 4] = [
        &["--scenario", "all,noise", "--controller", "lqr"],
        &["--scenario", "nominal", "--scenario", "nominal"],
        &["--scenario", "nominal", "--controller", "lqr,rule,lqr"],
        &["--scenario", "nominal", "--horizon", "3"],
    ];
    let mut cases: Vec<Case> = twice
        .iter()
        .map(|extra| {
            let args: Vec<&str> = base.iter().chain(extra.iter()).copied().collect();
            Case::new(format!("{args:?}"), &args, &["expected each row once"])
        })
        .collect();
    cases.extend(one_world(&base));
    // One world on the machine the episodes run on: the desk's own dead time and encoders.
    let desk = repo("rigs/desk.toml");
    for (specs, want) in [
        (
            "nominal,delay",
            "\"delay\": delay changes nothing on this machine, whose own dead time is 1 period;",
        ),
        (
            "encoder,encoder=2400/15000",
            "found \"encoder\" and \"encoder=2400/15000\", which build one world on this machine",
        ),
        // Gymnasium's candidate pool, which would run in Gymnasium's world under the desk's name.
        (
            "hard-candidates",
            "expected `hard-candidates` on Gymnasium's machine, where the `hard` set was chosen \
             from its rows; found another rig or world",
        ),
    ] {
        let mut args = os(&[&"eval", &"--controller", &"lqr", &"--rig", &desk]);
        args.extend(os(&[&"--episodes", &"1", &"--scenario", &specs]));
        cases.push(Case::new(
            format!("eval on desk --scenario {specs}"),
            &args,
            &[want],
        ));
    }
    let mut args = os(&[&"eval", &"--controller", &"lqr", &"--world", &desk]);
    args.extend(os(&[
        &"--episodes",
        &"1",
        &"--scenario",
        &"hard-candidates",
    ]));
    cases.push(Case::new(
        "eval --world desk --scenario hard-candidates".into(),
        &args,
        &["expected `hard-candidates` on Gymnasium's machine"],
    ));
    cases
}

/// Two specs of one world on Gymnasium's machine, as eval's rows (`base` its flags): however
/// a spec is written (a default written out, -0, a factor's product), and by how the world
/// runs (readings stuck for good whatever K, a zero error through encoders by the whole
/// counts it adds).
fn one_world(base: &[&str]) -> Vec<Case> {
    let mut cases = Vec::new();
    for (specs, want) in [
        ("noise,noise=1", "one scenario spelt twice"),
        ("push=0.5/100,push", "one scenario spelt twice"),
        ("zero=0/1,zero=-0/1", "one scenario spelt twice"),
        ("length=2+length=2,length=4", "one scenario spelt twice"),
        (
            "length=0.9+length=1.6+length=1.5,length=1.5+length=1.6+length=0.9",
            "one scenario spelt twice",
        ),
        (
            "stuck=5/5,stuck=1/1",
            "which build one world on this machine",
        ),
        (
            "encoder+zero=0.06,encoder+zero=0.07",
            "which build one world on this machine",
        ),
    ] {
        let args: Vec<&str> = base.iter().copied().chain(["--scenario", specs]).collect();
        cases.push(Case::new(format!("{args:?}"), &args, &[want]));
    }
    cases
}
