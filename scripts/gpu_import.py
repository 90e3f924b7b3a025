#!/usr/bin/env python3
"""Brings back the training runs a lent GPU machine trained (scripts/gpu_runs.py's packs) into
a campaign's folders, as `kept_train` (scripts/paper_lib.sh) would have left them here:

    scripts/gpu_import.py [--out runs/verdicts] [--keep results/verdicts] [--max-mb 5] PACK.tar...

Each pack holds NAME/best.pt, NAME/checkpoint.json and NAME/metrics.jsonl per finished run. A
run goes to OUT/NAME (replacing an unfinished folder of the same run trained here, which is not
kept), and is kept: KEEP/NAME with its weights where best.pt is at most --max-mb MB (git
ignores the weights: scripts/keep_weights.sh keeps them in history), else KEEP/NAME.record
with its record only (the weights stay in OUT/NAME). A run already kept (KEEP/NAME or
KEEP/NAME.record) is left as it is and named. A pack that is not one, or a run without its
three files, stops the import before anything is written, in one line.
"""
import argparse
import json
import os
import shutil
import sys
import tarfile
import tempfile

FILES = ("best.pt", "checkpoint.json", "metrics.jsonl")


def fail(msg):
    sys.exit("gpu_import: " + msg)


def extract(tar, dest, pack):
    """The pack's plain files and folders under dest; a link, a device or a path leaving dest
    stops the import. Python's own 'data' filter where it has one (3.11.4+; Debian 12 has
    3.11.2), the same checks by hand where not."""
    for m in tar.getmembers():
        if not (m.isfile() or m.isdir()) or os.path.isabs(m.name) or ".." in m.name.split("/"):
            fail(f"{pack}: not a pack of scripts/gpu_runs.py ({m.name} is not a plain file "
                 "inside the pack)")
    if hasattr(tarfile, "data_filter"):
        tar.extractall(dest, filter="data")
    else:
        tar.extractall(dest)


def read_packs(packs, tmp):
    """Every pack unpacked under tmp; returns {NAME: folder} of the runs they hold."""
    runs = {}
    for i, pack in enumerate(packs):
        try:
            with tarfile.open(pack) as tar:
                dest = os.path.join(tmp, str(i))
                extract(tar, dest, pack)
        except tarfile.TarError:
            fail(f"{pack}: not a pack of scripts/gpu_runs.py (not a tar file)")
        except OSError as e:
            fail(f"{pack}: {e.strerror or e}")
        for root, _, files in os.walk(dest):
            if "checkpoint.json" in files or "best.pt" in files:
                name = os.path.relpath(root, dest)
                missing = [f for f in FILES if f not in files]
                if missing:
                    fail(f"{pack}: {name} lacks {', '.join(missing)}")
                try:
                    with open(os.path.join(root, "checkpoint.json")) as f:
                        json.load(f)
                except ValueError as e:
                    fail(f"{pack}: {name}/checkpoint.json is not JSON ({e})")
                runs[name] = root
    if not runs:
        fail("the packs hold no run")
    return runs


def place(src, dest, files):
    tmp = dest + ".tmp"
    shutil.rmtree(tmp, ignore_errors=True)
    os.makedirs(tmp)
    for f in files:
        shutil.copy2(os.path.join(src, f), tmp)
    shutil.rmtree(dest, ignore_errors=True)
    os.makedirs(os.path.dirname(dest), exist_ok=True)
    os.rename(tmp, dest)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="runs/verdicts")
    ap.add_argument("--keep", default="results/verdicts")
    ap.add_argument("--max-mb", type=float, default=5.0)
    ap.add_argument("packs", nargs="+")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="gpu_import.") as tmp:
        runs = read_packs(a.packs, tmp)
        weights = []
        for name in sorted(runs):
            src, out = runs[name], os.path.join(a.out, name)
            kept = os.path.join(a.keep, name)
            if os.path.isdir(kept) or os.path.isdir(kept + ".record"):
                print(f"{name}: kept already, left as it is")
                continue
            with open(os.path.join(src, "checkpoint.json")) as f:
                device = json.load(f).get("runtime", {}).get("device", "?")
            place(src, out, FILES)
            if os.path.getsize(os.path.join(src, "best.pt")) <= a.max_mb * 1e6:
                place(src, kept, FILES)
                weights.append(kept)
                print(f"{name}: trained on {device}; {out} and kept in {kept}")
            else:
                place(src, kept + ".record", ("checkpoint.json", "metrics.jsonl"))
                print(f"{name}: trained on {device}; {out} (weights over {a.max_mb:g} MB), "
                      f"its record kept in {kept}.record")
        if weights:
            print("keep the weights in history: scripts/keep_weights.sh " + " ".join(weights))


if __name__ == "__main__":
    main()
