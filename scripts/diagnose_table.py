#!/usr/bin/env python3
"""Markdown summary of `causaldrive diagnose --json` reports over training seeds.

    scripts/diagnose_table.py ROOT --seeds 0 1 2 --methods bc-so bc-oh ...

Reads ROOT/seedS/METHOD.json (SPEC section 10) and prints one table per method: for each
situation, its frames (mean over seeds) and, per action component, the label's mean, the
prediction's mean and R², each as mean ± sd over the seeds that have a report. A component
whose label is constant in a situation has no R² ("-"). Methods without a report are skipped.
"""
import argparse
import json
import os
import statistics
import sys

ORDER = ["standing_free", "starting", "cruising", "following", "slowing_red", "slowing_other",
         "standing_blocked", "all"]


def cell(values, digits=2):
    values = [v for v in values if v is not None]
    if not values:
        return "-"
    if len(values) == 1:
        return f"{values[0]:.{digits}f}"
    return f"{statistics.mean(values):.{digits}f} ± {statistics.stdev(values):.{digits}f}"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root")
    ap.add_argument("--seeds", nargs="+", required=True)
    ap.add_argument("--methods", nargs="+", required=True)
    args = ap.parse_args()
    printed = 0
    for method in args.methods:
        reports = []
        for seed in args.seeds:
            path = os.path.join(args.root, f"seed{seed}", f"{method}.json")
            if os.path.exists(path):
                with open(path) as f:
                    reports.append(json.load(f))
        if not reports:
            continue
        components = reports[0]["components"]
        names = set().union(*(r["situations"].keys() for r in reports))
        situations = [s for s in ORDER if s in names] + sorted(names - set(ORDER))
        print(f"### {method} ({len(reports)} seed{'s' if len(reports) > 1 else ''}: label mean, "
              "prediction mean, R²; mean ± sd over seeds)\n")
        head = "| situation | frames |" + "".join(
            f" {c} label | {c} prediction | {c} R² |" for c in components)
        print(head)
        print("|---|---:|" + "---:|---:|---:|" * len(components))
        for sit in situations:
            rows = [r["situations"][sit] for r in reports if sit in r["situations"]]
            line = f"| {sit} | {cell([r['count'] for r in rows], 0)} |"
            for c in components:
                line += (f" {cell([r[c]['label_mean'] for r in rows])} |"
                         f" {cell([r[c]['pred_mean'] for r in rows])} |"
                         f" {cell([r[c]['r2'] for r in rows])} |")
            print(line)
        print()
        printed += 1
    if not printed:
        sys.exit(f"error: no diagnose report under {args.root} for {' '.join(args.methods)}")


if __name__ == "__main__":
    main()
