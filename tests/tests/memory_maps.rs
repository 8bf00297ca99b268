//! Each microcontroller target's self-test ELF is linked with its own memory map: the default
//! target with `memory.x` at the repository root, the others with theirs from
//! `selftest-app/memory/`, which the root file must not shadow although the linker looks in
//! the workspace root first (`selftest-app/build.rs` says how). The check is where the image
//! starts, read from the ELF's program headers: it must be where the target's machine boots.

use e2e::{build_app, default_target, mcu_targets, repo};

/// Where the target's QEMU machine takes its first instruction or vector table from.
fn boot_address(target: &str) -> u64 {
    match target {
        // mps2-an386 and the micro:bit: the vector table at 0.
        "thumbv7em-none-eabihf" | "thumbv6m-none-eabi" => 0,
        // mps2-an505 boots in the secure state from the secure alias of its code memory.
        "thumbv8m.main-none-eabihf" => 0x1000_0000,
        // `virt` with `-bios none` jumps to the start of its RAM.
        "riscv32imac-unknown-none-elf" => 0x8000_0000,
        other => panic!("{other}: no boot address known here; add its machine's"),
    }
}

/// The lowest physical address a loaded segment of a 32-bit little-endian ELF fills.
fn image_start(elf: &[u8]) -> u64 {
    assert!(
        elf.starts_with(b"\x7fELF\x01\x01"),
        "not a 32-bit little-endian ELF"
    );
    let u16_at = |at: usize| u64::from(u16::from_le_bytes([elf[at], elf[at + 1]]));
    let u32_at = |at: usize| u64::from(u32::from_le_bytes(elf[at..at + 4].try_into().unwrap()));
    let (phoff, phentsize, phnum) = (u32_at(0x1c), u16_at(0x2a), u16_at(0x2c));
    (0..phnum)
        .map(|i| (phoff + i * phentsize) as usize)
        // PT_LOAD with bytes in the file: what the loader writes.
        .filter(|&ph| u32_at(ph) == 1 && u32_at(ph + 16) > 0)
        .map(|ph| u32_at(ph + 12))
        .min()
        .expect("no loaded segment")
}

/// The `ORIGIN` of the `FLASH` region in the root `memory.x`.
fn root_flash_origin() -> u64 {
    let map = std::fs::read_to_string(repo().join("memory.x")).expect("memory.x at the root");
    let line = map
        .lines()
        .find(|l| l.trim_start().starts_with("FLASH"))
        .expect("memory.x: no FLASH region");
    let origin = line
        .split("ORIGIN")
        .nth(1)
        .and_then(|r| r.trim_start().strip_prefix('='))
        .and_then(|r| r.split(',').next())
        .map(str::trim)
        .unwrap_or_else(|| panic!("memory.x: no ORIGIN in {line:?}"));
    u64::from_str_radix(origin.trim_start_matches("0x"), 16).expect("a hexadecimal ORIGIN")
}

#[test]
fn the_root_memory_map_is_the_default_targets() {
    assert_eq!(root_flash_origin(), boot_address(&default_target()));
}

#[test]
fn every_target_is_linked_where_its_machine_boots() {
    let wrong: Vec<String> = mcu_targets()
        .iter()
        .filter_map(|target| {
            let elf =
                std::fs::read(build_app("selftest-app", Some(target))).expect("reading the ELF");
            let (start, want) = (image_start(&elf), boot_address(target));
            (start != want).then(|| format!("{target}: image at {start:#x}, boots at {want:#x}"))
        })
        .collect();
    assert!(wrong.is_empty(), "linked with another map: {wrong:#?}");
}
