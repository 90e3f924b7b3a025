"""The reproduction scripts' command line (scripts/*_paper.sh, run_steps in paper_lib.sh):
several steps run in order, an unknown step is refused before any step runs; kept_train keeps a
finished run and copies a kept one back without training; kept_json keeps a report and never
measures a kept one again; kept_report keeps no table over a partial run; suite_of generates
suites of any size; steering_summary.py condenses the kept csv files; config_variant.py sets
keys of a config; diagnose_table.py sums diagnose reports over seeds; turn_failures.py
classifies a route's junction passages by their turn; gpu_travel.sh counts what a call to a lent
machine carries and moves results/ out and back; gpu_import.py brings its packs back;
verdicts.sh's ablations and report steps."""
import importlib.util
import io
import json
import os
import subprocess
import sys
import unittest

from support import BIN, TempDirCase, needs_sumo

SOURCE = os.environ.get("CAUSALDRIVE_SOURCE_DIR",
                        os.path.join(os.path.dirname(__file__), "..", ".."))
SCRIPTS = ["cim_paper", "residual_paper", "steering_paper", "mujoco_paper"]


class PaperScriptsTest(TempDirCase):
    def run_script(self, name, *steps, **env):
        out = os.path.join(self.dir, "out")
        full = dict(os.environ, CD=os.path.abspath(BIN), OUT=out,
                    KEEP=os.path.join(self.dir, "keep"), **env)
        return subprocess.run([os.path.join(SOURCE, "scripts", name + ".sh"), *steps],
                              env=full, capture_output=True, text=True, timeout=120)

    def test_no_step_prints_the_usage(self):
        for name in SCRIPTS:
            with self.subTest(script=name):
                r = self.run_script(name)
                self.assertEqual(r.returncode, 2, r.stderr)
                # The usage is the header comment under the shebang, without its "# ".
                header = []
                with open(os.path.join(SOURCE, "scripts", name + ".sh")) as f:
                    for line in f.read().splitlines()[1:]:
                        if not line.startswith("#"):
                            break
                        header.append(line[2:] if line.startswith("# ") else line[1:])
                self.assertGreater(len(header), 5)
                self.assertEqual(r.stdout.splitlines(), header)
                self.assertIn("scripts/%s.sh" % name, r.stdout)

    def test_an_unknown_step_is_refused_before_any_step_runs(self):
        for name in SCRIPTS:
            with self.subTest(script=name):
                # A known step first: it must not run when a later name is wrong.
                r = self.run_script(name, "train", "tabel")
                self.assertEqual(r.returncode, 2, r.stdout + r.stderr)
                self.assertEqual(r.stderr.strip().splitlines(),
                                 [r.stderr.strip().splitlines()[0]])
                self.assertRegex(r.stderr, r"^error: unknown step 'tabel' \(steps: .*train")
                self.assertEqual(r.stdout, "")
                self.assertFalse(os.path.exists(os.path.join(self.dir, "out")))

    def test_several_steps_run_in_order(self):
        experts = os.path.join(self.dir, "experts")
        os.makedirs(experts)
        open(os.path.join(experts, "reacher.pt"), "w").close()
        # `experts` keeps an expert file that has no .resume beside it: each step says so.
        r = self.run_script("mujoco_paper", "experts", "experts", ENVS="reacher",
                            EXPERTS=experts)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertEqual(r.stderr.count("reacher.pt: kept"), 2, r.stderr)


class KeptTrainTest(TempDirCase):
    """paper_lib.sh's kept_train with a stand-in for the binary that records each call and writes
    a run (run.json, weights, series.csv, the policy family's resume state) into its --out
    folder."""

    def kept_train(self, label, **extra):
        fake = os.path.join(self.dir, "fake_cd")
        with open(fake, "w") as f:
            f.write('#!/usr/bin/env bash\necho "$*" >> "%s/calls"\n'
                    'while [[ $1 != --out ]]; do shift; done\nmkdir -p "$2"\n'
                    'echo "{}" > "$2/run.json"; echo w > "$2/vae.pt"; echo s > "$2/series.csv"\n'
                    'echo b > "$2/best.pt"; echo m > "$2/model.pt"; echo o > "$2/optimizer.pt"\n'
                    '[[ -z ${BIG:-} ]] || cp "$BIG" "$2/best.pt"\n'
                    % self.dir)
        os.chmod(fake, 0o755)
        script = ('source "%s/scripts/paper_lib.sh"\n'
                  'kept_train "$OUT/train/seed0/%s" --method cim --seed 0\n') % (SOURCE, label)
        env = dict(os.environ, CD=fake, OUT=os.path.join(self.dir, "out"),
                   KEEP=os.path.join(self.dir, "keep"), **extra)
        r = subprocess.run(["bash", "-c", script], env=env, capture_output=True, text=True,
                           timeout=60)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.stderr = r.stderr
        calls = os.path.join(self.dir, "calls")
        return open(calls).read().splitlines() if os.path.exists(calls) else []

    def test_a_new_run_is_trained_and_kept_without_its_series_or_resume_state(self):
        calls = self.kept_train("cim")
        self.assertEqual(calls, ["train --method cim --seed 0 --out %s/out/train/seed0/cim"
                                 % self.dir])
        kept = os.path.join(self.dir, "keep", "train", "seed0", "cim")
        self.assertEqual(sorted(os.listdir(os.path.dirname(kept))), ["cim"])  # no cim.tmp left
        self.assertEqual(sorted(os.listdir(kept)), ["best.pt", "run.json", "vae.pt"])
        for name in ("series.csv", "model.pt", "optimizer.pt"):
            self.assertTrue(os.path.exists(os.path.join(self.dir, "out/train/seed0/cim", name)))

    def test_a_run_with_a_file_over_the_limit_is_trained_but_not_kept(self):
        calls = self.kept_train("cim", KEEP_MAX_MB="0")
        self.assertEqual(len(calls), 1)
        # Every file is over 0 MB: nothing is kept, not even a record, and no run folder.
        seed0 = os.path.join(self.dir, "keep", "train", "seed0")
        self.assertEqual(os.listdir(seed0), ["cim.record"])
        self.assertEqual(os.listdir(os.path.join(seed0, "cim.record")), [])
        self.assertIn("out/train/seed0/cim: not kept (", self.stderr)
        self.assertTrue(os.path.exists(os.path.join(self.dir, "out/train/seed0/cim/vae.pt")))

    def test_a_run_with_weights_over_the_limit_keeps_its_record(self):
        # The fake's files are 2-3 bytes: a limit of 0 MB takes all; make best.pt large instead.
        fake_big = os.path.join(self.dir, "big")
        with open(fake_big, "wb") as f:
            f.write(b"x" * 2_000_001)
        calls = self.kept_train("cim", KEEP_MAX_MB="2", BIG=fake_big)
        self.assertEqual(len(calls), 1)
        seed0 = os.path.join(self.dir, "keep", "train", "seed0")
        self.assertEqual(sorted(os.listdir(seed0)), ["cim.record"])
        self.assertEqual(sorted(os.listdir(os.path.join(seed0, "cim.record"))),
                         ["run.json", "vae.pt"])
        self.assertIn("not kept (best.pt over 2 MB)", self.stderr)

    def test_a_kept_run_is_copied_back_and_not_trained(self):
        kept = os.path.join(self.dir, "keep", "train", "seed0", "dim")
        os.makedirs(kept)
        for name, text in (("dim.json", '{"kept": 1}'), ("member_0.pt", "weights")):
            with open(os.path.join(kept, name), "w") as f:
                f.write(text)
        self.assertEqual(self.kept_train("dim"), [])
        out = os.path.join(self.dir, "out", "train", "seed0", "dim")
        self.assertEqual(sorted(os.listdir(out)), ["dim.json", "member_0.pt"])
        with open(os.path.join(out, "member_0.pt")) as f:
            self.assertEqual(f.read(), "weights")

    def test_a_recorded_run_with_its_weights_here_is_not_trained_again(self):
        # Weights over the limit, trained here or imported from a lent machine: the record is
        # kept and the weights are in the run folder, which has no resume state.
        os.makedirs(os.path.join(self.dir, "keep", "train", "seed0", "residual.record"))
        out = os.path.join(self.dir, "out", "train", "seed0", "residual")
        os.makedirs(out)
        with open(os.path.join(out, "best.pt"), "w") as f:
            f.write("gpu")
        self.assertEqual(self.kept_train("residual"), [])
        self.assertEqual(os.listdir(out), ["best.pt"])
        # Without its weights here (a fresh checkout), it trains again.
        os.remove(os.path.join(out, "best.pt"))
        self.assertEqual(len(self.kept_train("residual")), 1)


class KeptJsonTest(TempDirCase):
    """paper_lib.sh's kept_json FILE CMD...: CMD's output as FILE, kept; a kept FILE is final."""

    def kept_json(self, command):
        script = ('source "%s/scripts/paper_lib.sh"\nkept_json "$OUT/probe/seed0/bc-oh.json" %s\n'
                  % (SOURCE, command))
        env = dict(os.environ, CD=os.path.abspath(BIN), OUT=os.path.join(self.dir, "out"),
                   KEEP=os.path.join(self.dir, "keep"), CALLS=os.path.join(self.dir, "calls"))
        return subprocess.run(["bash", "-c", script], env=env, capture_output=True, text=True,
                              timeout=60)

    def path(self, root):
        return os.path.join(self.dir, root, "probe", "seed0", "bc-oh.json")

    def test_the_output_is_written_and_kept(self):
        r = self.kept_json("""bash -c 'echo run >> "$CALLS"; echo "{\\"a\\": 1}"'""")
        self.assertEqual(r.returncode, 0, r.stderr)
        for root in ("out", "keep"):
            with open(self.path(root)) as f:
                self.assertEqual(json.load(f), {"a": 1})
        self.assertEqual(sorted(os.listdir(os.path.dirname(self.path("keep")))), ["bc-oh.json"])

    def test_a_kept_report_is_not_measured_again(self):
        os.makedirs(os.path.dirname(self.path("keep")))
        with open(self.path("keep"), "w") as f:
            f.write('{"kept": 1}')
        r = self.kept_json("""bash -c 'echo run >> "$CALLS"; echo "{}"'""")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertFalse(os.path.exists(os.path.join(self.dir, "calls")))
        with open(self.path("keep")) as f:
            self.assertEqual(f.read(), '{"kept": 1}')

    def test_a_report_without_its_kept_copy_is_measured_again(self):
        os.makedirs(os.path.dirname(self.path("out")))
        with open(self.path("out"), "w") as f:
            f.write('{"stale": 1}')
        r = self.kept_json("""bash -c 'echo run >> "$CALLS"; echo "{\\"a\\": 2}"'""")
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(self.dir, "calls")) as f:
            self.assertEqual(f.read(), "run\n")
        for root in ("out", "keep"):
            with open(self.path(root)) as f:
                self.assertEqual(json.load(f), {"a": 2})

    def test_a_failed_command_leaves_no_report(self):
        r = self.kept_json("""bash -c 'echo "{\\"half"; exit 3'""")
        self.assertNotEqual(r.returncode, 0)
        self.assertEqual(r.stderr.strip().splitlines(),
                         ["error: no %s (its command failed)" % self.path("out")])
        self.assertEqual(os.listdir(os.path.dirname(self.path("out"))), [])  # no .tmp left
        self.assertFalse(os.path.exists(self.path("keep")))


class KeptReportTest(TempDirCase):
    """paper_lib.sh's kept_report: the real `causaldrive report` over two evaluations (a kept
    results.json of the camera's tuning, copied); the table is kept only when no run holds an
    infrastructure failure."""

    RESULTS = os.path.join(SOURCE, "results", "camera", "recipe", "eval", "old", "seed0", "bc-oh",
                           "regular", "results.json")

    def write_run(self, name, failed=0):
        with open(self.RESULTS) as f:
            results = json.load(f)
        for episode in results["episodes"][:failed]:
            episode["outcome"] = "infrastructure_failure"
        path = os.path.join(self.dir, "out", "eval", name)
        os.makedirs(path)
        with open(os.path.join(path, "results.json"), "w") as f:
            json.dump(results, f)
        return path

    def kept_report(self, *dirs):
        script = ('source "%s/scripts/paper_lib.sh"\nkept_report table1 outcomes %s\n'
                  % (SOURCE, " ".join(dirs)))
        env = dict(os.environ, CD=os.path.abspath(BIN), OUT=os.path.join(self.dir, "out"),
                   KEEP=os.path.join(self.dir, "keep"))
        return subprocess.run(["bash", "-c", script], env=env, capture_output=True, text=True,
                              timeout=60)

    def test_a_table_of_complete_runs_is_kept(self):
        r = self.kept_report(self.write_run("a"), self.write_run("b"))
        self.assertEqual(r.returncode, 0, r.stderr)
        for name in ("table1.md", "table1.csv"):
            with open(os.path.join(self.dir, "out", name)) as f, \
                    open(os.path.join(self.dir, "keep", name)) as g:
                self.assertEqual(f.read(), g.read())

    def test_a_table_over_a_partial_run_is_written_but_not_kept(self):
        os.makedirs(os.path.join(self.dir, "keep"))
        with open(os.path.join(self.dir, "keep", "table1.md"), "w") as f:
            f.write("kept before\n")
        partial = self.write_run("b", failed=3)
        r = self.kept_report(self.write_run("a"), partial)
        self.assertNotEqual(r.returncode, 0)
        self.assertEqual(r.stderr.strip().splitlines()[-1],
                         "error: %s/out/table1.md not kept: 1 run(s) hold episodes that failed "
                         "outside the agent (run the step again to retry them): %s"
                         % (self.dir, partial))
        self.assertTrue(os.path.exists(os.path.join(self.dir, "out", "table1.md")))  # to look at
        with open(os.path.join(self.dir, "keep", "table1.md")) as f:
            self.assertEqual(f.read(), "kept before\n")
        self.assertFalse(os.path.exists(os.path.join(self.dir, "keep", "table1.csv")))


class DiagnoseTableTest(TempDirCase):
    """scripts/diagnose_table.py against hand-computed means and sds over seeds."""

    @staticmethod
    def report(count, label, pred, r2):
        comp = lambda l, p, q: {"label_mean": l, "label_sd": 0.1, "pred_mean": p, "pred_sd": 0.1,
                                "mae": abs(l - p), "r2": q}
        return {"components": ["throttle", "brake"], "situations": {
            "cruising": {"count": count, "throttle": comp(label, pred, r2),
                         "brake": comp(0.0, 0.0, None)},
            "starting": {"count": 10, "throttle": comp(1.0, pred, None),
                         "brake": comp(0.0, 0.0, None)}}}

    def table(self, *methods):
        return subprocess.run([os.path.join(SOURCE, "scripts", "diagnose_table.py"), self.dir,
                               "--seeds", "0", "1", "--methods", *methods],
                              capture_output=True, text=True, timeout=60)

    def test_cells_are_mean_and_sd_over_seeds(self):
        for seed, (count, pred, r2) in enumerate([(100, 0.30, -2.0), (200, 0.50, -4.0)]):
            os.makedirs(os.path.join(self.dir, "seed%d" % seed))
            with open(os.path.join(self.dir, "seed%d" % seed, "bc-so.json"), "w") as f:
                json.dump(self.report(count, 0.12, pred, r2), f)
        r = self.table("bc-so", "bc-oh")  # bc-oh has no report: skipped
        self.assertEqual(r.returncode, 0, r.stderr)
        rows = {line.split("|")[1].strip(): [c.strip() for c in line.split("|")[2:-1]]
                for line in r.stdout.splitlines() if line.startswith("| ") and "---" not in line}
        # frames 150 +- 70.7; throttle label 0.12 +- 0; prediction 0.40 +- 0.1414; R2 -3 +- 1.414
        self.assertEqual(rows["cruising"], ["150 ± 71", "0.12 ± 0.00", "0.40 ± 0.14",
                                            "-3.00 ± 1.41", "0.00 ± 0.00", "0.00 ± 0.00", "-"])
        self.assertEqual(rows["starting"][0:4], ["10 ± 0", "1.00 ± 0.00", "0.40 ± 0.14", "-"])
        self.assertEqual(list(rows)[1:], ["starting", "cruising"])  # the situations' fixed order
        self.assertNotIn("bc-oh", r.stdout)

    def test_no_report_at_all_is_one_line_and_exit_1(self):
        r = self.table("bc-so")
        self.assertEqual(r.returncode, 1)
        self.assertEqual(r.stderr.strip().splitlines(),
                         ["error: no diagnose report under %s for bc-so" % self.dir])


@unittest.skipUnless(os.path.isdir("/usr/share/sumo/tools/sumolib"), "needs sumo-tools' sumolib")
class TurnFailuresTest(unittest.TestCase):
    """scripts/turn_failures.py's turn classification and junction positions on hand-made edges
    (stand-ins with sumolib's methods), against hand computation."""

    @classmethod
    def setUpClass(cls):
        spec = importlib.util.spec_from_file_location(
            "turn_failures", os.path.join(SOURCE, "scripts", "turn_failures.py"))
        cls.tf = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(cls.tf)

    class Edge:
        def __init__(self, shape, length, via=None):
            self.shape, self.length, self.via = shape, length, via or {}

        def getShape(self):
            return self.shape

        def getLength(self):
            return self.length

        def getOutgoing(self):
            conn = lambda lane: type("C", (), {"getViaLaneID": lambda self: lane})()
            return {e: [conn(lane)] for e, lane in self.via.items()}

    def test_turns_are_signed_and_rounded(self):
        east = self.Edge([(0, 0), (100, 0)], 100)
        north = self.Edge([(105, 5), (105, 100)], 95)
        south = self.Edge([(105, -5), (105, -100)], 95)
        # 120 degrees to the right of east: heading -120 degrees.
        sharp = self.Edge([(104, -2), (104 - 50, -2 - 50 * 3 ** 0.5)], 100)
        self.assertEqual(self.tf.turn_angle(east, north), 90)
        self.assertEqual(self.tf.turn_angle(east, south), -90)
        self.assertEqual(self.tf.turn_angle(east, sharp), -120)
        self.assertEqual(self.tf.turn_angle(east, self.Edge([(106, 1), (200, 3)], 94)), 0)

    def test_junctions_lie_where_the_route_reaches_them(self):
        b = self.Edge([(110, 0), (110, 80)], 80)
        c = self.Edge([(110, 90), (0, 90)], 110)
        a = self.Edge([(0, 0), (100, 0)], 100, via={b: ":j0_0_0"})
        b.via = {c: ":j1_0_0"}
        lanes = {":j0_0_0": 12.0, ":j1_0_0": 9.0}
        net = type("Net", (), {
            "getEdge": lambda self, e: {"a": a, "b": b, "c": c}[e],
            "getLane": lambda self, lane: type("L", (), {"getLength": lambda s: lanes[lane]})()})()
        got = self.tf.junctions(net, {"route": ["a", "b", "c"], "start_pos": 30.0})
        # a from 30 m: 70 m to its end, 12 m through j0, 80 m of b, 9 m through j1.
        self.assertEqual(got, [(70.0, 82.0, 90), (162.0, 171.0, 90)])


@needs_sumo
class SuiteOfTest(TempDirCase):
    """paper_lib.sh's suite_of: a suite of $TASKS tasks generated from the name's fixed seed."""

    def suite_of(self, name, tasks, config=None, out="out"):
        env = dict(os.environ, CD=os.path.abspath(BIN), OUT=os.path.join(self.dir, out),
                   TASKS=str(tasks), TRIALS="2")
        env.pop("CONFIG", None)
        if config:
            env["CONFIG"] = config
        r = subprocess.run(["bash", "-c", 'source "%s/scripts/paper_lib.sh"; suite_of %s'
                            % (SOURCE, name)], env=env, capture_output=True, text=True,
                           timeout=120)
        return r

    def test_generated_suites_have_the_names_traffic_and_scenarios(self):
        for name, traffic, scenarios in (("town-a-dense", "dense", {"route"}),
                                         ("town-b-stopgo", "regular", {"red_light", "leader"})):
            with self.subTest(suite=name):
                r = self.suite_of(name, 4)
                self.assertEqual(r.returncode, 0, r.stderr)
                path = r.stdout.strip()
                self.assertEqual(path, os.path.join(self.dir, "out", "suites", name + "-4.json"))
                with open(path) as f:
                    suite = json.load(f)
                self.assertEqual((suite["town"], suite["traffic"], suite["trials"]),
                                 (name.rsplit("-", 1)[0], traffic, 2))
                self.assertEqual(len(suite["tasks"]), 4)
                self.assertEqual({t["scenario"] for t in suite["tasks"]}, scenarios)

    def expert_eval(self, config, suite, out):
        """`causaldrive eval` of the expert over SUITE, one trial a task, into OUT."""
        return subprocess.run([BIN, "eval", "--config", config, "--agent", "expert", "--suite",
                               suite, "--trials", "1", "--workers", "1", "--quiet", "--out", out],
                              capture_output=True, text=True, timeout=600)

    def test_a_route_mode_config_draws_tasks_its_ego_can_drive(self):
        # Drawn with a route-mode config, every task of town-c (which has routes that need a lane
        # change) is driven by the route-mode expert, none refused as an infrastructure failure;
        # drawn with the default (free) settings, the same name and seed give other routes.
        config = os.path.join(SOURCE, "configs", "cim_paper.toml")
        r = self.suite_of("town-c-regular", 6, config)
        self.assertEqual(r.returncode, 0, r.stderr)
        route_suite = r.stdout.strip()
        out = os.path.join(self.dir, "eval")
        e = self.expert_eval(config, route_suite, out)
        self.assertEqual(e.returncode, 0, e.stderr)
        with open(os.path.join(out, "results.json")) as f:
            outcomes = [ep["outcome"] for ep in json.load(f)["episodes"]]
        self.assertEqual(len(outcomes), 6)
        self.assertNotIn("infrastructure_failure", outcomes)
        r = self.suite_of("town-c-regular", 6, out="free")
        self.assertEqual(r.returncode, 0, r.stderr)
        free_suite = r.stdout.strip()
        with open(route_suite) as f, open(free_suite) as g:
            self.assertNotEqual([t["route"] for t in json.load(f)["tasks"]],
                                [t["route"] for t in json.load(g)["tasks"]])
        # The free suite's lane changes, driven in route mode, are refused, and the warning
        # names the first refusal's cause.
        e = self.expert_eval(config, free_suite, os.path.join(self.dir, "eval-free"))
        self.assertEqual(e.returncode, 0, e.stderr)
        self.assertRegex(e.stderr, r"warning: [1-6] episode\(s\) failed for reasons outside the "
                                   r"agent \(the first: job [0-9]+: the task's route needs a lane "
                                   r"change")

    def test_the_built_in_suite_at_25_tasks(self):
        r = self.suite_of("town-a-stopgo", 25)
        self.assertEqual((r.returncode, r.stdout.strip()), (0, "town-a-stopgo"), r.stderr)


class SteeringSummaryTest(TempDirCase):
    """scripts/steering_summary.py: the README's condensed steering tables from report csv files
    written here by hand (the cells computed by hand)."""

    HEADER = "label,suite,metric,mean,std,n\n"

    def write(self, relative, rows):
        path = os.path.join(self.dir, "results", relative)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "w") as f:
            f.write(self.HEADER + "".join(",".join(map(str, r)) + "\n" for r in rows))

    def summary(self):
        return subprocess.run(["python3", os.path.join(SOURCE, "scripts", "steering_summary.py"),
                               os.path.join(self.dir, "results")],
                              capture_output=True, text=True, timeout=60)

    def test_cells_are_mean_and_sd_in_percent_free_beside_route(self):
        self.write("cim_paper/table1.csv", [
            ("dim", "town-a-regular-100", "paper_error_rate", 0.0788888888889, 0.0234125638952, 3),
            ("dim", "town-a-regular-100", "success_rate", 0.877777777778, 0.0328858857488, 3)])
        self.write("steering/cim/table1.csv", [
            ("cs", "town-a-regular", "paper_error_rate", 0.64, "", 1),
            ("cs", "town-a-regular", "offroad_rate", 0, "", 1),
            ("cs", "town-a-regular", "success_rate", 0.32, "", 1),
            ("cs", "town-a-stopgo", "start_delay_median_s", "", "", 0),  # no value: skipped
            ("dim", "town-a-regular", "paper_error_rate", 0.16, 0.0565685, 2),
            ("dim", "town-a-regular", "offroad_rate", 0.76, 0, 2),
            ("dim", "town-a-regular", "success_rate", 0.02, 0.0282843, 2)])
        self.write("residual_paper/table7.csv", [
            ("bc-oh", "town-a-regular", "success_rate", 0, 0, 3),
            ("bc-oh", "town-a-regular", "collision_rate", 0.0133333333333, 0.0230940107676, 3),
            ("bc-oh", "town-a-regular", "inertia_rate", 0.613333333333, 0.0611010092661, 3)])
        self.write("residual_paper/table9.csv", [])
        self.write("steering/residual/dense.csv", [
            ("bc-oh", "town-a-regular", "success_rate", 0.146666666667, 0.161658075373, 3),
            ("bc-oh", "town-a-regular", "collision_rate", 0.333333333333, 0.271906, 3),
            ("bc-oh", "town-a-regular", "inertia_rate", 0.32, 0.381576, 3),
            ("bc-oh", "town-a-regular", "offroad_rate", 0, 0, 3)])
        r = self.summary()
        self.assertEqual(r.returncode, 0, r.stderr)
        rows = {tuple(c.strip() for c in line.split("|")[1:3]): line.split("|")[3].strip()
                for line in r.stdout.splitlines() if line.startswith("| ") and "mode" not in line}
        self.assertEqual(rows[("cs", "free")], "64 / 0 (32)")  # one run: no sd
        self.assertEqual(rows[("cs", "route")], "n/a (n/a)")   # not in the route csv
        self.assertEqual(rows[("dim", "route")], "8 ± 2 (88)")
        self.assertEqual(rows[("dim", "free")], "16 ± 6 / 76 ± 0 (2)")  # success: mean alone
        self.assertEqual(rows[("bc-oh", "route")], "0 ± 0 / 1 ± 2 / 61 ± 6")
        self.assertEqual(rows[("bc-oh", "free")], "15 ± 16 / 33 ± 27 / 32 ± 38 / 0 ± 0")
        self.assertIn("seeds per free-mode row: [3]", r.stdout)

    def test_a_missing_csv_is_one_line_and_exit_1(self):
        r = self.summary()
        self.assertEqual(r.returncode, 1)
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
        self.assertRegex(r.stderr, r"^steering_summary\.py: .*cim_paper/table1\.csv")


class ConfigVariantTest(TempDirCase):
    """scripts/config_variant.py: BASE with keys set, read back by tomllib (the oracle)."""

    def variant(self, *overrides):
        base = os.path.join(self.dir, "base.toml")
        with open(base, "w") as f:
            f.write('# a comment\n[world]\ntown = "town-a"\n\n[train]\nepochs = 8\n'
                    'lr = 2e-4\n\n[collect]\nepisodes = 3\n\n[collect.noise]\n'
                    'enabled = true\n')
        out = os.path.join(self.dir, "out.toml")
        r = subprocess.run([os.path.join(SOURCE, "scripts", "config_variant.py"), base, out,
                            *overrides], capture_output=True, text=True, timeout=60)
        return r, out

    def test_overrides_replace_add_and_keep_the_rest(self):
        import tomllib
        r, out = self.variant("train.epochs=24", "train.situation_weights=balanced",
                              "collect.noise.enabled=false", "model.speed_input=true")
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(out, "rb") as f:
            got = tomllib.load(f)
        self.assertEqual(got, {"world": {"town": "town-a"},
                               "train": {"epochs": 24, "lr": 2e-4,
                                         "situation_weights": "balanced"},
                               "collect": {"episodes": 3, "noise": {"enabled": False}},
                               "model": {"speed_input": True}})

    def test_a_malformed_override_is_one_line_and_exit_1(self):
        r, out = self.variant("epochs24")
        self.assertEqual(r.returncode, 1)
        self.assertEqual(r.stderr.strip().splitlines(),
                         ["error: override 'epochs24' is not TABLE.KEY=VALUE"])
        self.assertFalse(os.path.exists(out))


class VerdictsChooseTest(TempDirCase):
    """scripts/verdicts.sh choose: docs/protocol.md section 6's rule over validation results
    (highest mean success over the two suites; ties: lower mean collision, then list order)."""

    VARIANTS = ["old", "signed", "hold-balanced", "signed-hold-balanced"]

    def put(self, variant, method, kind, success, collision):
        d = os.path.join(self.dir, "val", variant, "seed0", method, kind)
        os.makedirs(d)
        with open(os.path.join(d, "results.json"), "w") as f:
            json.dump({"summary": {"success_rate": success, "collision_rate": collision}}, f)

    def choose(self, methods, configs, results):
        """Runs `verdicts.sh choose` for METHODS over self.dir/val; returns tuning.md."""
        r = subprocess.run([os.path.join(SOURCE, "scripts", "verdicts.sh"), "choose"],
                           env=dict(os.environ, CD=os.path.abspath(BIN), METHODS=methods,
                                    VAL=os.path.join(self.dir, "val"), CONFIGS=configs,
                                    RESULTS=results, OUT=os.path.join(self.dir, "out")),
                           capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(results, "tuning.md")) as f:
            return f.read()

    def test_the_rule_and_its_tie_breaks(self):
        import tomllib
        # a: signed-hold-balanced by success. b: signed and hold-balanced tie on success (0.5);
        # hold-balanced collides less. c: all tie at 0: old, the first. d: a variant missing.
        for v, (a, b) in zip(self.VARIANTS, [(0.0, 0.2), (0.1, 0.5), (0.2, 0.5), (0.8, 0.4)]):
            for kind in ("regular", "dense"):
                self.put(v, "a", kind, a, 0.1)
                self.put(v, "b", kind, b, 0.3 if v == "signed" else 0.2)
                self.put(v, "c", kind, 0.0, 0.0)
                if v != "signed":
                    self.put(v, "d", kind, 0.9, 0.0)
        configs, results = os.path.join(self.dir, "configs"), os.path.join(self.dir, "results")
        table = self.choose("a b c d", configs, results)
        keys = {"old": ("two", 0.0, "none"), "signed": ("signed", 0.0, "none"),
                "hold-balanced": ("two", 1.0, "balanced"),
                "signed-hold-balanced": ("signed", 1.0, "balanced")}
        for method, variant in (("a", "signed-hold-balanced"), ("b", "hold-balanced"),
                                ("c", "old")):
            with open(os.path.join(configs, method + ".toml"), "rb") as f:
                text = f.read()
            got = tomllib.loads(text.decode())
            self.assertEqual((got["model"]["pedals"], got["collect"]["hold_s"],
                              got["train"]["situation_weights"]), keys[variant], method)
            self.assertIn(('variant "%s"' % variant).encode(), text)
        self.assertFalse(os.path.exists(os.path.join(configs, "d.toml")))
        self.assertIn("| b | hold-balanced | 50.0 / 20.0 | 50.0 / 20.0 | 50.0 | **yes** |", table)
        self.assertIn("| b | signed | 50.0 / 30.0 | 50.0 / 30.0 | 50.0 |  |", table)
        self.assertIn("val/signed/seed0/d/regular/results.json", table)
        # Choosing for one method later keeps the other methods' rows and writes its config only.
        os.remove(os.path.join(configs, "b.toml"))
        again = self.choose("c", configs, results)
        self.assertIn("| b | hold-balanced | 50.0 / 20.0 | 50.0 / 20.0 | 50.0 | **yes** |", again)
        self.assertIn("| a | signed-hold-balanced |", again)
        self.assertFalse(os.path.exists(os.path.join(configs, "b.toml")))
        self.assertTrue(os.path.exists(os.path.join(configs, "c.toml")))


class VerdictsStandIn(TempDirCase):
    """A stand-in for causaldrive that records its arguments (train and eval write their
    output folder), and chosen configs for residual, bc-oh and keyframe."""

    def setUp(self):
        super().setUp()
        self.log = os.path.join(self.dir, "calls.log")
        self.cd = os.path.join(self.dir, "cd.sh")
        with open(self.cd, "w") as f:
            f.write('#!/bin/bash\necho "$@" >> %s\n' % self.log +
                    'cmd=$1\n'
                    'if [[ $cmd == train || $cmd == eval ]]; then\n'
                    '  while [[ $# -gt 0 ]]; do [[ $1 == --out ]] && out=$2; shift; done\n'
                    '  mkdir -p "$out"; echo "{}" > "$out/checkpoint.json"\n'
                    '  [[ $cmd == eval ]] && echo "{}" > "$out/results.json"\n'
                    'fi\n'
                    'exit 0\n')
        os.chmod(self.cd, 0o755)
        self.configs = os.path.join(self.dir, "configs")
        os.makedirs(self.configs)
        for m in ("residual", "bc-oh", "keyframe"):
            with open(os.path.join(self.configs, m + ".toml"), "w") as f:
                f.write('[collect]\nhold_s = %s\n\n[train]\nepochs = %d\n' % (
                    "0.0" if m == "keyframe" else "1.0", len(m)))

    def calls(self):
        with open(self.log) as f:
            return [line.split() for line in f.read().splitlines()]


class VerdictsAblationsTest(VerdictsStandIn):
    """scripts/verdicts.sh ablations and report: each ablation trains the residual network
    from its base method's chosen config with its keys set, on the base method's data folder
    of the seed; the primary report reads the six conditions of section 3's methods only, the
    secondary one the ablations on town-a dense and the stop-and-go runs."""

    def verdicts(self, *steps):
        env = dict(os.environ, CD=self.cd, OUT=os.path.join(self.dir, "out"),
                   KEEP=os.path.join(self.dir, "keep"), CONFIGS=self.configs,
                   SEEDS_OTHERS="0 1")
        return subprocess.run([os.path.join(SOURCE, "scripts", "verdicts.sh"), *steps],
                              cwd=SOURCE, env=env, capture_output=True, text=True, timeout=120)

    def test_each_ablation_trains_residual_from_its_base_config_and_data(self):
        r = self.verdicts("ablations")
        self.assertEqual(r.returncode, 0, r.stderr)
        out = os.path.join(self.dir, "out")
        trains = {(c[c.index("--out") + 1].split("/")[-2:][1], c[c.index("--seed") + 1]): c
                  for c in self.calls()}
        self.assertEqual(len(trains), 8)
        for (label, seed), c in trains.items():
            self.assertEqual(c[c.index("--method") + 1], "residual")
            data = c[c.index("--data") + 1]
            hold = "0.0" if label == "two-stream-keyframe" else "1.0"
            self.assertEqual(data, os.path.join(out, "data", "hold" + hold,
                                                "D1" if seed == "0" else "D2"))
        import tomllib
        with open(os.path.join(out, "configs", "two-stream-keyframe.toml"), "rb") as f:
            got = tomllib.load(f)
        self.assertEqual(got["train"]["epochs"], len("keyframe"))  # the base config's keys kept
        self.assertEqual(got["residual"], {"policy_input": "history", "memory_target": "action",
                                           "weights": "keyframe"})
        with open(os.path.join(out, "configs", "residual-b4.toml"), "rb") as f:
            got = tomllib.load(f)
        self.assertEqual((got["train"]["epochs"], got["residual"]), (8, {"branches": 4}))
        r = self.verdicts("ablations")  # kept: nothing trained again
        self.assertEqual(len(self.calls()), 8)

    def test_the_primary_report_reads_only_the_six_conditions_of_the_methods(self):
        keep = os.path.join(self.dir, "keep", "eval")
        for d in ("residual/seed0/a-regular", "residual/seed0/a-dense-shifted",
                  "residual/seed0/a-stopgo", "bc-oh/seed0/b-dense",
                  "two-stream-bc-oh/seed0/a-dense"):
            os.makedirs(os.path.join(keep, d))
            with open(os.path.join(keep, d, "results.json"), "w") as f:
                f.write("{}")
        r = self.verdicts("report")
        self.assertEqual(r.returncode, 0, r.stderr)
        reports = [c for c in self.calls() if c[0] == "report"]
        primary = [c for c in reports if "--power" in c][0]
        runs = sorted(os.path.relpath(x, keep) for x in primary if x.startswith(keep))
        self.assertEqual(runs, ["bc-oh/seed0/b-dense", "residual/seed0/a-dense-shifted",
                                "residual/seed0/a-regular"])
        table11 = [c for c in reports if "two-stream-bc-oh" in c and "--compare" in c][0]
        self.assertEqual([os.path.relpath(x, keep) for x in table11 if x.startswith(keep)],
                         ["two-stream-bc-oh/seed0/a-dense"])
        stopgo = [c for c in reports if "stopgo" in c][0]
        self.assertEqual([os.path.relpath(x, keep) for x in stopgo if x.startswith(keep)],
                         ["residual/seed0/a-stopgo"])

    def test_secondary_evaluates_what_has_weights_and_names_what_it_skips(self):
        out, keep = os.path.join(self.dir, "out"), os.path.join(self.dir, "keep")
        os.makedirs(os.path.join(out, "train", "seed0", "bc-oh"))  # trained here, weights
        open(os.path.join(out, "train", "seed0", "bc-oh", "best.pt"), "w").close()  # not kept
        os.makedirs(os.path.join(keep, "train", "seed0", "bc-oh.record"))
        os.makedirs(os.path.join(out, "train", "seed3", "bc-oh"))  # unfinished: no record
        open(os.path.join(out, "train", "seed3", "bc-oh", "best.pt"), "w").close()
        os.makedirs(os.path.join(keep, "train", "seed2", "bc-oh"))  # kept in git
        open(os.path.join(keep, "train", "seed2", "bc-oh", "checkpoint.json"), "w").close()
        os.makedirs(os.path.join(keep, "train", "seed1", "bc-oh.record"))  # weights not kept
        os.makedirs(os.path.join(keep, "eval", "bc-oh", "seed0", "b-stopgo"))  # evaluated
        with open(os.path.join(keep, "eval", "bc-oh", "seed0", "b-stopgo", "results.json"),
                  "w") as f:
            f.write("{}")
        env = dict(os.environ, CD=self.cd, OUT=out, KEEP=keep, CONFIGS=self.configs,
                   METHODS="bc-oh", SEEDS_MAIN="0 1 2 3", SEEDS_OTHERS="0",
                   ABLATION_LABELS="residual-b2")
        r = subprocess.run([os.path.join(SOURCE, "scripts", "verdicts.sh"), "secondary"],
                           cwd=SOURCE, env=env, capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stderr)
        evals = sorted(tuple(c[c.index("--out") + 1].split("/")[-2:]) for c in self.calls()
                       if c[0] == "eval")
        self.assertEqual(evals, [("seed0", "a-stopgo"), ("seed2", "a-stopgo"),
                                 ("seed2", "b-stopgo")])
        for run, folder in (("train/seed1/bc-oh", "eval/bc-oh/seed1/a-stopgo"),
                            ("train/seed1/bc-oh", "eval/bc-oh/seed1/b-stopgo"),
                            ("train/seed3/bc-oh", "eval/bc-oh/seed3/a-stopgo"),
                            ("train/seed0/residual-b2", "eval/residual-b2/seed0/a-dense")):
            self.assertIn("%s/%s: no weights here (not trained yet, or not kept), %s/%s skipped"
                          % (out, run, out, folder), r.stderr)
        self.assertIn("secondary: 5 evaluation(s) skipped for want of weights", r.stderr)

    def assert_refused_in_one_line(self, env, steps, word):
        """Each of STEPS of scripts/verdicts.sh, run alone with ENV, stops non-zero with one
        stderr line holding WORD."""
        for step in steps:
            r = subprocess.run([os.path.join(SOURCE, "scripts", "verdicts.sh"), step],
                               cwd=SOURCE, env=env, capture_output=True, text=True, timeout=120)
            self.assertNotEqual(r.returncode, 0, step)
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
            self.assertIn(word, r.stderr)

    def test_retrains_train_apart_and_are_evaluated_on_the_stop_and_go_suites_only(self):
        # Protocol section 11 (session 39): TRAIN=retrain trains into retrain/seedN/METHOD on
        # the seed's data folder, and secondary evaluates those alone, labelled METHOD-retrain.
        out = os.path.join(self.dir, "out")
        env = dict(os.environ, CD=self.cd, OUT=out, KEEP=os.path.join(self.dir, "keep"),
                   CONFIGS=self.configs, TRAIN="retrain", METHODS="residual",
                   SEEDS_RETRAIN="0 1", SEEDS_OTHERS="0", ABLATION_LABELS="residual-b2")
        script = os.path.join(SOURCE, "scripts", "verdicts.sh")
        r = subprocess.run([script, "train", "secondary"], cwd=SOURCE, env=env,
                           capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stderr)
        trains = [c for c in self.calls() if c[0] == "train"]
        self.assertEqual([(c[c.index("--out") + 1], c[c.index("--data") + 1], c[c.index("--seed") + 1])
                          for c in trains],
                         [(os.path.join(out, "retrain", "seed%d" % s, "residual"),
                           os.path.join(out, "data", "hold1.0", "D%d" % (s + 1)), str(s))
                          for s in (0, 1)])
        evals = [c for c in self.calls() if c[0] == "eval"]
        self.assertEqual(sorted((c[c.index("--out") + 1], c[c.index("--label") + 1],
                                 c[c.index("--checkpoint") + 1]) for c in evals),
                         [(os.path.join(out, "eval", "residual-retrain", "seed%d" % s, suite),
                           "residual-retrain", os.path.join(out, "retrain", "seed%d" % s, "residual"))
                          for s in (0, 1) for suite in ("a-stopgo", "b-stopgo")])
        self.assert_refused_in_one_line(env, ("eval", "ablations", "probe", "gpu-list"), "TRAIN=retrain")
        for train, step, code, msg in (("bogus", "report", 2, "unknown TRAIN 'bogus'"),
                                       ("cuda", "train", 1, "TRAIN=cuda runs train on a lent GPU")):
            r = subprocess.run([script, step], cwd=SOURCE, env=dict(env, TRAIN=train),
                               capture_output=True, text=True, timeout=120)
            self.assertEqual(r.returncode, code, r.stderr)
            self.assertIn(msg, r.stderr)
        self.assertEqual(len([c for c in self.calls() if c[0] in ("train", "eval")]), 6)

    def test_a_method_trained_again_on_the_cpu_is_evaluated_in_the_six_conditions_apart(self):
        # Protocol section 11 (session 40): TRAIN=cpu trains keyframe into cpu/seedN/keyframe on
        # its section-7 seeds' data folders, eval evaluates those labelled keyframe-cpu in the
        # six conditions, report compares them with residual and with keyframe's own runs.
        out, keep = os.path.join(self.dir, "out"), os.path.join(self.dir, "keep")
        env = dict(os.environ, CD=self.cd, OUT=out, KEEP=keep, CONFIGS=self.configs,
                   TRAIN="cpu", METHODS="keyframe", SEEDS_MAIN="0 1", SEEDS_OTHERS="0",
                   ABLATION_LABELS="two-stream-keyframe")
        script = os.path.join(SOURCE, "scripts", "verdicts.sh")
        r = subprocess.run([script, "train", "eval"], cwd=SOURCE, env=env, capture_output=True,
                           text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stderr)
        trains = [c for c in self.calls() if c[0] == "train"]
        self.assertEqual([(c[c.index("--out") + 1], c[c.index("--method") + 1],
                           c[c.index("--data") + 1], c[c.index("--seed") + 1]) for c in trains],
                         [(os.path.join(out, "cpu", "seed%d" % s, "keyframe"), "keyframe",
                           os.path.join(out, "data", "hold0.0", "D%d" % (s + 1)), str(s))
                          for s in (0, 1)])
        evals = [c for c in self.calls() if c[0] == "eval"]
        self.assertEqual(sorted(c[c.index("--out") + 1] for c in evals),
                         sorted(os.path.join(out, "eval", "keyframe-cpu", "seed%d" % s, name)
                                for s in (0, 1) for name in ("a-regular", "a-dense",
                                                             "a-regular-shifted", "a-dense-shifted",
                                                             "b-regular", "b-dense")))
        for c in evals:
            self.assertEqual(c[c.index("--label") + 1], "keyframe-cpu")
            self.assertIn(c[c.index("--checkpoint") + 1],
                          [os.path.join(out, "cpu", "seed%d" % s, "keyframe") for s in (0, 1)])
        for d in ("residual/seed0/a-regular", "keyframe/seed0/a-regular"):
            os.makedirs(os.path.join(keep, "eval", d))
            with open(os.path.join(keep, "eval", d, "results.json"), "w") as f:
                f.write("{}")
        r = subprocess.run([script, "report"], cwd=SOURCE, env=env, capture_output=True,
                           text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stderr)
        compared = sorted(tuple(c[c.index("--compare") + 1:c.index("--compare") + 3])
                          for c in self.calls() if c[0] == "report" and "--compare" in c and
                          "keyframe-cpu" in c)
        self.assertEqual(compared, [("keyframe", "keyframe-cpu"), ("residual", "keyframe-cpu")])
        self.assert_refused_in_one_line(env, ("secondary", "ablations", "probe", "gpu-list"), "TRAIN=cpu")

    def test_the_device_check_evaluates_the_cuda_runs_under_their_own_label(self):
        out = os.path.join(self.dir, "out")
        os.makedirs(os.path.join(out, "cuda", "seed0", "residual"))
        open(os.path.join(out, "cuda", "seed0", "residual", "best.pt"), "w").close()
        # imported by scripts/gpu_import.py: its record kept, the weights (over 5 MB) here
        os.makedirs(os.path.join(self.dir, "keep", "cuda", "seed0", "residual.record"))
        env = dict(os.environ, CD=self.cd, OUT=out, KEEP=os.path.join(self.dir, "keep"),
                   CONFIGS=self.configs, TRAIN="cuda", METHODS="residual", SEEDS_MAIN="0 1")
        r = subprocess.run([os.path.join(SOURCE, "scripts", "verdicts.sh"), "eval"], cwd=SOURCE,
                           env=env, capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn(os.path.join(out, "cuda", "seed1", "residual") + ": no weights here (not trained yet, or not on this machine), skipped",
                      r.stderr)
        evals = [c for c in self.calls() if c[0] == "eval"]
        self.assertEqual(sorted(c[c.index("--out") + 1].split("/")[-1] for c in evals),
                         sorted(["a-regular", "a-dense", "a-regular-shifted", "a-dense-shifted",
                                 "b-regular", "b-dense"]))
        for c in evals:
            self.assertEqual(c[c.index("--label") + 1], "residual-cuda")
            self.assertEqual(c[c.index("--checkpoint") + 1],
                             os.path.join(out, "cuda", "seed0", "residual"))
            self.assertIn("/eval/residual-cuda/seed0/", c[c.index("--out") + 1])
        # The report compares residual-cuda with the CUDA-trained methods and residual.
        keep = os.path.join(self.dir, "keep", "eval")
        for d in ("residual/seed0/a-regular", "bc-oh/seed0/a-regular"):
            os.makedirs(os.path.join(keep, d))
            with open(os.path.join(keep, d, "results.json"), "w") as f:
                f.write("{}")
        r = self.verdicts("report")
        self.assertEqual(r.returncode, 0, r.stderr)
        compared = sorted(c[c.index("--compare") + 2] for c in self.calls()
                          if c[0] == "report" and "--compare" in c and
                          c[c.index("--compare") + 1] == "residual-cuda")
        self.assertEqual(compared, ["bc-oh", "keyframe", "residual"])

    def test_gpu_list_names_every_run_not_kept_with_the_device_checks(self):
        out, keep = os.path.join(self.dir, "out"), os.path.join(self.dir, "keep")
        for d in ("D1", "D2"):
            os.makedirs(os.path.join(out, "data", "hold1.0", d))
            with open(os.path.join(out, "data", "hold1.0", d, "collect.json"), "w") as f:
                f.write("{}")
        os.makedirs(os.path.join(keep, "train", "seed0", "residual"))  # kept: not listed
        os.makedirs(os.path.join(keep, "cuda", "seed1", "residual.record"))  # kept as a record
        gpu = os.path.join(self.dir, "gpu")
        env = dict(os.environ, CD=self.cd, OUT=out, KEEP=keep, CONFIGS=self.configs,
                   METHODS="residual bc-oh", SEEDS_MAIN="0 1", SEEDS_OTHERS="1",
                   ABLATION_LABELS="two-stream-bc-oh", GPU_DIR=gpu)
        r = subprocess.run([os.path.join(SOURCE, "scripts", "verdicts.sh"), "gpu-list"],
                           cwd=SOURCE, env=env, capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(gpu, "runs.txt")) as f:
            lines = [line.split() for line in f if not line.startswith("#")]
        self.assertEqual([(n, m, seed) for n, m, _, _, seed in lines],
                         [("train/seed0/bc-oh", "bc-oh", "0"), ("cuda/seed0/residual", "residual", "0"),
                          ("train/seed1/bc-oh", "bc-oh", "1"),
                          ("train/seed1/two-stream-bc-oh", "residual", "1")])
        self.assertEqual({d for *_, d, _ in lines}, {os.path.join(gpu, "hold1.0-D1.tar.xz"),
                                                     os.path.join(gpu, "hold1.0-D2.tar.xz")})
        import tomllib
        with open(os.path.join(gpu, "residual.toml"), "rb") as f:
            got = tomllib.load(f)
        self.assertEqual((got["train"]["epochs"], got["train"]["cuda_deterministic"]), (8, True))

    def test_the_added_seeds_go_to_residual_on_both_devices_and_bc_oh_only(self):
        # Protocol section 7 and its session-31 amendment: SEEDS_ADDED trains residual (CPU
        # and CUDA) and bc-oh at seeds 10-14, never keyframe.
        out = os.path.join(self.dir, "out")
        for hold in ("hold1.0", "hold0.0"):
            for d in ("D1", "D2"):
                os.makedirs(os.path.join(out, "data", hold, d))
                with open(os.path.join(out, "data", hold, d, "collect.json"), "w") as f:
                    f.write("{}")
        gpu = os.path.join(self.dir, "gpu")
        env = dict(os.environ, CD=self.cd, OUT=out, KEEP=os.path.join(self.dir, "keep"),
                   CONFIGS=self.configs, METHODS="residual bc-oh keyframe", SEEDS_MAIN="0",
                   SEEDS_ADDED="10 11", SEEDS_OTHERS="0", ABLATION_LABELS="residual-b2",
                   GPU_DIR=gpu)
        r = subprocess.run([os.path.join(SOURCE, "scripts", "verdicts.sh"), "gpu-list"],
                           cwd=SOURCE, env=env, capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(gpu, "runs.txt")) as f:
            lines = [line.split() for line in f if not line.startswith("#")]
        # residual's section-7 runs (train/) are the CPU's: never listed for the GPU.
        self.assertEqual([n for n, *_ in lines],
                         ["train/seed0/bc-oh", "train/seed0/keyframe",
                          "cuda/seed0/residual", "train/seed0/residual-b2",
                          "train/seed10/bc-oh", "cuda/seed10/residual",
                          "train/seed11/bc-oh", "cuda/seed11/residual"])
        # Seed 11 trains on D2, seed 10 on D1 (even and odd, section 4).
        self.assertEqual({(n, os.path.basename(d)) for n, _, _, d, _ in lines
                          if "/seed1" in n},
                         {("train/seed10/bc-oh", "hold1.0-D1.tar.xz"),
                          ("cuda/seed10/residual", "hold1.0-D1.tar.xz"),
                          ("train/seed11/bc-oh", "hold1.0-D2.tar.xz"),
                          ("cuda/seed11/residual", "hold1.0-D2.tar.xz")})

    def test_an_unknown_ablation_is_one_line(self):
        env_label = dict(ABLATION_LABELS="two-stream-bc-oh nonsense")
        env = dict(os.environ, CD=self.cd, OUT=os.path.join(self.dir, "out"),
                   KEEP=os.path.join(self.dir, "keep"), CONFIGS=self.configs,
                   SEEDS_OTHERS="0", **env_label)
        r = subprocess.run([os.path.join(SOURCE, "scripts", "verdicts.sh"), "ablations"],
                           cwd=SOURCE, env=env, capture_output=True, text=True, timeout=120)
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("error: unknown ablation 'nonsense'", r.stderr)


class VerdictsCameraTest(VerdictsStandIn):
    """scripts/verdicts.sh with VIEW=camera (docs/camera.md's plan), the stand-in causaldrive
    recording its arguments: tuning trains and validates configs with the camera, the chosen
    configs keep it, table 8's conditions evaluate with the held-out weathers, and gpu-list
    and an unknown view are refused in one line."""

    def camera(self, *steps, **env):
        env = dict(dict(os.environ, CD=self.cd, VIEW="camera", OUT=os.path.join(self.dir, "out"),
                        KEEP=os.path.join(self.dir, "keep"), CONFIGS=self.configs), **env)
        return subprocess.run([os.path.join(SOURCE, "scripts", "verdicts.sh"), *steps],
                              cwd=SOURCE, env=env, capture_output=True, text=True, timeout=120)

    def test_tuning_trains_and_validates_with_the_camera_and_choose_keeps_it(self):
        import tomllib
        val = os.path.join(self.dir, "val", "eval")
        r = self.camera("tune", METHODS="bc-oh", VAL=val)
        self.assertEqual(r.returncode, 0, r.stderr)
        trains = [c for c in self.calls() if c[0] == "train"]
        evals = [c for c in self.calls() if c[0] == "eval"]
        self.assertEqual((len(trains), len(evals)), (4, 8))  # four variants, two suites each
        for c in trains + evals:
            with open(c[c.index("--config") + 1], "rb") as f:
                self.assertEqual(tomllib.load(f)["sense"]["view"], "camera")
            self.assertTrue(c[c.index("--out") + 1].startswith(
                os.path.join(self.dir, "out", "recipe") + "/"))
        # Its evaluations are kept under VAL, where choose reads them.
        for v in ("old", "signed", "hold-balanced", "signed-hold-balanced"):
            for kind in ("regular", "dense"):
                with open(os.path.join(val, v, "seed0", "bc-oh", kind, "results.json"), "w") as f:
                    json.dump({"summary": {"success_rate": 0.5 if v == "signed" else 0.1,
                                           "collision_rate": 0.0}}, f)
        configs, results = os.path.join(self.dir, "chosen"), os.path.join(self.dir, "results")
        r = self.camera("choose", METHODS="bc-oh", VAL=val, CONFIGS=configs, RESULTS=results)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(configs, "bc-oh.toml"), "rb") as f:
            text = f.read()
        got = tomllib.loads(text.decode())
        self.assertEqual((got["sense"]["view"], got["model"]["pedals"], got["collect"]["hold_s"]),
                         ("camera", "signed", 0.0))
        self.assertIn(b"for the camera runs", text)
        self.assertIn(b"sense.view=camera", text)

    def test_table_8_evaluates_with_the_held_out_weathers(self):
        import tomllib
        with open(os.path.join(self.configs, "bc-oh.toml"), "a") as f:
            f.write('\n[sense]\nview = "camera"\n')
        out = os.path.join(self.dir, "out")
        os.makedirs(os.path.join(out, "train", "seed0", "bc-oh"))
        r = self.camera("eval", METHODS="bc-oh", SEEDS_MAIN="0")
        self.assertEqual(r.returncode, 0, r.stderr)
        evals = {c[c.index("--out") + 1].split("/")[-1]: c
                 for c in self.calls() if c[0] == "eval"}
        self.assertEqual(sorted(evals), sorted(["a-regular", "a-dense", "a-regular-held-out",
                                                "a-dense-held-out", "b-regular", "b-dense"]))
        for name, c in evals.items():
            self.assertEqual(c[c.index("--sensor") + 1], "clean")
            with open(c[c.index("--config") + 1], "rb") as f:
                got = tomllib.load(f)
            self.assertEqual(got["sense"]["view"], "camera")
            self.assertEqual(got["sense"].get("camera", {}).get("weather"),
                             "held-out" if name.endswith("held-out") else None, name)
            self.assertEqual(got["train"]["epochs"], len("bc-oh"))  # the chosen config's keys

    def test_gpu_list_and_an_unknown_view_are_refused_in_one_line(self):
        r = self.camera("gpu-list")
        self.assertNotEqual(r.returncode, 0)
        self.assertIn("error: gpu-list lists the BEV's runs only", r.stderr)
        r = self.camera("report", VIEW="lidar")
        self.assertEqual(r.returncode, 2)
        self.assertEqual(r.stderr.strip(), "error: unknown VIEW 'lidar' (bev or camera)")


class VerdictsFreeModeTest(VerdictsStandIn):
    """scripts/verdicts.sh with MODE=free (protocol section 2's free-mode endpoint), the
    stand-in causaldrive recording its arguments: each method's chosen config of route mode
    with the free keys, its own data folders, seeds 0-4 on the six conditions; no tuning and
    no device check of its own; the report compares residual with the methods evaluated."""

    def free(self, *steps, **env):
        env = dict(dict(os.environ, CD=self.cd, MODE="free", OUT=os.path.join(self.dir, "out"),
                        KEEP=os.path.join(self.dir, "keep"), CONFIGS=self.configs,
                        METHODS="residual bc-oh keyframe"), **env)
        return subprocess.run([os.path.join(SOURCE, "scripts", "verdicts.sh"), *steps],
                              cwd=SOURCE, env=env, capture_output=True, text=True, timeout=120)

    def test_runs_use_the_chosen_configs_with_the_free_keys_at_five_seeds(self):
        import tomllib
        r = self.free("data", "train", "eval")
        self.assertEqual(r.returncode, 0, r.stderr)
        out = os.path.join(self.dir, "out")
        calls = self.calls()
        collects = [c for c in calls if c[0] == "collect"]
        trains = [c for c in calls if c[0] == "train"]
        evals = [c for c in calls if c[0] == "eval"]
        self.assertEqual({(c[c.index("--seed") + 1], c[c.index("--out") + 1]) for c in collects},
                         {("100", os.path.join(out, "data", h, "D1")) for h in ("hold1.0", "hold0.0")} |
                         {("200", os.path.join(out, "data", h, "D2")) for h in ("hold1.0", "hold0.0")})
        self.assertEqual(sorted((c[c.index("--method") + 1], c[c.index("--seed") + 1]) for c in trains),
                         sorted((m, str(s)) for m in ("residual", "bc-oh", "keyframe")
                                for s in range(5)))
        self.assertEqual(len(evals), 3 * 5 * 6)
        self.assertEqual({c[c.index("--out") + 1].split("/")[-1] for c in evals},
                         {"a-regular", "a-dense", "a-regular-shifted", "a-dense-shifted",
                          "b-regular", "b-dense"})
        for c in collects + trains + evals:
            config = c[c.index("--config") + 1]
            self.assertEqual(os.path.dirname(config), os.path.join(out, "configs"))
            with open(config, "rb") as f:
                got = tomllib.load(f)
            self.assertEqual((got["ego"]["lateral"], got["collect"]["augment"]["fraction"]),
                             ("free", 0.3))
            method = os.path.basename(config)[:-len(".toml")]
            self.assertEqual(got["train"]["epochs"], len(method))  # the chosen config's keys
        for c in trains:  # each seed on its folder: D1 for even seeds, D2 for odd (section 4)
            seed, method = int(c[c.index("--seed") + 1]), c[c.index("--method") + 1]
            self.assertEqual(c[c.index("--data") + 1], os.path.join(
                out, "data", "hold0.0" if method == "keyframe" else "hold1.0",
                "D1" if seed % 2 == 0 else "D2"))

    def test_no_tuning_no_device_check_and_the_report_of_what_is_evaluated(self):
        import tomllib
        r = self.free("tune", "data")
        self.assertNotEqual(r.returncode, 0)
        self.assertEqual(r.stderr.strip(), "error: MODE=free takes route mode's chosen configs "
                         "(%s): run tune without MODE" % self.configs)
        self.assertFalse(os.path.exists(self.log))  # nothing ran
        out, gpu = os.path.join(self.dir, "out"), os.path.join(self.dir, "gpu")
        for d in ("D1", "D2"):
            os.makedirs(os.path.join(out, "data", "hold1.0", d))
            with open(os.path.join(out, "data", "hold1.0", d, "collect.json"), "w") as f:
                f.write("{}")
        r = self.free("gpu-list", METHODS="residual bc-oh", SEEDS_MAIN="0", GPU_DIR=gpu,
                      AUGMENT="0.5")
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(gpu, "runs.txt")) as f:
            lines = [line.split() for line in f if not line.startswith("#")]
        self.assertEqual([n for n, *_ in lines], ["train/seed0/bc-oh"])  # no cuda/, no ablation
        with open(os.path.join(gpu, "bc-oh.toml"), "rb") as f:
            got = tomllib.load(f)
        self.assertEqual((got["ego"]["lateral"], got["collect"]["augment"]["fraction"],
                          got["train"]["cuda_deterministic"]), ("free", 0.5, True))
        keep = os.path.join(self.dir, "keep")
        for d in ("residual/seed0/a-regular", "bc-oh/seed0/a-regular"):
            os.makedirs(os.path.join(keep, "eval", d))
            with open(os.path.join(keep, "eval", d, "results.json"), "w") as f:
                f.write("{}")
        r = self.free("report")
        self.assertEqual(r.returncode, 0, r.stderr)
        compared = [c[c.index("--compare") + 2] for c in self.calls()
                    if c[0] == "report" and "--compare" in c]
        self.assertEqual(compared, ["bc-oh"])  # keyframe, dagger, ...: not evaluated
        with open(os.path.join(keep, "primary.md")) as f:
            self.assertEqual(f.readline().strip(), "# The free-mode verdicts' primary endpoint "
                             "(docs/protocol.md section 2), from the kept evaluations")
        r = self.free("report", MODE="sideways")
        self.assertEqual((r.returncode, r.stderr.strip()),
                         (2, "error: unknown MODE 'sideways' (route or free)"))


class GpuImportTest(TempDirCase):
    """scripts/gpu_import.py: a lent machine's packs land where kept_train would have left the
    runs (weights up to the limit kept, larger ones as a record with the weights in OUT), an
    unfinished folder of the same run is replaced, a kept run is left alone, and a bad pack or
    an incomplete run stops the import in one line before anything is written."""

    def pack(self, runs, name="runs_0.tar"):
        import tarfile
        src = os.path.join(self.dir, "src")
        path = os.path.join(self.dir, name)
        with tarfile.open(path, "w") as tar:
            for run, files in runs.items():
                for f, body in files.items():
                    p = os.path.join(src, run, f)
                    os.makedirs(os.path.dirname(p), exist_ok=True)
                    with open(p, "wb") as out:
                        out.write(body)
                    tar.add(p, arcname=os.path.join(run, f))
        return path

    def run_import(self, *packs):
        return subprocess.run([os.path.join(SOURCE, "scripts", "gpu_import.py"), "--out",
                               os.path.join(self.dir, "out"), "--keep",
                               os.path.join(self.dir, "keep"), "--max-mb", "1", *packs],
                              capture_output=True, text=True, timeout=60)

    def run_files(self, weights):
        ck = json.dumps({"runtime": {"device": "cuda"}, "epochs_done": 8}).encode()
        return {"best.pt": weights, "checkpoint.json": ck, "metrics.jsonl": b"{}\n"}

    def test_runs_land_as_kept_train_would_leave_them(self):
        out, keep = os.path.join(self.dir, "out"), os.path.join(self.dir, "keep")
        os.makedirs(os.path.join(out, "train/seed5/bc-oh"))  # unfinished here: replaced
        with open(os.path.join(out, "train/seed5/bc-oh/model.pt"), "w") as f:
            f.write("partial")
        pack = self.pack({"train/seed5/bc-oh": self.run_files(b"s" * 1000),
                          "train/seed5/residual": self.run_files(b"L" * 1_500_000)})
        r = self.run_import(pack)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(sorted(os.listdir(os.path.join(out, "train/seed5/bc-oh"))),
                         ["best.pt", "checkpoint.json", "metrics.jsonl"])
        self.assertEqual(sorted(os.listdir(os.path.join(keep, "train/seed5/bc-oh"))),
                         ["best.pt", "checkpoint.json", "metrics.jsonl"])
        self.assertEqual(sorted(os.listdir(os.path.join(keep, "train/seed5/residual.record"))),
                         ["checkpoint.json", "metrics.jsonl"])
        self.assertFalse(os.path.exists(os.path.join(keep, "train/seed5/residual")))
        with open(os.path.join(out, "train/seed5/residual/best.pt"), "rb") as f:
            self.assertEqual(f.read(), b"L" * 1_500_000)
        self.assertIn("trained on cuda", r.stdout)
        self.assertIn("scripts/keep_weights.sh " + os.path.join(keep, "train/seed5/bc-oh"),
                      r.stdout)
        # Kept: left alone on a second import.
        pack2 = self.pack({"train/seed5/bc-oh": self.run_files(b"t" * 1000)}, "runs_1.tar")
        r = self.run_import(pack2)
        self.assertIn("train/seed5/bc-oh: kept already", r.stdout)
        with open(os.path.join(keep, "train/seed5/bc-oh/best.pt"), "rb") as f:
            self.assertEqual(f.read(), b"s" * 1000)

    def test_a_bad_pack_or_an_incomplete_run_writes_nothing(self):
        good = self.pack({"train/seed1/bc-oh": self.run_files(b"s")})
        files = self.run_files(b"s")
        del files["metrics.jsonl"]
        bad_run = self.pack({"train/seed2/bc-oh": files}, "runs_1.tar")
        not_tar = os.path.join(self.dir, "x.tar")
        with open(not_tar, "w") as f:
            f.write("hello")
        import tarfile
        linked = os.path.join(self.dir, "runs_2.tar")  # a link out of the pack
        with tarfile.open(linked, "w") as tar:
            info = tarfile.TarInfo("train/seed3/bc-oh/best.pt")
            info.type, info.linkname = tarfile.SYMTYPE, "/etc/passwd"
            tar.addfile(info)
        escaping = os.path.join(self.dir, "runs_3.tar")  # a path out of the pack
        with tarfile.open(escaping, "w") as tar:
            info = tarfile.TarInfo("../../outside.pt")
            info.size = 1
            tar.addfile(info, io.BytesIO(b"x"))
        for packs, msg in (([good, bad_run], "train/seed2/bc-oh lacks metrics.jsonl"),
                           ([good, linked], "best.pt is not a plain file inside the pack"),
                           ([good, escaping], "outside.pt is not a plain file inside the pack"),
                           ([good, not_tar], "not a pack of scripts/gpu_runs.py"),
                           ([os.path.join(self.dir, "missing.tar")], "No such file")):
            r = self.run_import(*packs)
            self.assertEqual(r.returncode, 1)
            self.assertIn(msg, r.stderr)
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
            self.assertFalse(os.path.exists(os.path.join(self.dir, "out")))
            self.assertFalse(os.path.exists(os.path.join(self.dir, "keep")))


class GpuRunsTest(TempDirCase):
    """scripts/gpu_runs.py rehearsed on this CPU with this build: a run starts only while more
    than MIN_RUN_S seconds are left before DEADLINE_S, so a lease too short for a run spends
    nothing on it; the runs are named as not started."""

    def test_no_run_starts_that_cannot_end_by_the_deadline(self):
        runs = os.path.join(self.dir, "runs.txt")
        with open(runs, "w") as f:
            f.write("# two runs\ncuda/seed8/residual residual c.toml D1.tar.xz 8\n"
                    "cuda/seed9/residual residual c.toml D2.tar.xz 9\n")
        debs = os.path.join(self.dir, "debs")
        os.makedirs(debs)
        pack = os.path.join(self.dir, "pack")
        env = dict(os.environ, PACK=pack, OUT=os.path.join(self.dir, "logs"), CD=os.path.abspath(BIN),
                   DEVICE="cpu", CD_DEBS=debs, DEADLINE_S="20", MIN_RUN_S="60")
        r = subprocess.run([sys.executable, os.path.join(SOURCE, "scripts", "gpu_runs.py"), runs],
                           env=env, capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(pack, "gpu_runs.json")) as f:
            got = json.load(f)
        self.assertEqual(got["runs"], {"cuda/seed8/residual": {"exit": "not started (deadline)"},
                                       "cuda/seed9/residual": {"exit": "not started (deadline)"}})
        self.assertEqual([p for p in os.listdir(pack) if p.endswith(".tar")], [])


class GpuTravelTest(TempDirCase):
    """scripts/gpu_travel.sh in a small repository of its own: `size` counts the files a call
    to a lent machine carries (tracked, untracked but not ignored, and the carried paths; not
    the ignored ones) against 64 MiB; `aside` and `back` move results/ out and in, refusing
    while a job runs in the checkout."""

    def setUp(self):
        super().setUp()
        self.repo = os.path.join(self.dir, "repo")
        os.makedirs(os.path.join(self.repo, "scripts"))
        os.makedirs(os.path.join(self.repo, "results", "a"))
        os.makedirs(os.path.join(self.repo, "data"))
        with open(os.path.join(SOURCE, "scripts", "gpu_travel.sh"), "rb") as f:
            script = f.read()
        path = os.path.join(self.repo, "scripts", "gpu_travel.sh")
        with open(path, "wb") as f:
            f.write(script)
        os.chmod(path, 0o755)
        files = {"results/a/r.json": 3_000_000, ".gitignore": 0, "data/big.bin": 5_000_000,
                 "notes.txt": 700_000}
        for name, n in files.items():
            with open(os.path.join(self.repo, name), "wb") as f:
                f.write(b"x" * n if name != ".gitignore" else b"/data/\n")
        git = ["git", "-C", self.repo, "-c", "user.name=t", "-c", "user.email=t@t"]
        subprocess.run(git[:3] + ["init", "-q"], check=True)
        subprocess.run(git + ["add", "scripts", "results", ".gitignore"], check=True)
        subprocess.run(git + ["commit", "-q", "-m", "t"], check=True)

    def travel(self, *args):
        return subprocess.run([os.path.join(self.repo, "scripts", "gpu_travel.sh"), *args],
                              cwd=self.repo, capture_output=True, text=True, timeout=60)

    def test_split_makes_parts_that_gpu_runs_joins(self):
        data = os.path.join(self.dir, "coll")
        os.makedirs(data)
        sizes = {"collect.json": 100, "causaldrive.lock": 10, "episode_000000.h5": 600_000,
                 "episode_000001.h5": 600_000, "episode_000002.h5": 300_000,
                 "episode_000003.h5": 600_000}
        for name, n in sizes.items():
            with open(os.path.join(data, name), "wb") as f:
                f.write(name.encode()[:1] * n)
        dest = os.path.join(self.dir, "parts")
        r = self.travel("split", data, dest, "1")
        self.assertEqual(r.returncode, 0, r.stderr)
        parts = sorted(os.listdir(dest))
        self.assertEqual(parts, ["part1", "part2", "part3"])  # 0.6 | 0.6 + 0.3 | 0.6 MB
        seen = []
        for p in parts:
            files = os.listdir(os.path.join(dest, p))
            self.assertLessEqual(sum(os.path.getsize(os.path.join(dest, p, f)) for f in files),
                                 1_000_000)
            seen += files
        self.assertIn("collect.json", os.listdir(os.path.join(dest, "part1")))
        self.assertEqual(sorted(seen), sorted(k for k in sizes if k != "causaldrive.lock"))
        # gpu_runs joins the parts into one collect folder beside them.
        spec = importlib.util.spec_from_file_location(
            "gpu_runs_t", os.path.join(SOURCE, "scripts", "gpu_runs.py"))
        gpu_runs = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(gpu_runs)
        joined = gpu_runs.unpack_data(dest)
        self.assertEqual(joined, dest + ".joined")
        for name, n in sizes.items():
            if name != "causaldrive.lock":
                self.assertEqual(os.path.getsize(os.path.join(joined, name)), n)
        # A file larger than a part, or a folder that is not a collect folder: one line, no DEST.
        r = self.travel("split", data, os.path.join(self.dir, "p2"), "0")
        self.assertIn("MB: expected a whole number", r.stderr)
        os.remove(os.path.join(data, "collect.json"))
        r = self.travel("split", data, os.path.join(self.dir, "p3"))
        self.assertEqual((r.returncode, r.stderr.count("\n")), (1, 1), r.stderr)
        self.assertIn("not a collect folder", r.stderr)
        self.assertFalse(os.path.exists(os.path.join(self.dir, "p3")))

    def test_size_counts_tracked_untracked_and_carried_not_ignored(self):
        tree = sum(os.path.getsize(os.path.join(self.repo, f)) for f in
                   ("scripts/gpu_travel.sh", "results/a/r.json", ".gitignore", "notes.txt"))
        r = self.travel("size")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertIn("tree %.1f MB + carried 0.0 MB" % (tree / 1e6), r.stdout)
        r = self.travel("size", "data")
        self.assertIn("carried 5.0 MB = %.1f MB" % ((tree + 5_000_000) / 1e6), r.stdout)
        self.assertIn("fits", r.stdout)
        with open(os.path.join(self.repo, "data", "huge.bin"), "wb") as f:
            f.truncate(65 * 1024 * 1024)
        r = self.travel("size", "data")
        self.assertEqual(r.returncode, 1)
        self.assertIn("too large", r.stdout)
        r = self.travel("size", "missing")
        self.assertEqual(r.returncode, 1)
        self.assertIn("missing: no such path to carry", r.stderr)

    def test_aside_and_back_and_their_refusals(self):
        aside = os.path.join(self.dir, ".causaldrive-results-aside")
        r = self.travel("back")
        self.assertEqual(r.returncode, 1)
        self.assertIn("nothing aside", r.stderr)
        # A job of the checkout (a script running there) holds results/.
        with open(os.path.join(self.repo, "scripts", "job.sh"), "w") as f:
            f.write("sleep 30\n")
        job = subprocess.Popen(["bash", "scripts/job.sh"], cwd=self.repo)
        try:
            r = self.travel("aside")
            self.assertEqual(r.returncode, 1)
            self.assertIn("runs in this checkout", r.stderr)
            self.assertTrue(os.path.isdir(os.path.join(self.repo, "results")))
        finally:
            job.kill()
            job.wait()
        r = self.travel("aside")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertFalse(os.path.exists(os.path.join(self.repo, "results")))
        self.assertTrue(os.path.isfile(os.path.join(aside, "a", "r.json")))
        tree = sum(os.path.getsize(os.path.join(self.repo, f)) for f in
                   ("scripts/gpu_travel.sh", "scripts/job.sh", ".gitignore", "notes.txt"))
        self.assertIn("tree %.1f MB +" % (tree / 1e6), self.travel("size").stdout)
        r = self.travel("aside")
        self.assertEqual(r.returncode, 1)
        self.assertIn("results/ is not here", r.stderr)
        os.makedirs(os.path.join(self.repo, "results"))
        r = self.travel("back")
        self.assertEqual(r.returncode, 1)
        self.assertIn("results/ exists again", r.stderr)
        os.rmdir(os.path.join(self.repo, "results"))
        r = self.travel("back")
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(self.repo, "results", "a", "r.json"), "rb") as f:
            self.assertEqual(f.read(), b"x" * 3_000_000)


if __name__ == "__main__":
    unittest.main()
