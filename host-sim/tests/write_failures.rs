//! Outputs that cannot be written (`docs/FILES.md`): `render`, `identify` and
//! `startup --render` run with their files limited in size, so that a write fails as on a
//! full disk (EFBIG). Each exits 1 naming
//! the file it could not write, in the system's words and never plotters' Debug text, and
//! leaves every old output as it was (all of a command's outputs or none), no temporary and
//! no directory it created; `startup` prints its report first. And `host_sim::batch::Batch`,
//! which puts the files in place together, on its own.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use host_sim::batch::Batch;

// The shared harness: its scratch directories and listings.
#[allow(dead_code)]
#[path = "../../host-common/tests/support/hostile.rs"]
mod hostile;

use hostile::{Scratch, entries};

fn exe() -> &'static str {
    env!("CARGO_BIN_EXE_host-sim")
}

fn repo(path: &str) -> String {
    format!("{}/../{path}", env!("CARGO_MANIFEST_DIR"))
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn run(args: &[&str]) -> Output {
    let o = Command::new(exe()).args(args).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    o
}

/// host-sim with `args`, no file it writes larger than `bytes`: a write past it fails with
/// EFBIG, as on a full disk (SIGXFSZ ignored, which the command inherits).
fn limited(bytes: u64, args: &[&str]) -> Output {
    Command::new("bash")
        .args(["-c", r#"trap "" XFSZ; exec prlimit --fsize="$0" -- "$@""#])
        .arg(bytes.to_string())
        .arg(exe())
        .args(args)
        .output()
        .unwrap()
}

/// Exit 1, `file` named with what failed (`what`), no Debug text.
fn failed_writing(o: &Output, file: &Path, what: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    let said = format!("error: writing {}: {what}", file.display());
    assert!(err.contains(&said), "{said:?} not in {err}");
    for debug in ["BackendError", "Os {", "kind:", "Error("] {
        assert!(!err.contains(debug), "{err}");
    }
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap()
}

const PAIR: [&str; 2] = ["episode.gif", "episode.png"];

/// `render` into `out` from the start of `seed`.
fn render<'a>(out: &'a Path, horizon: &'static str, seed: &'static str) -> [&'a str; 7] {
    [
        "render",
        "--out",
        s(out),
        "--horizon",
        horizon,
        "--seed",
        seed,
    ]
}

#[test]
fn render_on_a_full_disk_keeps_the_old_pair_whichever_picture_fails() {
    let t = Scratch::new("render");
    let (pics, sizes) = (t.join("pics"), t.join("sizes"));
    run(&render(&pics, "20", "1"));
    run(&render(&sizes, "20", "2"));
    let old = PAIR.map(|p| read(&pics.join(p)));
    let fresh = PAIR.map(|p| read(&sizes.join(p)));
    assert_ne!(old, fresh);
    // The PNG is the larger: a limit of the GIF's size fails the second picture only.
    assert!(fresh[1].len() > fresh[0].len());
    for (limit, failing) in [
        (4096, "episode.gif"),
        (fresh[0].len() as u64, "episode.png"),
    ] {
        let o = limited(limit, &render(&pics, "20", "2"));
        failed_writing(&o, &pics.join(failing), "File too large");
        assert_eq!(PAIR.map(|p| read(&pics.join(p))), old, "{failing}");
        assert_eq!(entries(&pics), PAIR);
    }
}

#[test]
fn render_into_new_directories_on_a_full_disk_leaves_none() {
    let t = Scratch::new("render-new");
    let out = t.join("new/pics");
    let o = limited(4096, &["render", "--out", s(&out), "--horizon", "4"]);
    failed_writing(&o, &out.join("episode.gif"), "File too large");
    assert!(entries(&t.0).is_empty());
}

/// A picture's place made a directory while the pictures are drawn (the child stopped
/// while it is done): nothing is renamed, the old GIF stays, no temporary is left.
/// `identify` of `log` on the measured desk rig, writing `out` and `plots`.
fn identify<'a>(log: &'a Path, out: &'a Path, plots: &'a Path) -> [&'a str; 8] {
    let measured = concat!(env!("CARGO_MANIFEST_DIR"), "/../rigs/desk-measured.toml");
    let (out, plots) = (s(out), s(plots));
    [
        "identify",
        "--rig",
        measured,
        "--out",
        out,
        "--plots",
        plots,
        s(log),
    ]
}

#[test]
fn identify_on_a_full_disk_writes_neither_its_rig_file_nor_its_plots() {
    let t = Scratch::new("identify");
    let log = t.join("sim.log");
    let (desk, measured) = (repo("rigs/desk.toml"), repo("rigs/desk-measured.toml"));
    let world = ["--world", &desk, "--rig", &measured];
    let short = ["--cart-s", "3", "--swing-s", "3", "--out", s(&log)];
    run(&[&["simulate-logs"][..], &world, &short].concat());
    // Every plot's size, to fail the first PNG only once its SVG is written.
    let sizes = t.join("sizes");
    run(&identify(&log, &sizes.join("x.toml"), &sizes));
    let [svg, png] = ["svg", "png"].map(|e| {
        let plot = sizes.join(format!("identify-1-cart.{e}"));
        std::fs::metadata(plot).unwrap().len()
    });
    assert!(png > svg);
    std::fs::remove_dir_all(&sizes).unwrap();
    // Old outputs, and new places two directories deep.
    let (rig, plots) = (t.join("old.toml"), t.join("plots"));
    std::fs::create_dir(&plots).unwrap();
    std::fs::write(&rig, "old rig\n").unwrap();
    std::fs::write(plots.join("identify-1-cart.png"), "old plot").unwrap();
    let (new_rig, new_plots) = (t.join("new/deeper/x.toml"), t.join("new/plots"));
    for (limit, failing) in [
        (20_000, "identify-1-cart.svg"),
        (svg, "identify-1-cart.png"),
    ] {
        let o = limited(limit, &identify(&log, &rig, &plots));
        failed_writing(&o, &plots.join(failing), "File too large");
        assert_eq!(read(&rig), b"old rig\n");
        assert_eq!(entries(&plots), ["identify-1-cart.png"]);
        assert_eq!(read(&plots.join("identify-1-cart.png")), b"old plot");
        let o = limited(limit, &identify(&log, &new_rig, &new_plots));
        failed_writing(&o, &new_plots.join(failing), "File too large");
        assert_eq!(entries(&t.0), ["old.toml", "plots", "sim.log"]);
    }
}

#[test]
fn startup_on_a_full_disk_prints_its_report_then_fails_naming_the_picture() {
    let t = Scratch::new("startup");
    let out = t.join("new/pics");
    let args = ["startup", "--episodes", "2", "--within", "5", "--hold", "1"];
    let o = limited(4096, &[&args[..], &["--render", s(&out)]].concat());
    failed_writing(&o, &out.join("episode.gif"), "File too large");
    let report = String::from_utf8_lossy(&o.stdout);
    assert!(
        report.contains("start-up from Hanging") && report.contains("int8"),
        "{report}"
    );
    assert!(entries(&t.0).is_empty());
}

/// Files `dir/NAME` holding `text`, for each (NAME, text).
fn files(dir: &Path, named: &[(&str, &str)]) -> Vec<PathBuf> {
    named
        .iter()
        .map(|(n, text)| {
            let p = dir.join(n);
            std::fs::write(&p, text).unwrap();
            p
        })
        .collect()
}

#[test]
fn a_batch_puts_every_file_in_place_or_every_old_one_back() {
    let t = Scratch::new("batch");
    let old = files(&t.0, &[("a", "old a"), ("b", "old b")]);
    let (a, b) = (&old[0], &old[1]);
    let batch = |write_second: bool| {
        let mut batch = Batch::default();
        std::fs::write(batch.file(a).unwrap(), "new a").unwrap();
        let tb = batch.file(b).unwrap();
        if write_second {
            std::fs::write(tb, "new b").unwrap();
        }
        batch.commit()
    };
    // The second rename fails (its temporary is missing) once the first is done.
    let e = batch(false).unwrap_err().to_string();
    assert!(e.starts_with(&format!("writing {}: ", b.display())), "{e}");
    assert_eq!([read(a), read(b)], [b"old a", b"old b"]);
    assert_eq!(entries(&t.0), ["a", "b"]);
    // A place taken by a directory: nothing is renamed.
    std::fs::remove_file(b).unwrap();
    std::fs::create_dir(b).unwrap();
    let e = batch(true).unwrap_err().to_string();
    let found = "expected a regular file (or nothing), found a directory";
    assert!(e.ends_with(found), "{e}");
    assert_eq!(read(a), b"old a");
    assert_eq!(entries(&t.0), ["a", "b"]);
    std::fs::remove_dir(b).unwrap();
    batch(true).unwrap();
    assert_eq!([read(a), read(b)], [b"new a", b"new b"]);
    assert_eq!(entries(&t.0), ["a", "b"]);
}

#[test]
fn a_batch_writes_through_nothing_planted_and_puts_back_what_a_killed_commit_set_aside() {
    let t = Scratch::new("batch-planted");
    let victim = t.join("victim");
    std::fs::create_dir(&victim).unwrap();
    let a = t.join("a");
    // A link at the private directory's name, to a directory elsewhere.
    let private = t.join(&format!(".a.{}.d", std::process::id()));
    std::os::unix::fs::symlink(&victim, &private).unwrap();
    let mut batch = Batch::default();
    let tmp = batch.file(&a).unwrap();
    std::fs::write(&tmp, "new").unwrap();
    assert!(std::fs::symlink_metadata(&private).unwrap().is_dir());
    assert!(entries(&victim).is_empty());
    batch.commit().unwrap();
    assert_eq!(read(&a), b"new");
    assert_eq!(entries(&t.0), ["a", "victim"]);
    // A commit killed after moving the old file aside: the place is empty, the old file
    // under its second name; the next batch puts it back before anything else.
    std::fs::rename(&a, t.join(".a.4000000000.old")).unwrap();
    let batch = Batch::default().file(&a).map(drop);
    batch.unwrap();
    assert_eq!(read(&a), b"new");
    assert_eq!(entries(&t.0), ["a", "victim"]);
}

#[test]
fn a_batch_dropped_uncommitted_removes_its_temporaries_and_its_directories() {
    let t = Scratch::new("batch-drop");
    std::fs::create_dir(t.join("kept")).unwrap();
    let mut batch = Batch::default();
    let inner = t.join("made/deeper");
    batch.dir(&inner).unwrap();
    batch.dir(&t.join("kept/made")).unwrap();
    std::fs::write(batch.file(&inner.join("x")).unwrap(), "x").unwrap();
    drop(batch);
    assert_eq!(entries(&t.0), ["kept"]);
    assert!(entries(&t.join("kept")).is_empty());
}

#[test]
fn a_batch_writes_outputs_whose_names_share_their_first_200_bytes() {
    let t = Scratch::new("batch-long");
    let common = "p".repeat(200);
    let (a, b) = (
        t.join(&format!("{common}a.png")),
        t.join(&format!("{common}b.png")),
    );
    let mut batch = Batch::default();
    // Each temporary in a private directory named after its output's hidden name: one
    // shared by the two made the second take the first's away.
    std::fs::write(batch.file(&a).unwrap(), "a").unwrap();
    std::fs::write(batch.file(&b).unwrap(), "b").unwrap();
    batch.commit().unwrap();
    assert_eq!((read(&a), read(&b)), (b"a".to_vec(), b"b".to_vec()));
    assert_eq!(entries(&t.0).len(), 2);
}

#[test]
fn tables_on_a_full_disk_rewrites_no_document() {
    let t = Scratch::new("tables");
    std::fs::create_dir_all(t.join("docs/results")).unwrap();
    std::fs::write(t.join("Cargo.toml"), "[workspace]\n").unwrap();
    std::fs::copy(
        repo("docs/results/eval-shipped.json"),
        t.join("docs/results/r.json"),
    )
    .unwrap();
    // A small stale document, then a page of the results file far over the limit.
    let doc = "It fails <!-- value: docs/results/r.json scenario=nominal horizon=500 \
               controller=policy failures -->99<!-- /value --> times.\n";
    let a = t.join("docs/A.md");
    std::fs::write(&a, doc).unwrap();
    let o = limited(4096, &["tables", "--root", s(&t.0)]);
    failed_writing(&o, &t.join("docs/results/r.md"), "File too large");
    assert_eq!(read(&a), doc.as_bytes());
    assert_eq!(entries(&t.join("docs/results")), ["r.json"]);
}

/// Under a umask that takes the owner's own access (`umask 777`), every output is refused
/// before the work, and nothing made: a directory made for `render --out` could not be
/// written in, which it found after drawing (exit 1), and a user the permissions hold
/// could not read what it wrote. Root, which no permission stops, is refused alike.
#[test]
fn a_umask_that_takes_the_owners_access_is_refused_before_the_work() {
    let dir = Scratch::new("umask");
    let out = dir.join("pics/new");
    let under = |mask: &str, args: &[&str]| {
        let script = format!("umask {mask} && exec \"$0\" \"$@\"");
        let mut c = Command::new("sh");
        c.args(["-c", &script, exe()]).args(args);
        hostile::run_counted(&mut c)
    };
    let render = [
        "render",
        "--controller",
        "lqr",
        "--horizon",
        "20",
        "--out",
        s(&out),
    ];
    let (world, rig) = (repo("rigs/desk.toml"), repo("rigs/desk-measured.toml"));
    let logs = [
        "simulate-logs",
        "--world",
        &world,
        "--rig",
        &rig,
        "--out",
        s(&out),
    ];
    for (mask, args) in [("777", &render[..]), ("200", &render), ("777", &logs)] {
        let ran = under(mask, args);
        assert_eq!(ran.code, Some(2), "{mask} {args:?}: {}", ran.stderr);
        assert!(
            ran.stderr
                .contains(&format!("the process's umask 0{mask} takes"))
                && ran.stderr.contains("such as 0022 or 0077"),
            "{}",
            ran.stderr
        );
        assert!(ran.late().is_none(), "{:?}", ran.cpu);
        assert!(entries(&dir.0).is_empty(), "{:?}", entries(&dir.0));
    }
}
