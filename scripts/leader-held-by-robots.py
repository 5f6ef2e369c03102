#!/usr/bin/env python3
"""How long the leader stood with one of the fleet's robots in front of it, from
`basestation sim --trace` files: the two waiting for each other (the leader's ring holds
it short of the robot, whose slot is where the leader stands).

Usage: leader-held-by-robots.py TRACE.csv...

Per trace, and summed: seconds the leader stood (|v| < 0.02 m/s), and of those, seconds
with another robot's centre within 0.9 m and 40 degrees of its heading (the ring's view,
the footprints within 0.3 m). Robot 0 is taken for the leader (the trace's `role`).
"""

import csv
import math
import sys
from collections import defaultdict

STANDING_M_S = 0.02
NEAR_M = 0.9
RING_DEG = 40.0


def held(path):
    by_time = defaultdict(dict)
    period = None
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            by_time[float(row["t"])][int(row["id"])] = row
    times = sorted(by_time)
    if len(times) > 1:
        period = times[1] - times[0]
    standing = blocked = 0
    for t in times:
        rows = by_time[t]
        leader = next((r for r in rows.values() if r["role"] == "leader"), None)
        if leader is None or abs(float(leader["v"])) >= STANDING_M_S:
            continue
        standing += 1
        x, y, h = float(leader["x"]), float(leader["y"]), float(leader["heading"])
        for r in rows.values():
            if r is leader:
                continue
            dx, dy = float(r["x"]) - x, float(r["y"]) - y
            off = (math.atan2(dy, dx) - h + math.pi) % (2 * math.pi) - math.pi
            if math.hypot(dx, dy) < NEAR_M and abs(off) < math.radians(RING_DEG):
                blocked += 1
                break
    return standing * (period or 0.0), blocked * (period or 0.0)


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    total = [0.0, 0.0]
    for path in sys.argv[1:]:
        try:
            standing, blocked = held(path)
        except (OSError, KeyError, ValueError) as e:
            sys.exit(f"{path}: {e}")
        total[0] += standing
        total[1] += blocked
        print(f"{path}: leader standing {standing:.1f} s, a robot in front {blocked:.1f} s")
    print(f"all: leader standing {total[0]:.1f} s, a robot in front {total[1]:.1f} s")


if __name__ == "__main__":
    main()
