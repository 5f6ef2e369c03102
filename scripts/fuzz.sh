#!/usr/bin/env bash
# Runs each cargo-fuzz target for FUZZ_SECONDS (default 60) from the corpus in fuzz/corpus.
# A crash input is copied to fuzz/regressions/<target>/ (replayed by the regression tests)
# and the script fails. cargo-fuzz's instrumentation flags need nightly rustc features:
# RUSTC_BOOTSTRAP=1 lets the stable toolchain take them; no sanitizer (-s none).
set -euo pipefail
cd "$(dirname "$0")/../fuzz"
seconds=${FUZZ_SECONDS:-60}
if ! command -v cargo-fuzz >/dev/null 2>&1; then
    cargo install cargo-fuzz --locked --version 0.13.2
fi
export RUSTC_BOOTSTRAP=1
status=0
for target in frame_decoder scenario_parser; do
    echo "==> fuzz $target for ${seconds}s"
    work=$(mktemp -d)
    cp corpus/"$target"/* "$work"/
    if ! cargo fuzz run -s none "$target" "$work" -- -max_total_time="$seconds" -artifact_prefix="$work/crash-" 2>&1 | tail -n 5; then
        status=1
    fi
    for crash in "$work"/crash-*; do
        [ -e "$crash" ] || continue
        cp "$crash" regressions/"$target"/
        echo "crash input kept: fuzz/regressions/$target/$(basename "$crash")" >&2
        status=1
    done
    rm -rf "$work"
done
exit $status
