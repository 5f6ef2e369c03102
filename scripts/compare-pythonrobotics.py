#!/usr/bin/env python3
"""PythonRobotics' potential_field_planning on the maps route_compare wrote, beside our
route planner's results: who reached the goal, who only said so, and how long each took.

Usage: compare-pythonrobotics.py DIR PYTHONROBOTICS_FILE [TIMEOUT_S]
(DIR holds maps.json and ours.json; scripts/compare-pythonrobotics.sh prepares all.)
"""

import contextlib
import importlib.util
import io
import json
import math
import multiprocessing as mp
import sys
import time


def load(path):
    spec = importlib.util.spec_from_file_location("pfp", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    mod.show_animation = False
    return mod


def clearance(p, o):
    """Distance from p to obstacle o's surface (negative inside), like the Rust side."""
    x, y = p
    if o["kind"] == "circle":
        cx, cy = o["center"]
        return math.hypot(x - cx, y - cy) - o["radius"]

    def seg(a, b):
        ax, ay = a
        bx, by = b
        dx, dy = bx - ax, by - ay
        l2 = dx * dx + dy * dy
        t = 0.0 if l2 == 0 else max(0.0, min(1.0, ((x - ax) * dx + (y - ay) * dy) / l2))
        return math.hypot(x - ax - t * dx, y - ay - t * dy)

    if o["kind"] == "segment":
        return seg(o["a"], o["b"])
    pts = o["points"]
    d = min(seg(pts[i], pts[(i + 1) % len(pts)]) for i in range(len(pts)))
    inside = False
    j = len(pts) - 1
    for i in range(len(pts)):
        (xi, yi), (xj, yj) = pts[i], pts[j]
        if (yi > y) != (yj > y) and x < (xj - xi) * (y - yi) / (yj - yi) + xi:
            inside = not inside
        j = i
    return -d if inside else d


def run_one(path, m, queue):
    mod = load(path)
    ox = [p[0] for p in m["points"]]
    oy = [p[1] for p in m["points"]]
    (sx, sy), (gx, gy) = m["start"], m["goal"]
    out = io.StringIO()
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(out):
        rx, ry = mod.potential_field_planning(sx, sy, gx, gy, ox, oy, m["reso"], m["rr"])
    ms = (time.perf_counter() - t0) * 1e3
    queue.put((ms, "Goal!!" in out.getvalue(), list(zip(rx, ry))))


def main():
    directory, path = sys.argv[1], sys.argv[2]
    timeout = float(sys.argv[3]) if len(sys.argv) > 3 else 120.0
    maps = json.load(open(f"{directory}/maps.json"))
    ours = {r["name"]: r for r in json.load(open(f"{directory}/ours.json"))}
    rows = []
    for m in maps:
        queue = mp.Queue()
        proc = mp.Process(target=run_one, args=(path, m, queue))
        proc.start()
        proc.join(timeout)
        if proc.is_alive():
            proc.kill()
            proc.join()
            theirs = f"did not finish in {timeout:.0f} s"
            said = reached = "—"
            ms = None
        else:
            ms, said_goal, pts = queue.get()
            gx, gy = m["goal"]
            end = pts[-1]
            at_goal = math.hypot(end[0] - gx, end[1] - gy) <= m["reso"]
            fp = m["footprint"]
            touching = any(clearance(p, o) < fp for p in pts for o in m["obstacles"])
            said = "yes" if said_goal else "no"
            reached = "yes" if at_goal and not touching else (
                "no (touches)" if touching else f"no (stopped {math.hypot(end[0]-gx, end[1]-gy):.1f} m short)")
            theirs = f"{ms:.0f} ms"
        o = ours[m["name"]]
        ratio = f"{ms / o['ms']:.0f}×" if ms is not None else f"> {timeout * 1e3 / o['ms']:.0f}×"
        rows.append((m["name"], len(m["points"]), theirs, said, reached,
                     f"{o['ms']:.1f} ms", "yes" if o["said_goal"] else "no",
                     "yes" if o["reached_goal"] else "no", ratio))
    head = ("map", "points", "PythonRobotics", "says goal", "reached", "ours", "says goal",
            "reached", "ours faster")
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in rows:
        print("| " + " | ".join(str(c) for c in r) + " |")


if __name__ == "__main__":
    main()
