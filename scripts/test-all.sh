#!/usr/bin/env bash
# Runs every test of the project. Installs what it needs, fails loudly when it can't.
set -euo pipefail
cd "$(dirname "$0")/.."

step() { printf '\n==> %s\n' "$*"; }

step "rust target thumbv7em-none-eabihf"
if ! rustup target list --installed | grep -qx thumbv7em-none-eabihf; then
    rustup target add thumbv7em-none-eabihf
fi

step "qemu-system-arm (the firmware's SIL runs in QEMU)"
if ! command -v qemu-system-arm >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
        apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq qemu-system-arm >/dev/null
    else
        echo "qemu-system-arm is missing: run  sudo apt-get install -y qemu-system-arm  and try again" >&2
        exit 1
    fi
fi
qemu-system-arm --version | head -n 1

step "chromium (the operator console's browser test)"
if ! command -v chromium >/dev/null 2>&1; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
        { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; } ||
            echo "could not install chromium: the console's browser test will say it skipped" >&2
    else
        echo "chromium is missing (sudo apt-get install -y chromium): the console's browser test will say it skipped" >&2
    fi
fi

step "eclipse-zenoh for python3 (a client nobody here wrote, for the bus test)"
if ! python3 -c "import zenoh" >/dev/null 2>&1; then
    python3 -m pip install --quiet eclipse-zenoh==1.10.2 ||
        echo "could not install eclipse-zenoh: the bus test's Python client will say it skipped" >&2
fi

step "firmware for both boards (QEMU mps2-an386, NUCLEO-F411RE), size budget"
./scripts/build-firmware.sh

step "no_std crates build for the MCU target"
cargo build --locked --release --target thumbv7em-none-eabihf -p protocol -p control-core

step "host workspace tests"
log=target/test-all.log
mkdir -p target
cargo test --locked --workspace --release 2>&1 | tee "$log"

passed=$(grep -Eo '^test result: ok\. [0-9]+ passed' "$log" | awk '{s += $4} END {print s + 0}')
echo
echo "all tests passed: $passed tests in $((SECONDS / 60)) min $((SECONDS % 60)) s"
