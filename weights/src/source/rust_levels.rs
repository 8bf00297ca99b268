//! A Rust module's duty levels: `pub const LEVELS`, laid out as rustfmt lays it out.

use std::fmt::Write;

use super::push_list;

/// `pub const LEVELS: ::firmware::controller::Levels<A>`, checked as the crate compiles, laid
/// out as rustfmt lays it out, so a crate holding the export passes its format check.
pub(crate) fn levels_item(levels: &[f32]) -> String {
    let (mut list, a) = (String::new(), levels.len());
    push_list(&mut list, levels, "");
    let call = "::firmware::controller::Levels::new([";
    let head = format!("pub const LEVELS: ::firmware::controller::Levels<{a}> =");
    let mut s = String::from(
        "\n/// The duty level of each output, a fraction of the full push (+ towards +x).\n",
    );
    let one_line = format!("    match {call}{list}]) {{");
    if one_line.len() < RUSTFMT_WIDTH {
        let _ = write!(
            s,
            "{head}\n{one_line}\n        Ok(levels) => levels,\n        \
             Err(_) => panic!(\"the policy's levels are refused\"),\n    }};\n"
        );
        return s;
    }
    // Too long for a line: the match hugs the array, whose elements fill lines when all are
    // short (rustfmt's short array element width, 10) and stand one to a line otherwise.
    let _ = writeln!(s, "{head} match {call}");
    let items: Vec<String> = levels.iter().map(|v| format!("{v:?}")).collect();
    let short = items.iter().all(|i| i.len() <= 10);
    let mut line = String::new();
    for item in &items {
        if !line.is_empty() && (!short || line.len() + 1 + item.len() + 1 > RUSTFMT_WIDTH) {
            let _ = writeln!(s, "{line}");
            line.clear();
        }
        line.push_str(if line.is_empty() { "    " } else { " " });
        line.push_str(item);
        line.push(',');
    }
    let _ = write!(
        s,
        "{line}\n]) {{\n    Ok(levels) => levels,\n    \
         Err(_) => panic!(\"the policy's levels are refused\"),\n}};\n"
    );
    s
}

/// rustfmt's default line width.
const RUSTFMT_WIDTH: usize = 100;

#[cfg(test)]
mod tests {
    use super::*;

    /// The levels item is what rustfmt makes of it (the workspace's toolchain's rustfmt, an
    /// implementation nobody here wrote), however long its list: on one line after the
    /// `=`, hugging the array, filling lines or one element to a line.
    #[test]
    fn the_levels_item_is_laid_out_as_rustfmt_lays_it_out() {
        let lists: [&[f32]; 8] = [
            &[-1.0, 1.0],
            &[-1.0, 0.0, 1.0],
            &[-1.0, -0.5, -0.2, 0.0, 0.2, 0.5, 1.0],
            &[-1.0, -0.4, -0.15, -0.05, 0.0, 0.05, 0.15, 0.4, 1.0],
            // A match line of 99 columns, which rustfmt keeps, then one of 100.
            &[-1.0, -0.4, -0.15, -0.05, 0.25, 0.55, 0.752, 1.0],
            &[-1.0, -0.4, -0.15, -0.05, 0.25, 0.55, 0.7525, 1.0],
            // An element longer than rustfmt's short-element width.
            &[-0.12345679, -0.4, -0.15, -0.05, 0.0, 0.05, 0.15, 0.4, 1.0],
            // Short elements filling more than one line.
            &[
                -0.9876543, -0.8765432, -0.7654321, -0.6543211, -0.5432112, 0.12345678, 0.23456718,
                0.34567812, 0.45678123,
            ],
        ];
        let dir = std::env::temp_dir().join(format!("levels-fmt-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut lengths = Vec::new();
        for (i, levels) in lists.iter().enumerate() {
            let item = levels_item(levels);
            lengths.push(item.lines().map(str::len).max().unwrap());
            let file = dir.join(format!("l{i}.rs"));
            // The item opens with the blank line that parts it from the one above.
            std::fs::write(&file, item.trim_start_matches('\n')).unwrap();
            let out = std::process::Command::new("rustfmt")
                .args(["--edition", "2024", "--check"])
                .arg(&file)
                .output()
                .expect("rustfmt, a component of the workspace's toolchain");
            assert!(
                out.status.success(),
                "{levels:?}:\n{item}\n{}",
                String::from_utf8_lossy(&out.stdout)
            );
        }
        std::fs::remove_dir_all(&dir).unwrap();
        let filled = levels_item(lists[7]);
        let list_lines = filled
            .lines()
            .filter(|l| l.ends_with(',') && !l.contains("=>"));
        assert_eq!(list_lines.count(), 2, "{filled}");
        // The 99-column match stays on its line; the 100-column one does not.
        assert_eq!((lengths[4], lengths[5] < 99), (99, true), "{lengths:?}");
    }
}
