//! `host-sim tables`: the results tables and values of README.md and docs/*.md rendered from
//! the files of docs/results/ (`host_sim::tables`), and each results file's page
//! (`docs/results/NAME.md`, `host_sim::tables::pages`), written in place or, with `--check`,
//! compared.
//! Every document and page is read and rendered before any is written, so a refusal anywhere
//! leaves all of them as they were.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result, anyhow};
use clap::Args;
use host_sim::batch::Batch;
use host_sim::manifest::{self, Manifest};
use host_sim::tables::{self, RESULTS_DIR, Stale, pages, values};

#[derive(Args)]
#[command(after_help = format!("{}\n\n{}", tables::OPTIONS_HELP, values::HELP))]
pub struct TablesArgs {
    /// Write nothing: exit 1 listing every table and value that differs from its file.
    #[arg(long)]
    check: bool,
    /// The repository's root (default: the nearest directory at or above the current one
    /// that holds a Cargo.toml and docs/results/).
    #[arg(long)]
    root: Option<PathBuf>,
}

/// Renders or checks every document; false if `--check` found a stale table or value.
pub fn run(a: &TablesArgs) -> Result<bool> {
    let root = match &a.root {
        Some(r) => r.clone(),
        None => find_root(&std::env::current_dir()?)?,
    };
    check_pages_apart(&root)?;
    let mut updates: Vec<Generated> = Vec::new();
    for doc in documents(&root)? {
        let text = read_text(&root.join(&doc))
            .with_context(|| format!("reading {}", weights::shown(&doc)))?;
        let load = |file: &str| {
            read_results(&root.join(file)).map_err(|e| format!("reading {file}: {e:#}"))
        };
        let (new, stale) = tables::update(&text, load)
            .map_err(|r| anyhow!("{}:{}: {}", weights::shown(&doc), r.line, r.message))?;
        updates.push((doc, new, stale));
    }
    updates.extend(results_pages(&root)?);
    // Every place is checked before the first is written: a page that could not be
    // replaced was refused after the README had been.
    if !a.check {
        for (doc, _, stale) in &updates {
            if !stale.is_empty() {
                weights::files::check_output(&root.join(doc), &[])?;
            }
        }
    }
    // Every document and page put in place together, or none (a full disk half-way left
    // one page rewritten).
    let mut batch = Batch::default();
    let mut found = 0;
    for (doc, new, stale) in &updates {
        if a.check {
            for s in stale {
                host_common::errln!("{}:{}: {}", weights::shown(doc), s.line, s.what);
            }
        } else if !stale.is_empty() {
            let place = root.join(doc);
            weights::files::write_new(&batch.file(&place)?, new.as_bytes()).map_err(|e| {
                weights::Error::Io(format!("writing {}: {e}", weights::shown(&place)))
            })?;
        }
        found += stale.len();
    }
    batch.commit()?;
    if !a.check {
        for (doc, _, stale) in updates.iter().filter(|u| !u.2.is_empty()) {
            host_common::outln!(
                "{}: {} tables, values or pages written",
                weights::shown(doc),
                stale.len()
            );
        }
    }
    if a.check && found > 0 {
        host_common::errln!(
            "{found} tables, values or pages differ from their results: `host-sim tables` rewrites them"
        );
    }
    Ok(!a.check || found == 0)
}

/// Each results file's page, rendered, with a stale entry if it differs from the page on disk
/// (or there is none). The manifest titles the pages; a root without one gets untitled pages.
/// A manifest that is a link to nothing is one that cannot be read, not none.
fn results_pages(root: &Path) -> Result<Vec<Generated>> {
    let manifest = match root.join(manifest::PATH).symlink_metadata() {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
        _ => Some(Manifest::load(root)?),
    };
    let mut files = Vec::new();
    for file in results_files(root)? {
        let name = format!("{RESULTS_DIR}{file}");
        let json = read_results(&root.join(&name)).with_context(|| format!("reading {name}"))?;
        let steps = manifest.as_ref().map_or(Vec::new(), |m| m.producing(&name));
        files.push((name, json, steps));
    }
    let mut out = Vec::new();
    for (name, json, steps) in &files {
        let page = pages::page(name, json, steps).map_err(anyhow::Error::msg)?;
        let what = format!("the page differs from {name}");
        out.push(generated(root, &pages::path(name), page, what)?);
    }
    let index = pages::index(&files).map_err(anyhow::Error::msg)?;
    let what = format!("the list of results pages differs from {RESULTS_DIR}");
    out.push(generated(root, pages::INDEX, index, what)?);
    Ok(out)
}

/// Refuses, before any work, a results file whose page is another output's place
/// (`README.json`'s is the list of pages): the two were drawn, then the batch failed at
/// its commit with exit 1, naming a file that did not exist.
fn check_pages_apart(root: &Path) -> Result<()> {
    let pages: Vec<(String, PathBuf)> = results_files(root)?
        .into_iter()
        .map(|file| {
            let name = format!("{RESULTS_DIR}{file}");
            (format!("the page of {name}"), root.join(pages::path(&name)))
        })
        .collect();
    let mut files: Vec<(&str, &Path)> = pages
        .iter()
        .map(|(l, p)| (l.as_str(), p.as_path()))
        .collect();
    let index = root.join(pages::INDEX);
    files.push(("the list of results pages", &index));
    Ok(weights::files::check_apart(&files, &[])?)
}

/// A generated file's new text, with a stale entry (`what`) if the file on disk differs;
/// refused if what stands at its place is no regular file (a FIFO there was opened and
/// waited on for ever, even by `--check`).
fn generated(root: &Path, path: &str, text: String, what: String) -> Result<Generated> {
    let place = root.join(path);
    let old = match place.symlink_metadata() {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
        // Cut at one byte past the new text: a page that long differs whatever follows.
        Ok(m) if m.is_file() => prefix(&place, text.len() as u64 + 1)?,
        Ok(m) => anyhow::bail!(
            "{}: expected a regular file or none, to write its page in, found {}",
            weights::shown(&place),
            weights::files::kind(&m.file_type())
        ),
        Err(e) => anyhow::bail!("{}: {e}", weights::shown(&place)),
    };
    let stale = if old == text.as_bytes() {
        Vec::new()
    } else {
        vec![Stale { line: 1, what }]
    };
    Ok((PathBuf::from(path), text, stale))
}

/// Up to `n` bytes of the regular file at `path`.
fn prefix(path: &Path, n: u64) -> Result<Vec<u8>> {
    use std::io::Read;
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(n).read_to_end(&mut bytes))
        .with_context(|| format!("reading {}", weights::shown(path)))?;
    Ok(bytes)
}

/// A place's path, its new text and how it differs from what is there.
type Generated = (PathBuf, String, Vec<Stale>);

/// The names of the JSON files in docs/results/, sorted. A name is its page's and a link's
/// target as it is, so it must need no escaping there: ASCII letters, digits, `.`, `_` and
/// `-` (a name with a line break and a `|` broke the list of pages and headed it anew; one
/// that is not UTF-8 was passed over without a word).
fn results_files(root: &Path) -> Result<Vec<String>> {
    let dir = root.join(RESULTS_DIR);
    let listing =
        |e: std::io::Error| weights::Error::Io(format!("listing {}: {e}", weights::shown(&dir)));
    let mut files = Vec::new();
    for entry in std::fs::read_dir(&dir).map_err(listing)? {
        let name = entry.map_err(listing)?.file_name();
        let bytes = name.as_encoded_bytes();
        if !bytes.ends_with(b".json") || bytes.starts_with(b".") {
            continue;
        }
        let plain = |n: &&str| {
            n.bytes()
                .all(|b| b.is_ascii_alphanumeric() || b"._-".contains(&b))
        };
        let Some(name) = name.to_str().filter(plain) else {
            anyhow::bail!(
                "{}: expected a results file named with ASCII letters, digits, `.`, `_` and \
                 `-` (its page's name and a link's target), found {}",
                weights::shown(&dir),
                weights::quote(&name.to_string_lossy())
            );
        };
        files.push(name.to_string());
    }
    files.sort();
    Ok(files)
}

/// Largest document or results file read: the largest is a few hundred KB.
const MAX_TEXT_BYTES: u64 = 16 << 20;

/// The UTF-8 text of the regular file `path` (not a FIFO, never past [`MAX_TEXT_BYTES`]).
pub fn read_text(path: &Path) -> Result<String> {
    let bytes = weights::files::read_capped(path, MAX_TEXT_BYTES)?;
    String::from_utf8(bytes)
        .map_err(|e| anyhow!("{}: expected UTF-8 text, {e}", weights::shown(path)))
}

/// A results file's text, refused if a number in it reads as zero (`1e-400`): the JSON
/// parser reads it as 0, which a table or `results moved` then showed as measured.
pub fn read_results(path: &Path) -> Result<String> {
    let text = read_text(path)?;
    if let Some(why) = weights::hidden_zero_in_numbers(&text) {
        anyhow::bail!("{}: {why}", weights::shown(path));
    }
    Ok(text)
}

/// The nearest directory at or above `dir` with a Cargo.toml and the results directory.
pub fn find_root(dir: &Path) -> Result<PathBuf> {
    dir.ancestors()
        .find(|d| d.join("Cargo.toml").is_file() && d.join(RESULTS_DIR).is_dir())
        .map(Path::to_path_buf)
        .ok_or_else(|| {
            anyhow!(
                "no directory at or above {} holds a Cargo.toml and {RESULTS_DIR}: give --root",
                weights::shown(dir)
            )
        })
}

/// README.md and docs/*.md, relative to `root`, in a fixed order.
fn documents(root: &Path) -> Result<Vec<PathBuf>> {
    let mut docs: Vec<PathBuf> = std::fs::read_dir(root.join("docs"))
        .with_context(|| format!("listing {}", weights::shown(&root.join("docs"))))?
        .map(|e| e.map(|e| Path::new("docs").join(e.file_name())))
        .collect::<std::io::Result<_>>()?;
    // Every document is read, so one that is no regular file (a FIFO, a directory, a link to
    // nothing or to a device) is refused by name where it was skipped without a word.
    let hidden = |d: &PathBuf| {
        d.file_name()
            .is_some_and(|n| n.as_encoded_bytes().starts_with(b"."))
    };
    docs.retain(|d| d.extension().is_some_and(|x| x == "md") && !hidden(d));
    docs.sort();
    if root.join("README.md").symlink_metadata().is_ok() {
        docs.insert(0, PathBuf::from("README.md"));
    }
    Ok(docs)
}
