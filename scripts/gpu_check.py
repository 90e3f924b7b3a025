#!/usr/bin/env python3
"""The steps of scripts/gpu_check.sh (read it first): each step's time, status and figures go into
one JSON object, printed on one line at the end (and written to OUT/gpu_check.json)."""
import glob
import json
import os
import re
import shutil
import signal
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
# DEADLINE_S: seconds from the start after which the remaining steps are skipped (each is named in
# "skipped"), so that a lease's time limit still gets the JSON; 0 for none.
DEADLINE = float(os.environ.get("DEADLINE_S", "0"))
START = time.time()
# STEPS: which of the steps after the build run (default all): bench, train, unit.
STEPS = set(os.environ.get("STEPS", "bench,train,unit").split(","))
report = {"steps": {}, "errors": [], "skipped": []}


def left():
    """Seconds left before DEADLINE_S (None without one)."""
    return DEADLINE - (time.time() - START) if DEADLINE > 0 else None


def log_path(name):
    return os.path.join(OUT, name + ".log")


def run(name, cmd, env=None, timeout=None, check=True):
    """Runs cmd with its output in OUT/name.log; returns (returncode, output). A step that would
    start past DEADLINE_S is skipped (returncode None); one that runs into it is stopped (124)."""
    remaining = left()
    if remaining is not None:
        if remaining < 5:
            report["skipped"].append(name)
            return None, ""
        timeout = min(timeout, remaining) if timeout else remaining
    t = time.time()
    with open(log_path(name), "w") as f:
        f.write("$ " + " ".join(cmd) + "\n")
        f.flush()
        # Its own process group, so that a step stopped at its limit takes its children along
        # (ctest's tests would otherwise keep the output pipe open).
        p = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                             stderr=subprocess.STDOUT, text=True, start_new_session=True)
        try:
            out, _ = p.communicate(timeout=timeout)
            rc = p.returncode
        except subprocess.TimeoutExpired:
            os.killpg(p.pid, signal.SIGKILL)
            out, _ = p.communicate()
            rc = 124
            report["errors"].append(f"{name}: stopped after {timeout:.0f} s")
        f.write(out)
    report["steps"].setdefault(name, 0.0)
    report["steps"][name] = round(report["steps"][name] + time.time() - t, 2)
    if check and rc not in (0, None):
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
    """The machine's PyTorch, whose libtorch causaldrive builds against; a CPU rehearsal on a
    machine without PyTorch builds against the default libtorch (Debian's) and has no peer."""
    report["cores"] = os.cpu_count()
    report["device"] = DEVICE
    for key, cmd in (("compiler", ["c++", "--version"]), ("cmake", ["cmake", "--version"]),
                     ("os", ["sh", "-c", ". /etc/os-release && echo $PRETTY_NAME"]),
                     ("nvidia_smi", ["nvidia-smi", "--query-gpu=name,driver_version,memory.total",
                                     "--format=csv,noheader"])):
        try:
            out = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                 timeout=30).stdout
            report[key] = out.strip().splitlines()[0] if out.strip() else None
        except (OSError, subprocess.TimeoutExpired):
            report[key] = None
    try:
        import torch
    except ImportError:
        if DEVICE == "cuda":
            raise
        report["torch"] = None
        report["torch_prefix"] = None
        return None
    report["torch"] = torch.__version__
    report["cuda"] = torch.version.cuda
    report["gpu"] = torch.cuda.get_device_name(0) if torch.cuda.is_available() else None
    report["torch_prefix"] = torch.utils.cmake_prefix_path
    if DEVICE == "cuda" and not torch.cuda.is_available():
        report["errors"].append("PyTorch sees no GPU here")
    return torch.utils.cmake_prefix_path


def system_sonames():
    """The shared libraries the machine's loader already finds (ldconfig's cache)."""
    try:
        out = subprocess.run(["ldconfig", "-p"], stdout=subprocess.PIPE, text=True).stdout
    except OSError:
        return set()
    return {line.split()[0] for line in out.splitlines()[1:] if line.strip()}


def unpack_debs(env):
    """Carried Debian packages into a private prefix (never into /). The linker sees all of them;
    the programs run with only those runtime libraries the machine lacks (LD_LIBRARY_PATH would
    put a carried one before the machine's own for every program, PyTorch too), HDF5's own
    always, since HDF5 stops a program whose headers and library differ."""
    debs = sorted(glob.glob(os.path.join(DEBS, "*.deb")))
    if not debs:
        return env
    t = time.time()
    os.makedirs(PREFIX, exist_ok=True)
    for d in debs:
        subprocess.run(["dpkg", "-x", d, PREFIX], check=True)
    libs = [os.path.join(PREFIX, sub, "lib", "x86_64-linux-gnu") for sub in ("usr", "")]
    runtime = os.path.join(PREFIX, "runtime")
    shutil.rmtree(runtime, ignore_errors=True)
    os.makedirs(runtime)
    have, used, skipped = system_sonames(), [], []
    for lib in libs:
        for path in sorted(glob.glob(os.path.join(lib, "lib*.so.*"))):
            name = os.path.basename(path)
            if name.startswith("libhdf5") or name not in have:
                os.symlink(os.path.realpath(path), os.path.join(runtime, name))
                used.append(name)
            else:
                skipped.append(name)
    usr = os.path.join(PREFIX, "usr")
    env["CPATH"] = os.path.join(usr, "include") + os.pathsep + env.get("CPATH", "")
    env["LIBRARY_PATH"] = os.pathsep.join(libs + [env.get("LIBRARY_PATH", "")])
    env["LD_LIBRARY_PATH"] = os.pathsep.join([runtime, env.get("LD_LIBRARY_PATH", "")])
    report["steps"]["unpack"] = round(time.time() - t, 2)
    report["carried_debs"] = [os.path.basename(d) for d in debs]
    report["carried_libraries"] = {"used": used, "the_machine_has": skipped}
    return env


def build(env, torch_prefix, targets):
    """Configures and builds TARGETS against the machine's PyTorch (SUMO where its CMake config is
    installed, MuJoCo and the Python module off); returns the causaldrive binary, or finishes the
    report with exit 1 when either step fails."""
    sumo = os.environ.get("SUMO", "auto")
    if sumo == "auto":
        sumo = "ON" if os.path.isdir("/usr/share/sumo/cmake") else "OFF"
    report["build_parts"] = {"sumo": sumo, "mujoco": "OFF", "python_module": "OFF"}
    prefixes = [p for p in [torch_prefix] if p] + ([os.path.join(PREFIX, "usr")] if os.path.isdir(PREFIX) else [])
    gen = ["-G", "Ninja"] if shutil.which("ninja") else []
    rc, _ = run("configure", ["cmake", "-S", ROOT, "-B", BUILD, *gen, "-DCMAKE_BUILD_TYPE=Release",
                              f"-DCD_WITH_SUMO={sumo}", "-DCD_WITH_MUJOCO=OFF",
                              "-DCD_WITH_PYTHON=OFF", f"-DCD_TEST_PYTHON={sys.executable}",
                              "-DCMAKE_PREFIX_PATH=" + ";".join(prefixes)], env=env)
    if rc != 0:
        finish(1)
    rc, _ = run("build", ["cmake", "--build", BUILD, "-j", str(JOBS), "--target", *targets], env=env)
    if rc != 0:
        finish(1)
    return os.path.join(BUILD, "causaldrive")


def main():
    data = sys.argv[1] if len(sys.argv) > 1 else next(
        (d for d in (os.path.join(ROOT, ".gpu/data"), os.path.join(ROOT, "runs/quickstart/data"))
         if os.path.isdir(d)), None)
    torch_prefix = environment()
    env = unpack_debs(dict(os.environ))
    cd = build(env, torch_prefix, ["causaldrive", "causaldrive_unit_tests", "causaldrive_e2e_tests",
                                   "causaldrive_no_mpi_tests"])
    _, version = run("version", [cd, "--version"], env=env)
    report["version"] = version.strip()

    # The training step alone: C++ (bench train) and the PyTorch-Python peer, same network,
    # batch and precision, inputs on the device.
    bench = []
    for backbone in (("small", "resnet34") if "bench" in STEPS else ()):
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
                          [sys.executable, "scripts/gpu_peer.py", "--device", DEVICE, *common,
                           *(["--profile"] if batch == 512 else [])], env=env)
            peer = json.loads(out.strip().splitlines()[-1]) if rc == 0 else None
            if cpp:
                case["cpp_samples_per_s"] = round(cpp["samples_per_s"], 1)
                case["cpp_phases"] = cpp.get("phases")
            if peer:
                case["peer_samples_per_s"] = round(peer["samples_per_s"], 1)
                case["peer_phases"] = peer.get("phases")
            if cpp and peer:
                case.update(ratio=round(cpp["samples_per_s"] / peer["samples_per_s"], 3),
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

    if data and "train" in STEPS:
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
    if "unit" in STEPS:
        unit_tests(env)
    finish(0 if not report["errors"] else 1)


def unit_tests(env):
    """Last, since a lease may end first: the unit tests (train.device's default, auto, resolves
    to CUDA here) and the device tests of the e2e binary."""
    rc, out = run("unit_tests", ["ctest", "--test-dir", BUILD, "-L", "unit", "-j", str(min(JOBS, 8)),
                                 "--output-on-failure", "--timeout", "300"], env=env, check=False)
    m = re.search(r"(\d+)% tests passed, (\d+) tests failed out of (\d+)", out)
    report["unit_tests"] = {
        "passed": int(m.group(3)) - int(m.group(2)) if m else None,
        "failed": int(m.group(2)) if m else None, "total": int(m.group(3)) if m else None,
        "failures": re.findall(r"\d+ - (\S+) \((?:Failed|Timeout|SEGFAULT|Exception)", out)}
    if rc not in (0, None):  # a failed test fails the check
        report["errors"].append(f"unit tests: exit {rc}, failed: {report['unit_tests']['failures']}")
    # The device tests of the e2e binary (the one-line errors skip where CUDA is usable).
    run("device_cli", ["ctest", "--test-dir", BUILD, "-R", "CliDevice", "--output-on-failure"],
        env=env, check=False)


if __name__ == "__main__":
    main()
