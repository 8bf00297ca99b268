//! The table of scenario parts in docs/SCENARIOS.md is what `host-sim parts`
//! prints, the grammar's one table: a part, bound or default changed in the code and not in
//! the documents fails here.

use std::path::Path;
use std::process::Command;

/// The line that opens a generated block; the rest of it names the command.
const BEGIN: &str = "<!-- scenario-parts:";
/// The line that closes it.
const END: &str = "<!-- /scenario-parts -->";

/// The text between `doc`'s markers, or a message saying what is missing.
fn block(doc: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(doc);
    let text = std::fs::read_to_string(&path).unwrap();
    let start = text
        .find(BEGIN)
        .unwrap_or_else(|| panic!("{doc} has no {BEGIN} line"));
    let body = &text[start..];
    let body = &body[body.find('\n').expect("a line after the marker") + 1..];
    let end = body
        .find(END)
        .unwrap_or_else(|| panic!("{doc} has no {END} line"));
    assert!(
        !body[end + END.len()..].contains(BEGIN),
        "{doc} has two tables of parts"
    );
    body[..end].to_string()
}

#[test]
fn the_documents_show_the_table_host_sim_parts_prints() {
    let o = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .arg("parts")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let printed = String::from_utf8(o.stdout).unwrap();
    assert_eq!(printed, twin::grammar::markdown_table());
    let doc = "docs/SCENARIOS.md";
    assert!(
        block(doc) == printed,
        "{doc}'s table of parts differs from the grammar's: replace it with the output of \
         `cargo run -p host-sim -- parts`:\n{printed}"
    );
}
