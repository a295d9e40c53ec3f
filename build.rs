//! Link setup for the firmware binary. Does nothing for the plain library
//! (host-tests, target-tests), so their own memory layout is never shadowed.

use std::{env, fs, path::PathBuf};

/// The build's date and time as LX200's `:GVD#` and `:GVT#` give them
/// (`Nov 23 2026`, `06:30:00`): the commit's, so that a build is the same
/// whenever it is made; a fixed stamp outside a git checkout.
fn build_stamp() -> (String, String) {
    let git = std::process::Command::new("git")
        .args([
            "log",
            "-1",
            "--format=%cd",
            "--date=format-local:%b %d %Y|%H:%M:%S",
        ])
        .env("TZ", "UTC")
        .output()
        .ok()
        .filter(|o| o.status.success())
        .and_then(|o| String::from_utf8(o.stdout).ok());
    match git
        .as_deref()
        .map(str::trim)
        .and_then(|s| s.split_once('|'))
    {
        Some((date, time)) => (date.to_string(), time.to_string()),
        None => ("Jan 01 2026".to_string(), "00:00:00".to_string()),
    }
}

/// The MEMORY block of the selected chip, which memory.x includes (it
/// documents the layouts); on the L475 also SRAM2 and its section.
fn board_memory() -> String {
    if env::var_os("CARGO_FEATURE_STM32L475VG").is_some() {
        "MEMORY\n{\n  FLASH : ORIGIN = 0x08000000, LENGTH = 256K\n  RAM   : ORIGIN = 0x20000000, LENGTH = 96K\n  SRAM2 : ORIGIN = 0x10000000, LENGTH = 32K\n}\n\
         SECTIONS\n{\n  .sram2 (NOLOAD) : ALIGN(4)\n  {\n    *(.sram2 .sram2.*);\n    . = ALIGN(4);\n  } > SRAM2\n} INSERT AFTER .uninit;\n"
            .to_string()
    } else {
        "MEMORY\n{\n  FLASH : ORIGIN = 0x08000000, LENGTH = 256K\n  RAM   : ORIGIN = 0x20000000, LENGTH = 128K\n}\n"
            .to_string()
    }
}

fn main() {
    println!("cargo:rerun-if-changed=build.rs");
    for git in [".git/HEAD", ".git/refs/heads"] {
        if std::path::Path::new(git).exists() {
            println!("cargo:rerun-if-changed={git}");
        }
    }
    let (date, time) = build_stamp();
    println!("cargo:rustc-env=MKGP_BUILD_DATE={date}");
    println!("cargo:rustc-env=MKGP_BUILD_TIME={time}");
    println!("cargo:rerun-if-changed=memory.x");
    if env::var_os("CARGO_FEATURE_FIRMWARE").is_none() {
        return;
    }
    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("OUT_DIR"));
    fs::copy("memory.x", out.join("memory.x")).expect("copy memory.x");
    fs::write(out.join("board-memory.x"), board_memory()).expect("write board-memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
}
