use super::*;

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("outdir-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A run that fails leaves none of the directories made to hold it (a `train` that
/// stopped on a non-finite loss left `new/deeper/`); one committed keeps them.
#[test]
fn the_directories_made_for_a_run_go_with_it_unless_it_is_committed() {
    let dir = scratch("made");
    let dest = dir.join("new/deeper/run");
    drop(Staging::new(&dest, "train").unwrap());
    assert!(!dir.join("new").exists());
    let st = Staging::new(&dest, "train").unwrap();
    std::fs::write(st.path().join("a"), b"x").unwrap();
    st.commit().unwrap();
    assert!(dest.join("a").is_file());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `run/../run` runs through the destination, which the commit moves aside: it replaces
/// the earlier output whole, as `run` does. `run/.` names no entry a rename can replace.
#[test]
fn a_destination_named_through_itself_is_replaced_whole_or_refused() {
    let dir = scratch("through");
    let dest = dir.join("run");
    let write = |at: &Path, text: &[u8]| {
        let st = Staging::new(at, "train").unwrap();
        std::fs::write(st.path().join("summary.json"), text).unwrap();
        st.commit().unwrap();
    };
    write(&dest, b"first");
    write(&dest.join("..").join("run"), b"second");
    assert_eq!(std::fs::read(dest.join("summary.json")).unwrap(), b"second");
    let left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left, ["run"]);
    for dotted in [dest.join("."), dir.join("run/.")] {
        let e = check_output_dir(&dotted, "train").unwrap_err().to_string();
        assert!(e.contains("it is not a directory's name"), "{e}");
    }
    assert_eq!(std::fs::read(dest.join("summary.json")).unwrap(), b"second");
}

#[test]
fn a_committed_staging_replaces_only_its_own_kind_holding_only_its_files() {
    let dir = scratch("commit");
    let dest = dir.join("run");
    let st = Staging::new(&dest, "train").unwrap();
    std::fs::create_dir(st.path().join("seed-1")).unwrap();
    std::fs::write(st.path().join("seed-1/summary.json"), b"{}").unwrap();
    std::fs::write(st.path().join("aggregate.json"), b"{}").unwrap();
    st.commit().unwrap();
    let found = listing(&dest).unwrap();
    assert_eq!(found, ["aggregate.json", "seed-1/", "seed-1/summary.json"]);
    assert_eq!(proof(&dest, "train", &found).unwrap(), [Found::Owned; 3]);
    check_output_dir(&dest, "train").unwrap();
    let e = check_output_dir(&dest, "reproduce")
        .unwrap_err()
        .to_string();
    assert!(e.contains("not of policy-export reproduce"), "{e}");
    std::fs::write(dest.join("seed-1/notes.txt"), b"mine").unwrap();
    let e = check_output_dir(&dest, "train").unwrap_err().to_string();
    assert!(
        e.contains("1 entry policy-export did not write (\"seed-1/notes.txt\")"),
        "{e}"
    );
    std::fs::remove_file(dest.join("seed-1/notes.txt")).unwrap();
    std::os::unix::fs::symlink("/etc", dest.join("link")).unwrap();
    let e = check_output_dir(&dest, "train").unwrap_err().to_string();
    assert!(
        e.contains("a symbolic link \"link\", which this tool never writes"),
        "{e}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_listed_file_no_longer_as_written_is_refused_and_kept() {
    let dir = scratch("changed");
    let dest = dir.join("run");
    let st = Staging::new(&dest, "train").unwrap();
    std::fs::write(st.path().join("summary.json"), b"{}").unwrap();
    std::fs::write(st.path().join("metrics.csv"), b"a,b").unwrap();
    st.commit().unwrap();
    // The same size, other bytes: the digest tells.
    std::fs::write(dest.join("summary.json"), b"[]").unwrap();
    let e = check_output_dir(&dest, "train").unwrap_err().to_string();
    let said = "it holds 1 file no longer as policy-export wrote (its .cartpole-run lists \
                another size or digest: \"summary.json\")";
    assert!(e.contains(said), "{e}");
    // Changed after the check, before the clearing: kept, named, the rest removed.
    let e = clear(&dest, "train").unwrap_err();
    assert!(e.contains("\"summary.json\""), "{e}");
    assert_eq!(std::fs::read(dest.join("summary.json")).unwrap(), b"[]");
    assert!(!dest.join("metrics.csv").exists() && dest.join(MARKER).exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_marker_that_lists_files_without_digests_proves_nothing() {
    let dir = scratch("names");
    std::fs::write(dir.join("thesis.tex"), b"years of work").unwrap();
    let marker = r#"{"tool":"policy-export","version":"0","kind":"train","files":["thesis.tex"]}"#;
    std::fs::write(dir.join(MARKER), marker).unwrap();
    let e = check_output_dir(&dir, "train").unwrap_err().to_string();
    assert!(
        e.contains("lists files without their sizes and digests"),
        "{e}"
    );
    // Written by hand with the file's size but another digest.
    let marker = r#"{"tool":"policy-export","version":"0","kind":"train","entries":[
        {"path":"thesis.tex","bytes":13,"fnv1a64":"0000000000000000"}]}"#;
    std::fs::write(dir.join(MARKER), marker).unwrap();
    let e = check_output_dir(&dir, "train").unwrap_err().to_string();
    assert!(e.contains("no longer as policy-export wrote"), "{e}");
    clear(&dir, "train").unwrap_err();
    assert_eq!(
        std::fs::read(dir.join("thesis.tex")).unwrap(),
        b"years of work"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `reproduce --out docs/reproduction`, as the documents give it, may replace the
/// committed run: its marker lists every file in it.
#[test]
fn the_committed_reproduction_is_marked_as_this_tools() {
    let committed = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/reproduction");
    check_output_dir(&committed, "reproduce").unwrap();
}
