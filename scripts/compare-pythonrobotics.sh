#!/usr/bin/env bash
# Route planning side by side with PythonRobotics' potential_field_planning, on its own
# map, the paper's map and 100 m sites (issue 11's benchmark). Installs what it needs in
# target/pythonrobotics (a Python venv with numpy and matplotlib; the planner's file from
# PythonRobotics at a pinned commit, or from $PYTHONROBOTICS_FILE if set, e.g. a local
# checkout where GitHub is not reachable). Prints a Markdown table.
#
#   scripts/compare-pythonrobotics.sh [TIMEOUT_S]
set -euo pipefail
cd "$(dirname "$0")/.."
work=target/pythonrobotics
commit=b38c510e  # AtsushiSakai/PythonRobotics, the version measured in docs/basestation.md
mkdir -p "$work"
if [ ! -x "$work/venv/bin/python" ]; then
    python3 -m venv "$work/venv"
    "$work/venv/bin/pip" install --quiet numpy matplotlib
fi
file="${PYTHONROBOTICS_FILE:-$work/potential_field_planning.py}"
if [ ! -f "$file" ]; then
    url="https://raw.githubusercontent.com/AtsushiSakai/PythonRobotics/$commit/PathPlanning/PotentialFieldPlanning/potential_field_planning.py"
    if ! curl -fsSL "$url" -o "$file"; then
        echo "cannot download $url; set PYTHONROBOTICS_FILE to a copy of potential_field_planning.py" >&2
        exit 2
    fi
fi
cargo run --release --quiet -p base-station --example route_compare -- "$work"
MPLBACKEND=Agg "$work/venv/bin/python" scripts/compare-pythonrobotics.py "$work" "$file" "${1:-120}"
