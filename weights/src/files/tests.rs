use super::*;

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("weights-files-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

#[test]
fn atomic_write_replaces_whole_files_and_leaves_no_temporary() {
    let dir = scratch("atomic");
    let p = dir.join("x.bin");
    write_atomic(&p, b"first").unwrap();
    write_atomic(&p, b"second").unwrap();
    assert_eq!(std::fs::read(&p).unwrap(), b"second");
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_link_or_fifo_at_the_temporary_name_is_never_written_through() {
    let dir = scratch("planted");
    let victim = dir.join("victim.txt");
    std::fs::write(&victim, b"precious").unwrap();
    let out = dir.join("x.rs");
    let tmp = temp_path(&out);
    std::os::unix::fs::symlink(&victim, &tmp).unwrap();
    write_atomic(&out, b"module").unwrap();
    assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
    assert!(std::fs::symlink_metadata(&out).unwrap().is_file());
    let made = std::process::Command::new("mkfifo")
        .arg(&tmp)
        .status()
        .unwrap();
    assert!(made.success());
    write_atomic(&out, b"again").unwrap();
    assert_eq!(std::fs::read(&out).unwrap(), b"again");
    assert!(std::fs::symlink_metadata(&tmp).is_err());
    // A name the file system takes whole, its hidden siblings' cut to fit beside it.
    let long = dir.join("c".repeat(250));
    write_atomic(&long, b"long").unwrap();
    assert_eq!(std::fs::read(&long).unwrap(), b"long");
    assert!(hidden_name(&long, u32::MAX, "tmp.gif").len() <= 255);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_killed_writers_temporary_is_removed_and_a_live_ones_kept() {
    let dir = scratch("stale");
    let p = dir.join("policy.rs");
    // No process has PID 4,000,000,000 (Linux caps PIDs at 2^22).
    assert_eq!(
        temp_path(Path::new("d/episode.png")),
        Path::new(&format!("d/.episode.png.{}.tmp", std::process::id()))
    );
    let dead = dir.join(".policy.rs.4000000000.tmp");
    let probe = dir.join(".policy.rs.4000000000.probe");
    std::fs::write(&probe, b"").unwrap();
    // PID 1 (init) always runs.
    let live = dir.join(".policy.rs.1.tmp");
    let other = dir.join(".other.rs.4000000000.tmp");
    for f in [&dead, &live, &other] {
        std::fs::write(f, b"half").unwrap();
    }
    write_atomic(&p, b"whole").unwrap();
    assert_eq!(dead.exists(), !Path::new("/proc/self").exists());
    assert_eq!(probe.exists(), !Path::new("/proc/self").exists());
    assert!(live.exists() && other.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn outputs_sharing_their_first_200_bytes_have_hidden_names_of_their_own() {
    let dir = scratch("shared");
    let common = "n".repeat(200);
    let (a, b) = (dir.join(common.clone() + "a"), dir.join(common + "b"));
    assert_ne!(temp_path(&a), temp_path(&b));
    // One write under way while the other runs whole: neither takes the other's temporary.
    let tmp_a = temp_path(&a);
    write_new(&tmp_a, b"a").unwrap();
    write_atomic(&b, b"b").unwrap();
    std::fs::rename(&tmp_a, &a).unwrap();
    assert_eq!(std::fs::read(&a).unwrap(), b"a");
    assert_eq!(std::fs::read(&b).unwrap(), b"b");
    // The longest names, of one byte and of two-byte characters, and a process id of ten
    // digits: within a file system's 255 bytes, each name's own.
    let widest = [
        dir.join("w".repeat(255)),
        dir.join("\u{e9}".repeat(127) + "w"),
    ];
    let names = widest.map(|p| hidden_name(&p, u32::MAX, "partial"));
    assert!(names.iter().all(|n| n.len() <= 255), "{names:?}");
    assert_ne!(names[0], names[1]);
    // What an earlier version, which kept the whole name, left for a name of 201 to 242
    // bytes (PID 4,000,000,000 is no process's).
    let earlier = dir.join(format!(".{}.4000000000.tmp", "m".repeat(230)));
    std::fs::write(&earlier, b"half").unwrap();
    write_atomic(&dir.join("m".repeat(230)), b"whole").unwrap();
    assert_eq!(earlier.exists(), !Path::new("/proc/self").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn outputs_never_replace_directories_devices_or_inputs() {
    let dir = scratch("out");
    let e = write_atomic(&dir, b"x").unwrap_err().to_string();
    assert!(e.contains("found a directory"), "{e}");
    #[cfg(unix)]
    {
        let e = check_output(Path::new("/dev/null"), &[]).unwrap_err();
        assert!(e.to_string().contains("found a device"), "{e}");
        assert!(e.is_input());
    }
    let input = dir.join("in.bin");
    std::fs::write(&input, b"weights").unwrap();
    let e = check_output(&input, &[&input]).unwrap_err().to_string();
    assert!(e.contains("would overwrite the input"), "{e}");
    // The same file by another name.
    let other = dir.join(".").join("in.bin");
    assert!(check_output(&other, &[&input]).is_err());
    assert!(check_output(&dir.join("new.rs"), &[&input]).is_ok());
    // A name ending in '/', which a file cannot be written as, whatever is there.
    for slashed in ["new.h/", "in.bin/", "new/deeper/"] {
        let e = check_output(&dir.join(slashed), &[]).unwrap_err();
        assert!(e.is_input(), "{e}");
        assert!(e.to_string().contains("found a path ending in '/'"), "{e}");
    }
    assert_eq!(std::fs::read(&input).unwrap(), b"weights");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn inputs_and_places_are_checked_with_their_flags_before_any_work() {
    let dir = scratch("io");
    let (input, file) = (dir.join("in.bin"), dir.join("file"));
    std::fs::write(&input, b"w").unwrap();
    std::fs::write(&file, b"mine").unwrap();
    let ok = check_io(
        &[("SRC", &input)],
        &[("--out", &dir.join("new/deeper/out.rs"))],
    );
    ok.unwrap();
    type Paths<'a> = &'a [(&'a str, &'a Path)];
    let cases: [(Paths, Paths, &str); 4] = [
        (&[("SRC", &dir)], &[], "SRC "),
        (
            &[],
            &[("--out", &file.join("x.rs"))],
            "found a regular file",
        ),
        (
            &[],
            &[("--out", Path::new("/proc/cartpole/x.rs"))],
            "refuses",
        ),
        (
            &[("SRC", &input)],
            &[("--out", &input)],
            "would overwrite the input",
        ),
    ];
    for (inputs, outputs, want) in cases {
        let e = check_io(inputs, outputs).unwrap_err();
        assert!(e.is_input() && e.to_string().contains(want), "{e}");
    }
    // Nothing was created, not even the probe.
    let mut left: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    left.sort();
    assert_eq!(left, ["file", "in.bin"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn reads_are_capped_and_only_of_regular_files() {
    let dir = scratch("read");
    let p = dir.join("w.bin");
    std::fs::write(&p, vec![7u8; 100]).unwrap();
    assert_eq!(read_capped(&p, 100).unwrap().len(), 100);
    let e = read_capped(&p, 99).unwrap_err().to_string();
    assert!(e.contains("expected at most 99 bytes"), "{e}");
    let e = read_capped(&dir, 10).unwrap_err().to_string();
    assert!(
        e.contains("expected a regular file, found a directory"),
        "{e}"
    );
    #[cfg(unix)]
    {
        let e = read_capped(Path::new("/dev/zero"), 10)
            .unwrap_err()
            .to_string();
        assert!(e.contains("found a device"), "{e}");
        let fifo = dir.join("fifo");
        let status = std::process::Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap();
        assert!(status.success());
        // Without O_NONBLOCK this would wait for a writer forever.
        let e = read_capped(&fifo, 10).unwrap_err().to_string();
        assert!(e.contains("found a FIFO"), "{e}");
    }
    let e = read_capped(&dir.join("missing"), 10).unwrap_err();
    assert!(e.is_input() && e.to_string().contains("missing"), "{e}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_read_the_system_fails_is_its_failure_a_path_that_cannot_be_opened_the_inputs() {
    // It opens as a regular file, and a read at address 0 fails with an I/O error.
    let mem = Path::new("/proc/self/mem");
    let e = read_capped(mem, 100).unwrap_err();
    assert!(
        !e.is_input() && e.to_string().starts_with("reading /proc/self/mem: "),
        "{e}"
    );
    let e = read_capped(Path::new("/nonexistent/summary.json"), 100).unwrap_err();
    assert!(e.is_input(), "{e}");
}

/// Two names that are not UTF-8 and differ only in their invalid bytes read alike lossily;
/// their hidden names differ all the same.
#[cfg(unix)]
#[test]
fn names_differing_only_in_invalid_bytes_have_hidden_names_of_their_own() {
    use std::os::unix::ffi::OsStrExt;
    let dir = scratch("invalid");
    let [a, b] = [b"out\xff.rs", b"out\xfe.rs"].map(|n| dir.join(std::ffi::OsStr::from_bytes(n)));
    assert_eq!(a.to_string_lossy(), b.to_string_lossy());
    assert_ne!(temp_path(&a), temp_path(&b));
}

/// A new directory output ending in `/.` or `/..` after others, with trailing slashes or
/// not, is refused (the system refused the first after the work; the second made a
/// directory and wrote in its parent); one that exists, and `.` and `..` alone, name
/// directories that are.
#[test]
fn a_new_directory_ending_in_a_dot_is_refused() {
    let d = scratch("dots");
    let new = d.join("new");
    for end in [".", "..", "./", "../", ".//"] {
        let bad = format!("{}/{end}", new.display());
        let e = check_dir_name("--plots", Path::new(&bad))
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(&format!("--plots {bad}: expected a directory")),
            "{e}"
        );
    }
    let a = d.join("a");
    std::fs::create_dir_all(a.join("b")).unwrap();
    for good in [".", "..", "../..", "./plots", "plots", "a/.b", "a/..c", "/"] {
        check_dir_name("--plots", Path::new(good)).unwrap();
    }
    for there in [a.join("."), a.join("b/.."), a.join("b/../")] {
        check_dir_name("--plots", &there).unwrap();
    }
    assert!(!new.exists());
    std::fs::remove_dir_all(&d).unwrap();
}
