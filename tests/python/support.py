"""What the Python tests share: the binary, temporary folders, a fast test config."""
import functools
import json
import os
import shutil
import subprocess
import tempfile
import unittest

BIN = os.environ.get("CAUSALDRIVE_BIN", "build/causaldrive")


@functools.lru_cache(maxsize=None)
def _version():
    try:
        return subprocess.run([BIN, "--version"], capture_output=True, text=True).stdout
    except OSError:
        return ""  # no binary: the tests say so themselves


def _needs(part, option):
    """A decorator: the test is skipped in a build without an optional part ("SUMO", "MuJoCo"),
    as `causaldrive --version` says (asked once, by the files that use it)."""
    def decorate(test):
        return unittest.skipIf(part + ": no" in _version(), "needs %s (-D%s=OFF)" % (part, option))(test)
    return decorate


# A test that needs an optional part of the build (docs/gpu.md) is skipped without it; a file
# that needs one throughout says "# needs: PART" in its first lines and CMake leaves it out.
needs_sumo = _needs("SUMO", "CD_WITH_SUMO")
needs_mujoco = _needs("MuJoCo", "CD_WITH_MUJOCO")

# A fast world for tests (as tests/support/test_support.hpp's test config): town-a, a short
# warm-up, short routes.
FAST = {"world.town": "town-a", "world.warmup_s": 5.0, "collect.min_route_m": 100.0,
        "collect.max_route_m": 200.0, "collect.workers": 1, "eval.workers": 1}


def write_config(folder, traffic="regular"):
    path = os.path.join(folder, "test.toml")
    with open(path, "w") as f:
        f.write("[world]\ntown = \"town-a\"\ntraffic = \"%s\"\nwarmup_s = 5\n" % traffic)
        f.write("[collect]\nworkers = 1\nmin_route_m = 100\nmax_route_m = 200\n")
        f.write("[eval]\nworkers = 1\n")
    return path


def cli(*args):
    """Runs the binary; fails the test with its output unless it exits with 0."""
    r = subprocess.run([BIN] + [str(a) for a in args], capture_output=True, text=True)
    if r.returncode != 0:
        raise AssertionError("causaldrive %s failed (%d):\n%s%s" %
                             (" ".join(map(str, args)), r.returncode, r.stdout, r.stderr))
    return r


def small_suite(folder, tasks=2, trials=1, scenarios=("route",), seed=5, traffic="regular"):
    path = os.path.join(folder, "small.json")
    cli("suite", "--town", "town-a", "--traffic", traffic, "--tasks", tasks, "--trials", trials,
        "--seed", seed, "--min-route", 100, "--max-route", 160, "--scenarios", *scenarios,
        "--out", path)
    return path


def read_json(path):
    with open(path) as f:
        return json.load(f)


class TempDirCase(unittest.TestCase):
    def setUp(self):
        self.dir = tempfile.mkdtemp(prefix="cd_py_")

    def tearDown(self):
        shutil.rmtree(self.dir, ignore_errors=True)
