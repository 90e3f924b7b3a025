#!/usr/bin/env python3
"""The steps of scripts/gpu_check.sh (read it first): each step's time, status and figures go into
one JSON object, printed on one line at the end (and written to OUT/gpu_check.json)."""
import glob
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
JOBS = int(os.environ.get("JOBS", os.cpu_count() or 1))
BUILD = os.path.join(ROOT, os.environ.get("BUILD", "build-gpu"))
DEBS = os.path.join(ROOT, os.environ.get("CD_DEBS", ".gpu/debs"))
PREFIX = os.path.join(ROOT, ".gpu/prefix")
OUT = os.environ.get("OUT") or tempfile.mkdtemp(prefix="gpu_check.")
# DEVICE=cpu rehearses every step on a machine without a GPU (what was run where).
DEVICE = os.environ.get("DEVICE", "cuda")
report = {"steps": {}, "errors": []}


def log_path(name):
    return os.path.join(OUT, name + ".log")


def run(name, cmd, env=None, timeout=None, check=True):
    """Runs cmd with its output in OUT/name.log; returns (returncode, output)."""
    t = time.time()
    with open(log_path(name), "w") as f:
        f.write("$ " + " ".join(cmd) + "\n")
        f.flush()
        try:
            p = subprocess.run(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True, timeout=timeout)
            rc, out = p.returncode, p.stdout
        except subprocess.TimeoutExpired as e:
            rc, out = 124, (e.stdout or b"").decode() if isinstance(e.stdout, bytes) else (e.stdout or "")
        f.write(out)
    report["steps"].setdefault(name, 0.0)
    report["steps"][name] = round(report["steps"][name] + time.time() - t, 2)
    if check and rc != 0:
        tail = "\n".join(out.strip().splitlines()[-5:])
        report["errors"].append(f"{name}: exit {rc}: {tail}")
    return rc, out


def agreement(backbone, samples, cpu_loss, device_loss, tolerance=0.01):
    """The first epoch's loss on the device against the CPU's; a difference over `tolerance`
    (relative) is an error of the check, so that its exit code fails."""
    rel = abs(device_loss - cpu_loss) / abs(cpu_loss) if cpu_loss else float("inf")
    within = rel <= tolerance
    if not within:
        report["errors"].append(f"{backbone}: the {DEVICE} loss {device_loss:.6g} differs from "
                                f"the CPU's {cpu_loss:.6g} by {100 * rel:.2f}% "
                                f"(tolerance {100 * tolerance:.0f}%)")
    return {"samples": samples, DEVICE: device_loss, "cpu": cpu_loss,
            "relative_difference": rel, "tolerance": tolerance, "within": within}


def finish(code=0):
    line = json.dumps(report, sort_keys=True)
    with open(os.path.join(OUT, "gpu_check.json"), "w") as f:
        f.write(line + "\n")
    print(line, flush=True)
    sys.exit(code)


def environment():
    import torch  # the machine's PyTorch: its libtorch is what causaldrive builds against
    report["torch"] = torch.__version__
    report["cuda"] = torch.version.cuda
    report["gpu"] = torch.cuda.get_device_name(0) if torch.cuda.is_available() else None
    report["cores"] = os.cpu_count()
    report["torch_prefix"] = torch.utils.cmake_prefix_path
    report["device"] = DEVICE
    if DEVICE == "cuda" and not torch.cuda.is_available():
        report["errors"].append("PyTorch sees no GPU here")
    return torch.utils.cmake_prefix_path


def unpack_debs(env):
    """Carried Debian packages into a private prefix (never into /)."""
    debs = sorted(glob.glob(os.path.join(DEBS, "*.deb")))
    if not debs:
        return env
    t = time.time()
    os.makedirs(PREFIX, exist_ok=True)
    for d in debs:
        subprocess.run(["dpkg", "-x", d, PREFIX], check=True)
    usr = os.path.join(PREFIX, "usr")
    env["CPATH"] = os.path.join(usr, "include") + os.pathsep + env.get("CPATH", "")
    lib = os.path.join(usr, "lib", "x86_64-linux-gnu")
    env["LIBRARY_PATH"] = lib + os.pathsep + env.get("LIBRARY_PATH", "")
    env["LD_LIBRARY_PATH"] = lib + os.pathsep + env.get("LD_LIBRARY_PATH", "")
    report["steps"]["unpack"] = round(time.time() - t, 2)
    report["carried_debs"] = [os.path.basename(d) for d in debs]
    return env


def main():
    data = sys.argv[1] if len(sys.argv) > 1 else next(
        (d for d in (os.path.join(ROOT, ".gpu/data"), os.path.join(ROOT, "runs/quickstart/data"))
         if os.path.isdir(d)), None)
    torch_prefix = environment()
    env = unpack_debs(dict(os.environ))
    sumo = os.environ.get("SUMO", "auto")
    if sumo == "auto":
        sumo = "ON" if os.path.isdir("/usr/share/sumo/cmake") else "OFF"
    report["build_parts"] = {"sumo": sumo, "mujoco": "OFF", "python_module": "OFF"}
    prefixes = [torch_prefix] + ([os.path.join(PREFIX, "usr")] if os.path.isdir(PREFIX) else [])
    gen = ["-G", "Ninja"] if shutil.which("ninja") else []
    rc, _ = run("configure", ["cmake", "-S", ROOT, "-B", BUILD, *gen, "-DCMAKE_BUILD_TYPE=Release",
                              f"-DCD_WITH_SUMO={sumo}", "-DCD_WITH_MUJOCO=OFF",
                              "-DCD_WITH_PYTHON=OFF", f"-DCD_TEST_PYTHON={sys.executable}",
                              "-DCMAKE_PREFIX_PATH=" + ";".join(prefixes)], env=env)
    if rc != 0:
        finish(1)
    rc, _ = run("build", ["cmake", "--build", BUILD, "-j", str(JOBS), "--target", "causaldrive",
                          "causaldrive_unit_tests", "causaldrive_e2e_tests"], env=env)
    if rc != 0:
        finish(1)
    cd = os.path.join(BUILD, "causaldrive")
    _, version = run("version", [cd, "--version"], env=env)
    report["version"] = version.strip()

    # Unit tests: train.device's default, auto, resolves to CUDA here.
    rc, out = run("unit_tests", ["ctest", "--test-dir", BUILD, "-L", "unit", "-j", str(min(JOBS, 8)),
                                 "--output-on-failure", "--timeout", "300"], env=env, check=False)
    m = re.search(r"(\d+)% tests passed, (\d+) tests failed out of (\d+)", out)
    report["unit_tests"] = {
        "passed": int(m.group(3)) - int(m.group(2)) if m else None,
        "failed": int(m.group(2)) if m else None, "total": int(m.group(3)) if m else None,
        "failures": re.findall(r"\d+ - (\S+) \((?:Failed|Timeout|SEGFAULT|Exception)", out)}
    # The device tests of the e2e binary (the one-line errors skip where CUDA is usable).
    run("device_cli", ["ctest", "--test-dir", BUILD, "-R", "CliDevice", "--output-on-failure"],
        env=env, check=False)

    # The training step alone: C++ (bench train) and the PyTorch-Python peer, same network,
    # batch and precision, inputs on the device.
    bench = []
    for backbone in ("small", "resnet34"):
        for batch, precision in ((128, "fp32"), (512, "fp32"), (512, "bf16")):
            steps = "100" if backbone == "small" else "40"
            warmup = "10"
            if DEVICE == "cpu":  # a rehearsal: the same calls, few steps
                if precision == "bf16":
                    continue
                steps, warmup = "2", "1"
            common = ["--backbone", backbone, "--batch", str(batch), "--precision", precision,
                      "--steps", steps, "--warmup", warmup]
            case = {"backbone": backbone, "batch": batch, "precision": precision}
            rc, out = run(f"bench_{backbone}_{batch}_{precision}",
                          [cd, "bench", "train", "--device", DEVICE, "--json", *common], env=env)
            cpp = json.loads(out.strip().splitlines()[-1]) if rc == 0 else None
            rc, out = run(f"peer_{backbone}_{batch}_{precision}",
                          [sys.executable, "scripts/gpu_peer.py", "--device", DEVICE, *common], env=env)
            peer = json.loads(out.strip().splitlines()[-1]) if rc == 0 else None
            if cpp and peer:
                case.update(cpp_samples_per_s=round(cpp["samples_per_s"], 1),
                            peer_samples_per_s=round(peer["samples_per_s"], 1),
                            ratio=round(cpp["samples_per_s"] / peer["samples_per_s"], 3),
                            same_parameters=cpp["parameters"] == peer["parameters"])
            bench.append(case)
        # The same step on this machine's CPU cores (batch 128, fp32).
        steps = "20" if backbone == "small" else "3"
        rc, out = run(f"bench_{backbone}_cpu", [cd, "bench", "train", "--device", "cpu", "--json",
                                                "--backbone", backbone, "--batch", "128",
                                                "--steps", steps, "--warmup", "2"], env=env)
        if rc == 0:
            bench.append({"backbone": backbone, "batch": 128, "precision": "fp32", "device": "cpu",
                          "cpp_samples_per_s": round(json.loads(out.strip().splitlines()[-1])["samples_per_s"], 1)})
    report["bench_train"] = bench

    # bc-oh trained by `causaldrive train` on the data folder (loading included), on the device and
    # on the CPU cores, one epoch of a fixed number of samples; the first epoch's loss of the same
    # seed and samples on both (dropout off: its masks come from each device's own generator).
    def train_bc_oh(label, backbone, device, samples):
        """The first epoch's metrics and runtime of one run, or None when it failed."""
        cfg = os.path.join(OUT, label + ".toml")
        with open(cfg, "w") as f:
            f.write(f'[model]\nbackbone = "{backbone}"\ndropout = 0.0\n'
                    f'[train]\nepochs = 1\nbatch_size = 128\nepoch_samples = {samples}\n'
                    f'threads = {os.cpu_count()}\nval_fraction = 0.1\n')
        run_dir = os.path.join(OUT, label)
        rc, _ = run(label, [cd, "train", "--method", "bc-oh", "--data", data, "--config", cfg,
                            "--out", run_dir, "--device", device], env=env)
        if rc != 0:
            return None
        ck = json.load(open(os.path.join(run_dir, "checkpoint.json")))
        ep = ck["metrics"][0]
        return {"samples": samples, "samples_per_s": round(ep["samples_per_s"], 1),
                "train_loss": ep["train_loss"], "val_loss": ep.get("val_loss"),
                "runtime": ck.get("runtime")}

    if data:
        report["data"] = data
        train = {}
        # (backbone, samples on the GPU, samples on the CPU cores)
        for backbone, dev_n, cpu_n in (("small", 65536, 4096), ("resnet34", 16384, 512)):
            cpu = train_bc_oh(f"train_{backbone}_cpu", backbone, "cpu", cpu_n)
            train[f"{backbone}_cpu"] = cpu
            if DEVICE == "cpu":  # a rehearsal: the CPU run stands for both
                same = cpu
            else:
                train[f"{backbone}_{DEVICE}"] = train_bc_oh(f"train_{backbone}_{DEVICE}", backbone,
                                                           DEVICE, dev_n)
                same = train_bc_oh(f"agree_{backbone}_{DEVICE}", backbone, DEVICE, cpu_n)
            if cpu and same:
                train[f"{backbone}_agreement"] = agreement(backbone, cpu_n, cpu["train_loss"],
                                                           same["train_loss"])
        report["train"] = train
    finish(0 if not report["errors"] else 1)


if __name__ == "__main__":
    main()
