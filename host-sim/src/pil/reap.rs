//! Ending a target with every process it started: those below it by their parents, and
//! those that left it (a daemon that forked twice and started a session of its own, handed
//! to init), by a mark in the environment each inherits.

use std::process::{Child, Command};
use std::sync::atomic::{AtomicU64, Ordering};

use rustix::process::{Pid, Signal, kill_process};

/// The environment variable the mark is carried in.
const MARK: &str = "CARTPOLE_PIL_RUN";

/// What a target's processes carry in their environment: this process, a count and the
/// clock, so that no other run's (nor an earlier run's, under a reused process id) match.
pub struct Mark(String);

impl Mark {
    /// A mark no other target carries.
    pub fn new() -> Mark {
        static COUNT: AtomicU64 = AtomicU64::new(0);
        let n = COUNT.fetch_add(1, Ordering::Relaxed);
        let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH);
        let ns = now.map_or(0, |d| d.as_nanos());
        Mark(format!("{}.{n}.{ns}", std::process::id()))
    }

    /// Gives the mark to `command`'s process, and so to every process it starts.
    pub fn set(&self, command: &mut Command) {
        command.env(MARK, &self.0);
    }

    /// Whether process `pid` was started with the mark (false where its environment cannot
    /// be read: another user's).
    fn carried_by(&self, pid: i32) -> bool {
        let entry = format!("{MARK}={}", self.0);
        std::fs::read(format!("/proc/{pid}/environ"))
            .is_ok_and(|env| env.split(|&b| b == 0).any(|e| e == entry.as_bytes()))
    }
}

/// Ends `child` and every process it started. Not a process group of its own, which would
/// keep a terminal's Ctrl-C from reaching them. Each is stopped first, and they are gathered
/// again once stopped, so that none starts another unseen.
pub fn end(child: &mut Child, mark: &Mark) {
    let _ = kill_process(Pid::from_child(child), Signal::STOP);
    let mut gathered = Vec::new();
    for _ in 0..2 {
        gathered = gather(child.id(), mark);
        for &pid in &gathered {
            let _ = kill_process(pid, Signal::STOP);
        }
    }
    for pid in gathered {
        let _ = kill_process(pid, Signal::KILL);
    }
    let _ = child.kill();
    let _ = child.wait();
}

/// Every process below `root` by their parents in `/proc`, and every one carrying `mark`
/// with those below it (none where `/proc` cannot be read): gathered whole before any is
/// ended, which would hand its children to init.
fn gather(root: u32, mark: &Mark) -> Vec<Pid> {
    let parent_of = |entry: std::fs::DirEntry| {
        let pid: i32 = entry.file_name().to_str()?.parse().ok()?;
        let stat = std::fs::read_to_string(entry.path().join("stat")).ok()?;
        // `pid (name) state ppid ...`, the name holding any bytes but its last `)`.
        let ppid = stat.rsplit_once(") ")?.1.split(' ').nth(1)?.parse().ok()?;
        Some((pid, ppid))
    };
    let Ok(dir) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    let links: Vec<(i32, i32)> = dir.filter_map(|e| parent_of(e.ok()?)).collect();
    let root = root as i32;
    let mut found = vec![root];
    found.extend(
        links
            .iter()
            .map(|l| l.0)
            .filter(|&p| p != root && mark.carried_by(p)),
    );
    let mut k = 0;
    while let Some(&parent) = found.get(k) {
        for &(pid, _) in links.iter().filter(|l| l.1 == parent) {
            if !found.contains(&pid) {
                found.push(pid);
            }
        }
        k += 1;
    }
    found[1..]
        .iter()
        .filter_map(|&p| Pid::from_raw(p))
        .collect()
}
