#!/usr/bin/env python3
"""Where on their routes do agents leave the road? Off-road episodes by the turn before them.

    scripts/turn_failures.py [--cd BIN] [--after M] RESULTS.json...

Each RESULTS.json is an `eval` output on a built-in suite (suites/NAME.json, named in the file).
For every junction passage of every episode's route it classifies the turn by the angle between
the heading at the end of the incoming edge and at the start of the outgoing one (+ is a left
turn, rounded to 10 degrees), counts the passages the agent reached (its driven distance passed
the junction's entry) and those after which it left the road within --after metres (default 25)
of the junction's exit. Positions along the route are the distance driven from the task's
start position, edge and junction lengths from the town's network (`causaldrive town NAME`
prints its path); a weaving agent drives a little more than its route progress, so the
attribution is approximate by a few metres. Prints a markdown table. Needs sumo-tools' sumolib.
"""
import argparse
import collections
import json
import math
import os
import subprocess
import sys

sys.path.append(os.environ.get("SUMO_TOOLS", "/usr/share/sumo/tools"))
import sumolib  # noqa: E402


def net_path(cd, town):
    out = subprocess.run([cd, "town", town], check=True, capture_output=True, text=True).stdout
    for line in out.splitlines():
        parts = line.split()
        if parts and parts[0] == town and parts[-1].endswith(".net.xml"):
            return parts[-1]
    sys.exit(f"error: `{cd} town {town}` printed no network path")


def heading(a, b):
    return math.atan2(b[1] - a[1], b[0] - a[0])


def turn_angle(e1, e2):
    s1, s2 = e1.getShape(), e2.getShape()
    d = math.degrees(heading(s2[0], s2[1]) - heading(s1[-2], s1[-1]))
    d = (d + 180) % 360 - 180
    return int(round(d / 10.0)) * 10 or 0  # -0 -> 0


def junctions(net, task):
    """[(entry, exit, angle)] of the route's junction passages, in metres from the start."""
    edges = [net.getEdge(e) for e in task["route"]]
    pos, out = -task["start_pos"], []
    for e, nxt in zip(edges, edges[1:]):
        pos += e.getLength()
        length = 0.0
        for c in e.getOutgoing().get(nxt, []):
            if c.getViaLaneID():
                length = net.getLane(c.getViaLaneID()).getLength()
                break
        out.append((pos, pos + length, turn_angle(e, nxt)))
        pos += length
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cd", default="build/causaldrive", help="the causaldrive binary")
    ap.add_argument("--after", type=float, default=25.0, help="metres after a junction's exit")
    ap.add_argument("results", nargs="+")
    args = ap.parse_args()
    nets, suites = {}, {}
    reached, offroad = collections.Counter(), collections.Counter()
    episodes = offroad_total = 0
    for path in args.results:
        with open(path) as f:
            res = json.load(f)
        name = res["suite"]
        if name not in suites:
            suite_file = os.path.join("suites", name + ".json")
            if not os.path.exists(suite_file):
                sys.exit(f"error: {path}: suite '{name}' is not a built-in suite ({suite_file})")
            with open(suite_file) as f:
                suites[name] = json.load(f)
        suite = suites[name]
        town = suite["town"]
        if town not in nets:
            nets[town] = sumolib.net.readNet(net_path(args.cd, town), withInternal=True)
        tasks = {t["id"]: t for t in suite["tasks"]}
        for ep in res["episodes"]:
            episodes += 1
            offroad_total += ep["outcome"] == "offroad"
            d = ep["distance_m"]
            for entry, exit_, angle in junctions(nets[town], tasks[ep["task"]]):
                if d < entry:
                    break
                reached[angle] += 1
                if ep["outcome"] == "offroad" and d <= exit_ + args.after:
                    offroad[angle] += 1
    print(f"{len(args.results)} evaluations, {episodes} episodes, {offroad_total} off-road; "
          f"off-road within {args.after:g} m after the junction:\n")
    print("| turn (deg, + left) | passages reached | off-road after it | % |")
    print("|---:|---:|---:|---:|")
    for angle in sorted(reached):
        n, k = reached[angle], offroad[angle]
        print(f"| {angle:+d} | {n} | {k} | {100.0 * k / n:.1f} |")
    k = offroad_total - sum(offroad.values())
    print(f"\nOff-road elsewhere (mid-edge, or before the first junction): {k}")


if __name__ == "__main__":
    main()
