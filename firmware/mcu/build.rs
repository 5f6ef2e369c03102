//! Link arguments live here (not in untargeted rustflags), so the ELF links wherever cargo
//! is run from. The QEMU board brings its own memory map and (empty) interrupt list.
use std::{env, fs, path::PathBuf};

fn main() {
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");
    if env::var_os("CARGO_FEATURE_BOARD_QEMU").is_some() {
        let out = PathBuf::from(env::var("OUT_DIR").unwrap());
        fs::copy("memory-qemu.x", out.join("memory.x")).unwrap();
        // cortex-m-rt's `device` feature includes the device's interrupt names: none here.
        fs::write(out.join("device.x"), "").unwrap();
        println!("cargo:rustc-link-search={}", out.display());
    }
    println!("cargo:rerun-if-changed=memory-qemu.x");
    println!("cargo:rerun-if-changed=build.rs");
}
