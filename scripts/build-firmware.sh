#!/usr/bin/env bash
# Builds the robot firmware for every board, each in its own target directory (two boards
# under one profile would overwrite one ELF with the other), records flash and static RAM
# in firmware/mcu/size-<board>.txt, and fails above the budget (64 KiB flash, 16 KiB RAM).
set -euo pipefail
cd "$(dirname "$0")/../firmware/mcu"
# Panic locations carry the absolute paths of the path dependencies (firmware/core,
# protocol), about a dozen times: under their own path the image grew 12 B for each
# character of the checkout's path. Mapped to one short prefix, it is the same size
# wherever the repository is.
root=$(cd ../.. && pwd)
export RUSTFLAGS="${RUSTFLAGS:+$RUSTFLAGS }--remap-path-prefix=$root=/sweeper"

rustup target add thumbv7em-none-eabihf >/dev/null
rustup component add llvm-tools >/dev/null 2>&1 || true
size_tool=$(ls "$(rustc --print sysroot)"/lib/rustlib/*/bin/llvm-size 2>/dev/null | head -n 1 || true)
if [ -z "$size_tool" ]; then
    echo "llvm-size not found: run 'rustup component add llvm-tools'" >&2
    exit 1
fi

FLASH_LIMIT=$((64 * 1024))
RAM_LIMIT=$((16 * 1024))
status=0
for board in ${BOARDS:-qemu nucleo}; do
    echo "==> firmware, board $board"
    cargo build --locked --release --no-default-features --features "board-$board" \
        --target thumbv7em-none-eabihf \
        --target-dir "target/$board"
    elf="target/$board/thumbv7em-none-eabihf/release/sweeper-firmware"
    # Sections: flash = vectors + code + read-only data + the initial values of .data;
    # static RAM = .data + .bss + .uninit.
    read -r flash ram < <("$size_tool" -A "$elf" | awk '
        $1 ~ /^\.(vector_table|text|rodata)$/ { f += $2 }
        $1 == ".data" { f += $2; r += $2 }
        $1 ~ /^\.(bss|uninit)$/ { r += $2 }
        END { print f, r }')
    {
        echo "# sweeper-firmware, board-$board, release (opt-level s, fat LTO, DEFMT_LOG=${DEFMT_LOG:-info})"
        echo "# scripts/build-firmware.sh; budget $FLASH_LIMIT flash / $RAM_LIMIT static RAM"
        echo "flash_bytes $flash"
        echo "static_ram_bytes $ram"
    } > "size-$board.txt"
    cat "size-$board.txt"
    if [ "$flash" -gt "$FLASH_LIMIT" ] || [ "$ram" -gt "$RAM_LIMIT" ]; then
        echo "board-$board is over budget: $flash bytes flash (max $FLASH_LIMIT), $ram bytes RAM (max $RAM_LIMIT)" >&2
        status=1
    fi
done
exit $status
