#!/usr/bin/env python3
"""Training runs on a lent GPU machine, in one command (docs/gpu.md, "Training runs there"):
builds causaldrive as scripts/gpu_check.sh does (its carried packages, its PyTorch), then trains
the listed runs on the device, PARALLEL at a time, until DEADLINE_S; the finished runs come back
packed, the rest are named as not finished.

    scripts/gpu_runs.py RUNS

RUNS: a text file, one run per line: NAME METHOD CONFIG DATA SEED (# starts a comment). DATA is
a `causaldrive collect` folder, a .tar.xz of one (unpacked once, beside it) or a folder of parts
(scripts/gpu_travel.sh split; joined once, beside it, as PATH.joined). NAME is the run's
folder relative to the packs (e.g. train/seed2/bc-oh).

Environment: gpu_check's (JOBS, BUILD, CD_DEBS, DEVICE, DEADLINE_S; OUT takes the logs) and
  PACK      where the packs and gpu_runs.json go (required: the lease's $OUT)
  PARALLEL  runs at a time (default 4), each with cores / PARALLEL torch threads
  PACK_MB   the largest pack (default 15 MB): packs are uncompressed tars of finished runs,
            NAME/{best.pt,checkpoint.json,metrics.jsonl} (what an agent loads and the record);
            a run's resume state (model.pt, optimizer.pt) stays behind
  MAX_PACKS how many packs at most (default 7); finished runs that do not fit are named
  MIN_RUN_S a run starts only while more than this many seconds are left before DEADLINE_S
            (default 30); set it to a run's measured time so that none starts that cannot end
            (a residual run took 272-279 s on the H200 at PARALLEL=4)
  CD        a causaldrive binary to use instead of building one (a rehearsal with DEVICE=cpu)
Each run's record (checkpoint.json) names the device it trained on.
"""
import json
import os
import signal
import subprocess
import sys
import tarfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gpu_check as gc  # noqa: E402
from gpu_import import extract  # noqa: E402

PACK = os.environ.get("PACK")
PARALLEL = int(os.environ.get("PARALLEL", "4"))
PACK_MB = float(os.environ.get("PACK_MB", "15"))
MAX_PACKS = int(os.environ.get("MAX_PACKS", "7"))
MIN_RUN_S = float(os.environ.get("MIN_RUN_S", "30"))
KEPT_FILES = ("best.pt", "checkpoint.json", "metrics.jsonl")


def read_runs(path):
    runs = []
    with open(path) as f:
        for n, line in enumerate(f, 1):
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            parts = line.split()
            if len(parts) != 5:
                sys.exit(f"error: {path}:{n}: expected NAME METHOD CONFIG DATA SEED, got '{line}'")
            runs.append(dict(zip(("name", "method", "config", "data", "seed"), parts)))
    return runs


def join_parts(path):
    """A folder of parts (scripts/gpu_travel.sh split: part1, part2, ... carried one a call) ->
    the collect folder they make, PATH.joined, as hard links (once the parts are all there)."""
    parts = sorted(d for d in os.listdir(path) if d.startswith("part"))
    dest = path.rstrip("/") + ".joined"
    if os.path.isdir(dest):
        return dest
    if not os.path.exists(os.path.join(path, "part1", "collect.json")):
        sys.exit(f"error: {path}: part1/collect.json missing (carry part1 first)")
    os.makedirs(dest + ".tmp", exist_ok=True)
    for d in parts:
        for f in os.listdir(os.path.join(path, d)):
            target = os.path.join(dest + ".tmp", f)
            if not os.path.exists(target):
                os.link(os.path.join(path, d, f), target)
    os.rename(dest + ".tmp", dest)
    gc.report["steps"]["join " + os.path.basename(path)] = len(parts)
    return dest


def unpack_data(path):
    """A .tar.xz of a collect folder -> the folder beside it (once); a folder of parts ->
    join_parts; a folder as it is."""
    if os.path.isdir(path) and os.path.isdir(os.path.join(path, "part1")):
        return join_parts(path)
    if not path.endswith(".tar.xz"):
        return path
    dest = path[: -len(".tar.xz")]
    if not os.path.isdir(dest):
        t = time.time()
        with tarfile.open(path) as tar:
            extract(tar, dest + ".tmp", path)
        os.rename(dest + ".tmp", dest)
        gc.report["steps"]["unpack " + os.path.basename(dest)] = round(time.time() - t, 2)
    return dest


def train_all(cd, env, runs, work):
    """Runs the queue, PARALLEL at a time; stops what is left at DEADLINE_S."""
    threads = max(1, (os.cpu_count() or 1) // PARALLEL)
    queue, active, status = list(runs), {}, {}
    while queue or active:
        left = gc.left()
        while queue and len(active) < PARALLEL and (left is None or left > MIN_RUN_S):
            r = queue.pop(0)
            out = os.path.join(work, r["name"])
            os.makedirs(os.path.dirname(out), exist_ok=True)
            log = open(os.path.join(gc.OUT, r["name"].replace("/", "_") + ".log"), "w")
            cmd = [cd, "train", "--method", r["method"], "--config", r["config"],
                   "--data", unpack_data(r["data"]), "--seed", r["seed"], "--out", out,
                   "--device", gc.DEVICE, "--threads", str(threads)]
            log.write("$ " + " ".join(cmd) + "\n")
            log.flush()
            p = subprocess.Popen(cmd, cwd=gc.ROOT, env=env, stdout=log, stderr=subprocess.STDOUT,
                                 start_new_session=True)
            active[p] = (r, out, log, time.time())
        for p in list(active):
            r, out, log, t = active[p]
            if p.poll() is None:
                continue
            log.close()
            del active[p]
            status[r["name"]] = {"exit": p.returncode, "seconds": round(time.time() - t, 1)}
            if p.returncode != 0:
                with open(log.name) as f:
                    tail = " | ".join(f.read().strip().splitlines()[-3:])
                gc.report["errors"].append(f"{r['name']}: exit {p.returncode}: {tail}")
        left = gc.left()
        if left is not None and left < 15:
            for p, (r, _, log, t) in active.items():
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
                log.close()
                status[r["name"]] = {"exit": "stopped at the deadline",
                                     "seconds": round(time.time() - t, 1)}
            active = {}
            for r in queue:
                status[r["name"]] = {"exit": "not started (deadline)"}
            queue = []
        time.sleep(1)
    return status


def pack(runs, status, work):
    """The finished runs into at most MAX_PACKS tars of at most PACK_MB each."""
    packs, current, size = [], [], 0
    limit = PACK_MB * 1e6
    for r in runs:
        st = status.get(r["name"], {})
        if st.get("exit") != 0:
            continue
        out = os.path.join(work, r["name"])
        files = [os.path.join(out, f) for f in KEPT_FILES]
        ck = json.load(open(os.path.join(out, "checkpoint.json")))
        st["device"] = ck.get("runtime", {}).get("device")
        st["samples_per_s"] = [round(m["samples_per_s"]) for m in ck.get("metrics", [])]
        need = sum(os.path.getsize(f) for f in files)
        if current and size + need > limit:
            packs.append(current)
            current, size = [], 0
        current.append((r["name"], files))
        size += need
    if current:
        packs.append(current)
    for i, members in enumerate(packs):
        if i >= MAX_PACKS:
            for name, _ in members:
                status[name]["packed"] = False
            continue
        path = os.path.join(PACK, f"runs_{i}.tar")
        with tarfile.open(path, "w") as tar:
            for name, files in members:
                for f in files:
                    tar.add(f, arcname=os.path.join(name, os.path.basename(f)))
                status[name]["packed"] = os.path.basename(path)


def main():
    if len(sys.argv) != 2 or not PACK:
        sys.exit("usage: PACK=DIR scripts/gpu_runs.py RUNS")
    runs = read_runs(sys.argv[1])
    os.makedirs(PACK, exist_ok=True)
    os.makedirs(gc.OUT, exist_ok=True)
    torch_prefix = gc.environment()
    env = gc.unpack_debs(dict(os.environ))
    cd = os.environ.get("CD") or gc.build(env, torch_prefix, ["causaldrive"])
    work = os.path.join(gc.ROOT, ".gpu", "runs")
    status = train_all(cd, env, runs, work)
    pack(runs, status, work)
    gc.report["runs"] = status
    gc.report["parallel"] = PARALLEL
    with open(os.path.join(PACK, "gpu_runs.json"), "w") as f:
        json.dump(gc.report, f, sort_keys=True, indent=1)
    gc.finish(0 if not gc.report["errors"] else 1)


if __name__ == "__main__":
    main()
