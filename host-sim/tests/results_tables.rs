//! Every results table and value in README.md and docs/*.md, and every results file's page
//! (docs/results/NAME.md), is what `host-sim tables` renders from its file in docs/results/:
//! a table, figure or page edited by hand, or a results file measured again without its
//! documents rewritten, fails here. The other tests run the
//! command on a scratch root, to show that the check fails and that writing repairs.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn tables(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .arg("tables")
        .args(args)
        .current_dir(dir)
        .output()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn the_documents_tables_are_their_results() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let o = tables(&["--check"], &root);
    assert!(
        o.status.success(),
        "{}\nrun `cargo run -p host-sim -- tables` and commit the documents",
        stderr(&o)
    );
}

const JSON: &str = r#"{"seed": 0, "rows": [{"controller": "policy", "scenario": "noise",
  "horizon": 500, "success_rate": 0.75, "success_ci95": [0.7, 0.8], "failures": 250,
  "rms_theta_deg": {"mean": 0.5}, "rms_x_m": {"mean": 0.1}, "switches_per_s": {"mean": 30}}]}"#;

const TABLE: &str = "\
| scenario | policy success [95% CI] (failed) |
| --- | ---: |
| `noise` | 75.0% [70.0, 80.0] (250) |
";

/// A repository root with one results file and `docs` as its documents.
fn scratch(name: &str, docs: &[(&str, &str)]) -> PathBuf {
    let root = std::env::temp_dir().join(format!("host-sim-tables-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&root);
    std::fs::create_dir_all(root.join("docs/results")).unwrap();
    std::fs::write(root.join("Cargo.toml"), "[workspace]\n").unwrap();
    std::fs::write(root.join("docs/results/r.json"), JSON).unwrap();
    for (path, text) in docs {
        std::fs::write(root.join(path), text).unwrap();
    }
    root
}

#[test]
fn a_stale_table_or_value_fails_the_check_and_writing_repairs_it() {
    let doc = "# A\n\n<!-- results: docs/results/r.json success=policy -->\n| old |\n<!-- /results -->\n\
               It fails <!-- value: docs/results/r.json failures -->25<!-- /value --> times.\n";
    let fresh = doc.replace("| old |\n", TABLE).replace("-->25<", "-->250<");
    let root = scratch("stale", &[("README.md", &fresh), ("docs/A.md", doc)]);
    let check = tables(&["--check"], &root.join("docs"));
    assert_eq!(check.status.code(), Some(1), "{}", stderr(&check));
    let err = stderr(&check);
    assert!(
        err.contains("docs/A.md:3: the table differs from docs/results/r.json\n"),
        "{err}"
    );
    let value = "docs/A.md:6: the value \"25\" differs from docs/results/r.json's `250` (failures, no selector)\n";
    assert!(err.contains(value), "{err}");
    let page = "docs/results/r.md:1: the page differs from docs/results/r.json\n";
    assert!(err.contains(page), "{err}");
    assert!(
        err.contains("docs/results/README.md:1: the list of results pages"),
        "{err}"
    );
    assert!(!err.lines().any(|l| l.starts_with("README.md")), "{err}");
    let write = tables(&["--root", root.to_str().unwrap()], Path::new("/"));
    assert!(write.status.success(), "{}", stderr(&write));
    assert_eq!(
        std::fs::read_to_string(root.join("docs/A.md")).unwrap(),
        fresh
    );
    // The file's page: every row, and the command it would have recorded unknown.
    let page = std::fs::read_to_string(root.join("docs/results/r.md")).unwrap();
    assert!(page.starts_with("# r\n\n"), "{page}");
    assert!(page.contains("records no provenance"), "{page}");
    assert!(
        page.contains(
            "| `noise` | policy | - | 75.0% [70.0, 80.0] | 250 | - | 0.500 | 0.100 | - | 30.0 | - |"
        ),
        "{page}"
    );
    assert!(tables(&["--check"], &root).status.success());
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_bad_marker_or_a_missing_file_exits_2_and_writes_nothing() {
    let stale = "<!-- results: docs/results/r.json success=policy -->\n<!-- /results -->\n";
    let cases = [
        (
            "<!-- results: docs/results/gone.json success=policy -->\n<!-- /results -->\n",
            "docs/B.md:2: reading docs/results/gone.json",
        ),
        (
            "<!-- results: docs/results/r.json colour=red -->\n<!-- /results -->\n",
            "docs/B.md:2: unknown option \"colour=red\"",
        ),
        (
            "<!-- results: docs/results/r.json success=policy -->\n",
            "docs/B.md:2: no `<!-- /results -->` line",
        ),
        (
            "It fails <!-- value: docs/results/r.json controller=lqr failures -->1<!-- /value -->.\n",
            "docs/B.md:2: no row of docs/results/r.json matches \"controller=lqr\"",
        ),
        (
            "It fails <!-- value: docs/results/r.json failures -->1 times.\n",
            "docs/B.md:2: no `<!-- /value -->` follows this value on its line",
        ),
    ];
    for (i, (bad, want)) in cases.into_iter().enumerate() {
        let root = scratch(
            &format!("bad{i}"),
            &[("docs/A.md", stale), ("docs/B.md", &format!("x\n{bad}"))],
        );
        for args in [&["--check"][..], &[]] {
            let o = tables(args, &root);
            assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
            assert!(stderr(&o).contains(want), "{args:?}: {}", stderr(&o));
        }
        let a = std::fs::read_to_string(root.join("docs/A.md")).unwrap();
        assert_eq!(a, stale, "a refusal in one document left another rewritten");
        let _ = std::fs::remove_dir_all(&root);
    }
    // A page that cannot be replaced: refused before any document is written.
    let root = scratch("page", &[("docs/A.md", stale)]);
    std::fs::create_dir(root.join("docs/results/r.md")).unwrap();
    let o = tables(&[], &root);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("found a directory"), "{}", stderr(&o));
    let a = std::fs::read_to_string(root.join("docs/A.md")).unwrap();
    assert_eq!(a, stale, "a refused page left a document rewritten");
    let _ = std::fs::remove_dir_all(&root);
    // A manifest that links to nothing is not taken for none.
    let root = scratch("dangling", &[("docs/A.md", stale)]);
    std::os::unix::fs::symlink(
        root.join("gone.toml"),
        root.join("docs/results/manifest.toml"),
    )
    .unwrap();
    let o = tables(&[], &root);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("manifest.toml"), "{}", stderr(&o));
    let _ = std::fs::remove_dir_all(&root);
}

/// A number in a results file that reads as zero (`1e-400`) was read as 0 and shown as
/// measured, by a table and by `results moved`: refused by name, nothing written.
#[test]
fn a_hidden_zero_in_a_results_file_is_refused() {
    let doc = "<!-- results: docs/results/r.json success=policy -->\n<!-- /results -->\n";
    let root = scratch("zero", &[("docs/A.md", doc)]);
    let r = root.join("docs/results/r.json");
    let old = root.join("old.json");
    std::fs::write(&old, JSON).unwrap();
    std::fs::write(&r, JSON.replace("\"mean\": 0.5", "\"mean\": 1e-400")).unwrap();
    for o in [
        tables(&[], &root),
        Command::new(env!("CARGO_BIN_EXE_host-sim"))
            .args(["results", "moved"])
            .args([&old, &r])
            .output()
            .unwrap(),
    ] {
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(
            stderr(&o).contains("r.json: line 3, column"),
            "{}",
            stderr(&o)
        );
        assert!(stderr(&o).contains("1e-400 reads as 0"), "{}", stderr(&o));
        assert!(o.stdout.is_empty());
    }
    assert_eq!(
        std::fs::read_to_string(root.join("docs/A.md")).unwrap(),
        doc
    );
    let _ = std::fs::remove_dir_all(&root);
}

/// A kind of file, the words that refuse it, and how to make one.
type Maker = (&'static str, &'static str, fn(&Path));

/// A document that is no regular file (a directory, a FIFO, a link to nothing or to a
/// device) was skipped without a word, and a FIFO as a page hung: each is refused by name,
/// nothing written.
#[test]
fn a_document_that_is_no_regular_file_is_refused() {
    let stale = "<!-- results: docs/results/r.json success=policy -->\n<!-- /results -->\n";
    let makers: [Maker; 4] = [
        ("dir", "found a directory", |p| {
            std::fs::create_dir(p).unwrap()
        }),
        ("fifo", "found a FIFO", |p| {
            let made = std::process::Command::new("mkfifo").arg(p).status();
            assert!(made.unwrap().success());
        }),
        ("gone", "docs/Z.md", |p| {
            std::os::unix::fs::symlink(p.with_extension("gone"), p).unwrap()
        }),
        ("device", "docs/Z.md", |p| {
            std::os::unix::fs::symlink("/dev/zero", p).unwrap()
        }),
    ];
    for (name, want, make) in makers {
        let root = scratch(&format!("odd-{name}"), &[("docs/A.md", stale)]);
        make(&root.join("docs/Z.md"));
        let o = tables(&[], &root);
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        assert!(stderr(&o).contains(want), "{name}: {}", stderr(&o));
        let a = std::fs::read_to_string(root.join("docs/A.md")).unwrap();
        assert_eq!(a, stale, "{name}: a refusal left a document rewritten");
        let _ = std::fs::remove_dir_all(&root);
    }
    // A FIFO where a page goes was opened and waited on for ever, `--check` too.
    for page in ["docs/results/r.md", "docs/results/README.md"] {
        let root = scratch("odd-page", &[("docs/A.md", stale)]);
        (makers[1].2)(&root.join(page));
        for args in [&["--check"][..], &[]] {
            let o = tables(args, &root);
            assert_eq!(o.status.code(), Some(2), "{page}: {}", stderr(&o));
            assert!(
                stderr(&o).contains("found a FIFO"),
                "{page}: {}",
                stderr(&o)
            );
        }
        let _ = std::fs::remove_dir_all(&root);
    }
}

/// Text a results file gives reaches its page escaped: an argument with an escape sequence,
/// a backtick and a line break, a CPU named with a bell, a controller with a line break,
/// each a `|` besides, broke the page's table and headed it anew, with the control
/// characters raw. A file's name is its page's name and a link's target, so a name that
/// would need escaping there is refused before anything is written.
#[test]
fn text_from_a_results_file_is_escaped_and_an_unplain_name_refused() {
    let hostile = JSON
        .replace("\"policy\"", "\"lqr\\n# ctl \\u001b | x\"")
        .replace(
            "\"seed\": 0,",
            "\"provenance\": {\"tool\": \"host-sim\", \"argv\": [\"\\u001b[2J`\\n# injected | x\"], \
             \"date\": \"2026-12-07T08:52:11Z\", \"revision\": \"unknown\", \"dirty\": false, \
             \"nproc\": 2, \"cpu\": \"cpu\\u0007\\n| evil |\"}, \"seed\": 0,",
        );
    let root = scratch("escaped", &[("docs/results/r.json", &hostile)]);
    let o = tables(&["--root", root.to_str().unwrap()], Path::new("/"));
    assert!(o.status.success(), "{}", stderr(&o));
    for page in ["docs/results/r.md", "docs/results/README.md"] {
        let text = std::fs::read_to_string(root.join(page)).unwrap();
        assert!(!text.chars().any(|c| c.is_control() && c != '\n'), "{text}");
        for line in text.lines() {
            assert!(
                !line.starts_with("# injected") && !line.starts_with("| evil"),
                "{text}"
            );
        }
        // Every row of a table has its header's cells: no `|` of the input splits one.
        let cells = |l: &str| l.matches('|').count() - l.matches("\\|").count();
        let rows: Vec<&str> = text.lines().filter(|l| l.starts_with('|')).collect();
        assert!(rows.iter().all(|l| cells(l) == cells(rows[0])), "{text}");
    }
    let page = std::fs::read_to_string(root.join("docs/results/r.md")).unwrap();
    assert!(
        page.contains("- command: `host-sim \\u{1b}[2J\\u{60}\\n# injected \\| x`\n"),
        "{page}"
    );
    assert!(
        page.contains("| `noise` | lqr\\n# ctl \\u{1b} \\| x | "),
        "{page}"
    );
    assert!(
        page.contains("- machine: 2 CPUs, cpu\\u{7}\\n\\| evil \\|\n"),
        "{page}"
    );
    let _ = std::fs::remove_dir_all(&root);
    for name in [
        "a\u{1b}[2Jb.json",
        "a|b\n## injected](javascript:x) <script>.json",
    ] {
        let root = scratch("unplain", &[(&format!("docs/results/{name}"), JSON)]);
        let o = tables(&["--root", root.to_str().unwrap()], Path::new("/"));
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(
            err.contains("expected a results file named with ASCII letters, digits"),
            "{err}"
        );
        assert!(!err.trim_end().contains(['\n', '\u{1b}']), "{err}");
        assert!(!root.join("docs/results/README.md").exists());
        assert!(!root.join("docs/results/r.md").exists());
        let _ = std::fs::remove_dir_all(&root);
    }
}

/// `results steps` on a scratch root whose manifest is `manifest`.
fn steps(name: &str, manifest: &str) -> Output {
    let root = scratch(name, &[("docs/results/manifest.toml", manifest)]);
    let o = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["results", "steps", "--root"])
        .arg(&root)
        .output()
        .unwrap();
    std::fs::remove_dir_all(&root).unwrap();
    o
}

/// What `scripts/regenerate.sh` reads of each line (its own `read`): runs of tabs are one
/// separator to it, so an empty field shifted the ones after it and the about ran.
const READ: &str = "IFS=$'\\t' read -r name cost needs rebuild printed output prepare run about; \
                    printf '%s|%s|%s|%s' \"$output\" \"$prepare\" \"$run\" \"$about\"";

#[test]
fn the_steps_read_back_field_for_field_and_a_field_they_cannot_carry_is_refused() {
    let step = "[[step]]\nname = \"a\"\nabout = \"the about\"\nrun = \"echo hi\"\n\
                prepare = \"true\"\noutput = \"o\"\ncost = 1\n";
    let o = steps("steps-ok", step);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut bash = Command::new("bash")
        .args(["-c", READ])
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    use std::io::Write;
    bash.stdin.take().unwrap().write_all(&o.stdout).unwrap();
    let read = bash.wait_with_output().unwrap();
    assert_eq!(
        String::from_utf8_lossy(&read.stdout),
        "o|true|echo hi|the about"
    );
    let cases = [
        (
            "output = \"o\"",
            "output = \"\"",
            "step \"a\": output: expected",
        ),
        (
            "prepare = \"true\"",
            "prepare = \"\"",
            "step \"a\": prepare: expected a command",
        ),
        (
            "output = \"o\"",
            "output = \"-\"",
            "step \"a\": output: expected",
        ),
        (
            "prepare = \"true\"",
            "prepare = \"-\"",
            "the steps' list's mark for none",
        ),
        (
            "output = \"o\"",
            "output = \"/etc/passwd\"",
            "(an absolute path)",
        ),
        ("output = \"o\"", "output = \"../../x\"", "(a `..` part)"),
        (
            "output = \"o\"",
            "output = \"docs/\"\nstdout = true",
            "(a name ending in `/`)",
        ),
        (
            "the about",
            "the\u{2028}about",
            "step \"a\": about: expected no control",
        ),
    ];
    for (k, (from, to, want)) in cases.into_iter().enumerate() {
        let o = steps(&format!("steps-{k}"), &step.replace(from, to));
        assert_eq!(o.status.code(), Some(2), "{to}: {}", stderr(&o));
        assert!(o.stdout.is_empty(), "{to}: nothing printed");
        assert!(stderr(&o).contains(want), "{want}: {}", stderr(&o));
    }
    let twice = format!("{step}{}", step.replace("\"a\"", "\"b\""));
    let o = steps("steps-twice", &twice);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("step \"a\": output \"o\" is step \"b\"'s too"),
        "{}",
        stderr(&o)
    );
}
