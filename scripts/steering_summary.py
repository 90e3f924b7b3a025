#!/usr/bin/env python3
"""The README's condensed steering tables, free mode beside route mode, from the kept csv files.

    scripts/steering_summary.py [RESULTS]   # RESULTS defaults to results/

Reads what `causaldrive report --csv` wrote (label,suite,metric,mean,std,n):
  route mode  RESULTS/cim_paper/table1.csv, RESULTS/residual_paper/table7.csv and table9.csv
  free mode   RESULTS/steering/cim/table1.csv, RESULTS/steering/residual/dense.csv
and prints two markdown tables: seed 000's table 1 (paper error %, and off-road % in free mode,
success % in brackets) and seed 001's comparison (success / collision / inertia %, and off-road %
in free mode). Cells are mean ± sd over the seeds a csv holds (n); n = 1 prints the mean alone.
"""
import csv
import os
import sys


def load(*paths):
    """{(label, suite, metric): (mean, std, n)} of one or more report csv files."""
    table = {}
    for path in paths:
        with open(path, newline="") as f:
            for row in csv.DictReader(f):
                if not row["mean"]:  # a metric with no value (no event to measure)
                    continue
                std = float(row["std"]) if row["std"] else None
                table[(row["label"], row["suite"], row["metric"])] = (
                    float(row["mean"]), std, int(row["n"]))
    return table


def cell(table, label, suite, metric, sd=True):
    """One metric as a percentage, 'mean ± sd' when the csv has several seeds."""
    key = (label, suite, metric)
    if key not in table:
        return "n/a"
    mean, std, n = table[key]
    text = f"{100 * mean:.0f}"
    if sd and n > 1 and std is not None:
        text += f" ± {100 * std:.0f}"
    return text


def seeds(table, labels):
    """The seed counts behind the rows of labels, for the caption."""
    return sorted({v[2] for k, v in table.items() if k[0] in labels})


def print_head(route, free, methods, suites, column):
    """A table's caption (the seed counts behind it) and markdown header, one column per suite."""
    print(f"seeds per free-mode row: {seeds(free, methods)}; route mode: {seeds(route, methods)}\n")
    print("| method | mode | " + " | ".join(s.replace("town-", "") for s in suites) + " |")
    print("|---|---|" + column * len(suites))


def table1(results):
    route = load(os.path.join(results, "cim_paper/table1.csv"))
    free = load(os.path.join(results, "steering/cim/table1.csv"))
    suites = ["town-a-regular", "town-a-dense", "town-a-stopgo",
              "town-b-regular", "town-b-dense", "town-b-stopgo"]
    methods = ["cs", "dim", "rip", "cim"]
    print_head(route, free, methods, suites, "---:|")
    for m in methods:
        cells = [f"{cell(route, m, s + '-100', 'paper_error_rate')} "
                 f"({cell(route, m, s + '-100', 'success_rate', sd=False)})" for s in suites]
        print(f"| {m} | route | " + " | ".join(cells) + " |")
        cells = [f"{cell(free, m, s, 'paper_error_rate')} / {cell(free, m, s, 'offroad_rate')} "
                 f"({cell(free, m, s, 'success_rate', sd=False)})" for s in suites]
        print(f"| {m} | free | " + " | ".join(cells) + " |")


def dense(results):
    route = load(os.path.join(results, "residual_paper/table7.csv"),
                 os.path.join(results, "residual_paper/table9.csv"))
    free = load(os.path.join(results, "steering/residual/dense.csv"))
    suites = ["town-a-regular", "town-a-dense", "town-b-regular", "town-b-dense"]
    methods = ["bc-so", "bc-oh", "residual", "dagger", "hd", "fca", "keyframe"]
    print_head(route, free, methods, suites, "---|")
    for m in methods:
        for mode, table, metrics in (
                ("route", route, ["success_rate", "collision_rate", "inertia_rate"]),
                ("free", free, ["success_rate", "collision_rate", "inertia_rate", "offroad_rate"])):
            cells = [" / ".join(cell(table, m, s, x) for x in metrics) for s in suites]
            print(f"| {m} | {mode} | " + " | ".join(cells) + " |")


def main():
    results = sys.argv[1] if len(sys.argv) > 1 else "results"
    try:
        table1(results)
        print()
        dense(results)
    except (OSError, KeyError, ValueError) as e:
        sys.exit(f"steering_summary.py: {e}")


if __name__ == "__main__":
    main()
