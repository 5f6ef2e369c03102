#!/usr/bin/env bash
# Runs every test of the project. Installs what it needs, fails loudly when it can't.
set -euo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n==> %s\n' "$*"; }

step "rust target thumbv7em-none-eabihf"
if ! rustup target list --installed | grep -qx thumbv7em-none-eabihf; then
    rustup target add thumbv7em-none-eabihf
fi

step "no_std crates build for the MCU target"
cargo build --locked --release --target thumbv7em-none-eabihf -p protocol -p control-core

step "host workspace tests"
cargo test --locked --workspace --release

echo
echo "all tests passed"
