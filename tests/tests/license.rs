//! The licence the packages declare is the one the repository's licence files grant: every
//! Cargo package (the workspace's, the boards', the fuzz targets') and the Python package
//! declare `MIT OR Apache-2.0`, and `LICENSE-MIT` and `LICENSE-APACHE` hold those texts.

use std::path::{Path, PathBuf};

use e2e::repo;

const EXPRESSION: &str = "MIT OR Apache-2.0";

fn toml_at(path: &Path) -> toml::Table {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    text.parse()
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// Every `Cargo.toml` under `dir`, build outputs and hidden directories left out.
fn manifests(dir: &Path, found: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let e = e.unwrap();
        let name = e.file_name();
        let name = name.to_string_lossy();
        if e.file_type().unwrap().is_dir() {
            if name != "target" && !name.starts_with('.') {
                manifests(&e.path(), found);
            }
        } else if name == "Cargo.toml" {
            found.push(e.path());
        }
    }
}

#[test]
fn every_package_declares_the_licence_the_files_grant() {
    let root = toml_at(&repo().join("Cargo.toml"));
    let workspace = root["workspace"]["package"]["license"].as_str();
    assert_eq!(workspace, Some(EXPRESSION), "the workspace's license");
    let mut found = Vec::new();
    manifests(&repo(), &mut found);
    let packages: Vec<PathBuf> = found
        .into_iter()
        .filter(|m| toml_at(m).contains_key("package"))
        .collect();
    // The workspace's ten members, two boards and the fuzz targets at least.
    assert!(packages.len() >= 13, "{packages:?}");
    for m in &packages {
        let manifest = toml_at(m);
        let license = manifest["package"].get("license");
        let inherited = license
            .and_then(|l| l.get("workspace"))
            .and_then(toml::Value::as_bool)
            == Some(true);
        let declared = license.and_then(toml::Value::as_str);
        assert!(
            inherited || declared == Some(EXPRESSION),
            "{}: license {license:?}, expected \"{EXPRESSION}\" or the workspace's",
            m.display()
        );
    }
    let python = toml_at(&repo().join("python/pyproject.toml"));
    assert_eq!(
        python["project"]
            .get("license")
            .and_then(toml::Value::as_str),
        Some(EXPRESSION),
        "python/pyproject.toml"
    );
}

#[test]
fn the_licence_files_hold_the_two_licences() {
    let read = |name: &str| {
        std::fs::read_to_string(repo().join(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
    };
    let mit = read("LICENSE-MIT");
    assert!(mit.starts_with("MIT License\n\nCopyright (c) 2026 The cartpole-ddqn developers\n"));
    assert!(mit.contains("Permission is hereby granted, free of charge, to any person"));
    let apache = read("LICENSE-APACHE");
    assert!(
        apache.contains("Apache License\n                           Version 2.0, January 2004")
    );
    assert!(apache.contains("END OF TERMS AND CONDITIONS"));
    assert!(apache.contains("Copyright 2026 The cartpole-ddqn developers"));
}
