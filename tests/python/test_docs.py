"""The documentation: the README fits in 250 lines; every relative link of the README, the
docs/ pages and ARCHITECTURE.md resolves (the file, and a #anchor to one of its headings, by
GitHub's rule); docs/configuration.md is what `causaldrive config --reference` prints now;
docs/verdicts.md is what the kept results give, its tables 7-9 rows from whole seeds only."""
import contextlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
import unittest

from support import BIN

ROOT = os.path.abspath(os.environ.get("CAUSALDRIVE_SOURCE_DIR",
                                      os.path.join(os.path.dirname(__file__), "..", "..")))


def pages():
    out = [os.path.join(ROOT, "README.md"), os.path.join(ROOT, "ARCHITECTURE.md")]
    docs = os.path.join(ROOT, "docs")
    out += sorted(os.path.join(docs, f) for f in os.listdir(docs) if f.endswith(".md"))
    return out


def without_code(text):
    """The text outside fenced blocks and `inline code`."""
    text = re.sub(r"```.*?```", "", text, flags=re.S)
    return re.sub(r"`[^`\n]*`", "", text)


def slug(heading):
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    s = heading.strip().lower()
    s = re.sub(r"[^\w\- ]", "", s)
    return s.replace(" ", "-")


def anchors(path):
    with open(path, encoding="utf-8") as f:
        text = re.sub(r"```.*?```", "", f.read(), flags=re.S)
    return {slug(m.group(1)) for m in re.finditer(r"^#+ (.*)$", text, re.M)}


@contextlib.contextmanager
def scratch_checkout(prefix):
    """A folder of its own standing in for a checkout (results/ written by the test), removed
    afterwards."""
    tmp = tempfile.mkdtemp(prefix=prefix)
    try:
        yield tmp
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def load_verdicts_doc(root):
    """scripts/verdicts_doc.py as a module reading the checkout ROOT (and this build's binary)."""
    import importlib.util
    spec = importlib.util.spec_from_file_location(
        "verdicts_doc_%d" % id(root), os.path.join(ROOT, "scripts", "verdicts_doc.py"))
    doc = importlib.util.module_from_spec(spec)
    saved = {k: os.environ.get(k) for k in ("ROOT", "CD")}
    os.environ["ROOT"], os.environ["CD"] = root, os.path.abspath(BIN)
    try:
        spec.loader.exec_module(doc)
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    return doc


CONDITIONS = ["a-regular", "a-dense", "a-regular-shifted", "a-dense-shifted", "b-regular",
              "b-dense"]


def copy_kept_run(tmp, label, seed, condition, src_method=None, src_seed=None,
                  results="verdicts"):
    """A checkout of its own under tmp: the kept 25-task run of SRC_METHOD (default LABEL) at
    SRC_SEED (default SEED) in CONDITION (residual_paper's town-CONDITION), written as LABEL's
    evaluation of SEED under results/RESULTS there (relabelled); returns its episodes."""
    import json
    src = os.path.join(ROOT, "results", "residual_paper", "eval", src_method or label,
                       "seed%d" % (seed if src_seed is None else src_seed), "town-" + condition,
                       "results.json")
    with open(src) as f:
        res = json.load(f)
    res["label"] = label
    dst = os.path.join(tmp, "results", results, "eval", label, "seed%d" % seed, condition)
    os.makedirs(dst)
    with open(os.path.join(dst, "results.json"), "w") as f:
        json.dump(res, f)
    return res["episodes"]


def copy_kept_seeds(tmp, labels, seeds, **kw):
    """copy_kept_run of each of LABELS at each of SEEDS in the six CONDITIONS (KW passed on);
    returns {(label, seed, condition): its episodes}."""
    return {(m, s, c): copy_kept_run(tmp, m, s, c, **kw)
            for m in labels for s in seeds for c in CONDITIONS}


def write_run_record(tmp, label, seed, device, kind="train", runtime=(), **fields):
    """The run record (checkpoint.json: its runtime's device, RUNTIME's other keys and FIELDS)
    of LABEL's training seed SEED under results/verdicts/KIND in the checkout under tmp, where
    verdicts_doc.py reads it; returns its folder."""
    import json
    dst = os.path.join(tmp, "results", "verdicts", kind, "seed%d" % seed, label)
    os.makedirs(dst, exist_ok=True)
    with open(os.path.join(dst, "checkpoint.json"), "w") as f:
        json.dump(dict(fields, runtime=dict(runtime, device=device)), f)
    return dst


def success_share(episodes):
    return sum(e["outcome"] == "success" for e in episodes) / len(episodes)


class Docs(unittest.TestCase):
    def test_the_verdicts_page_is_what_the_kept_results_give(self):
        # scripts/verdicts_doc.py regenerates docs/verdicts.md from `report` over the kept
        # results; --check fails on any difference, so no number of the page is typed by hand.
        script = os.path.join(ROOT, "scripts", "verdicts_doc.py")
        env = dict(os.environ, CD=os.path.abspath(BIN), ROOT=ROOT)
        r = subprocess.run([sys.executable, script, "--check"], env=env, capture_output=True, text=True,
                           timeout=600)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(ROOT, "docs", "verdicts.md"), encoding="utf-8") as f:
            text = f.read()
        # docs/seed000.md's cim - dim figure is the page's (both from the kept evaluations).
        with open(os.path.join(ROOT, "docs", "seed000.md"), encoding="utf-8") as f:
            m = re.search(r"cim - dim over the six suites: ([+-][0-9.]+ \[[+-][0-9.]+, [+-][0-9.]+\]) "
                          r"points", f.read())
        self.assertIsNotNone(m)
        self.assertIn("cim - dim, error_rate over 6 conditions: %s points" % m.group(1), text)
        self.assertIn("| refuted |", text)

    def test_primary_rows_use_whole_seeds_and_stay_interim_until_every_seed_is_in(self):
        # A checkout of its own: residual and bc-oh "evaluated" in the six conditions by copies
        # of the kept 25-task runs (residual_paper), bc-oh's seed 2 missing one condition.
        with scratch_checkout("cd_verdicts_") as tmp:
            success = {}
            for m in ("residual", "bc-oh"):
                for s in (0, 1, 2):
                    for c in CONDITIONS:
                        if (m, s, c) != ("bc-oh", 2, "b-dense"):
                            success[m, s, c] = success_share(copy_kept_run(tmp, m, s, c))
            doc = load_verdicts_doc(tmp)
            rows = doc.primary_rows()
            row = rows[0]
            self.assertIn("residual beats bc-oh", row[0])
            self.assertIn("(3 x 2 seeds)", row[2])  # bc-oh's seed 2 lacks a condition
            self.assertTrue(row[3].startswith("not yet (interim: 3 of 10 and 2 of 10"), row[3])
            # The difference by hand: each label's mean success over its seeds and the six
            # conditions (every run holds 25 tasks), residual's minus bc-oh's.
            a = sum(success["residual", s, c] for s in (0, 1, 2) for c in CONDITIONS) / 18
            b = sum(success["bc-oh", s, c] for s in (0, 1) for c in CONDITIONS) / 12
            self.assertIn("over 6 conditions: %+.1f [" % (100 * (a - b)), row[2])
            self.assertIn("pending", rows[1][2])  # keyframe: nothing evaluated

    def test_table_rows_compare_each_tables_two_conditions(self):
        # A checkout of its own: residual and bc-oh seeds 0-1 "evaluated" in the six conditions
        # by copies of the kept 25-task runs; each table's row holds residual - bc-oh in its two
        # conditions, checked by hand, and stays interim below the planned seeds.
        with scratch_checkout("cd_tables_") as tmp:
            success = {k: success_share(eps) for k, eps in
                       copy_kept_seeds(tmp, ("residual", "bc-oh"), (0, 1)).items()}
            doc = load_verdicts_doc(tmp)
            rows = doc.table_rows()
            self.assertEqual([r[0][:16] for r in rows], ["Seed 001 table 7", "Seed 001 table 8",
                                                         "Seed 001 table 9"])
            self.assertIn("regular 78.0 against 67.0 %", rows[0][1])  # 100 - 6.8 - 15.2 ...
            for row, (reg, dense) in zip(rows, (CONDITIONS[0:2], CONDITIONS[2:4],
                                                CONDITIONS[4:6])):
                for word, c in (("regular", reg), ("dense", dense)):
                    diff = sum(success["residual", s, c] - success["bc-oh", s, c]
                               for s in (0, 1)) / 2
                    self.assertIn("%s %+.1f [" % (word, 100 * diff), row[2])
                self.assertIn("(2 x 2 seeds)", row[2])
                self.assertEqual(row[3], "not yet (interim: 2 of 10 and 2 of 10 planned seeds "
                                         "evaluated)")

    def test_the_failure_rows_compare_copycat_and_collision_rates_lower_better(self):
        # A checkout of its own: residual and bc-oh seeds 0-1 "evaluated" in the six conditions
        # by copies of the kept 25-task runs (residual's are dagger's, relabelled: residual's
        # own predate the taxonomy); the copycat and collision differences by hand (SPEC
        # section 14: copycat = stuck + restart stall + stopped free), bc-oh interim as its
        # primary row, every other baseline pending.
        with scratch_checkout("cd_failures_") as tmp:
            eps = copy_kept_seeds(tmp, ("residual",), (0, 1), src_method="dagger")
            eps.update(copy_kept_seeds(tmp, ("bc-oh",), (0, 1)))
            for s in (0, 1):  # bc-oh trained on another device than residual: named
                write_run_record(tmp, "residual", s, "cpu")
                write_run_record(tmp, "bc-oh", s, "cuda")
            doc = load_verdicts_doc(tmp)
            rows = doc.failure_rows(doc.primary_rows())
            for row, classes in zip(rows, ({"stuck", "restart_stall", "stopped_free"},
                                           {"collision"})):
                def rate(m):
                    return sum(sum(e["outcome"] in classes for e in eps[m, s, c]) / 25
                               for s in (0, 1) for c in CONDITIONS) / 12
                self.assertIn("bc-oh %+.1f [" % (100 * (rate("residual") - rate("bc-oh"))),
                              row[2])
                self.assertIn("(2 x 2 seeds; bc-oh on cuda (seeds 0-1))", row[2])
                self.assertIn("keyframe pending", row[2])
                self.assertEqual(row[3], "not yet on bc-oh, keyframe, dagger, bc-so, hd, fca")
            self.assertIn("copycat", rows[0][0])
            self.assertIn("mean collision 23.1 against bc-oh 23.8", rows[1][1])

    def test_seed_000s_seed_count_is_read_from_the_kept_evaluations(self):
        # The page's header names how many training seeds seed 000's rows rest on; while an
        # added seed is evaluated model by model it names the range and each model's count.
        with scratch_checkout("cd_cimseeds_") as tmp:
            models = ["cim", "dim", "rip", "cim-mlp", "cim-entangled", "cim-fewshot",
                      "cim-mlp-fewshot"]
            for m in models:
                for s in range(3):
                    os.makedirs(os.path.join(tmp, "results", "cim_paper", "eval", m, "seed%d" % s))
            doc = load_verdicts_doc(tmp)
            self.assertEqual(doc.cim_paper_seeds(), "3 seeds")
            for m in ("cim", "dim"):
                os.makedirs(os.path.join(tmp, "results", "cim_paper", "eval", m, "seed3"))
            self.assertEqual(doc.cim_paper_seeds(),
                             "3-4 seeds: cim 4, dim 4, rip 3, cim-mlp 3, cim-entangled 3, "
                             "cim-fewshot 3, cim-mlp-fewshot 3")

    def test_a_claim_over_conditions_waits_while_seed_counts_differ(self):
        # A checkout of its own with seed 000's kept cim and dim runs at seeds 0-1 on two
        # suites; with dim's seed 1 missing on one suite, report gives no row over the suites
        # and the claim's row says so, rather than passing one suite's figure off as the whole.
        with scratch_checkout("cd_cimrow_") as tmp:
            suites = ("town-a-regular", "town-b-dense")
            for m in ("cim", "dim"):
                for seed in (0, 1):
                    for suite in suites:
                        rel = os.path.join("results", "cim_paper", "eval", m, "seed%d" % seed,
                                           suite)
                        os.makedirs(os.path.join(tmp, rel))
                        shutil.copy(os.path.join(ROOT, rel, "results.json"),
                                    os.path.join(tmp, rel, "results.json"))
            doc = load_verdicts_doc(tmp)

            def row():
                return doc.compare_row("claim", "paper",
                                       doc.dirs_of("results/cim_paper/eval/dim/seed*/*",
                                                   "results/cim_paper/eval/cim/seed*/*"),
                                       "cim", "dim", "error_rate", True, "cmd")
            whole = row()
            self.assertRegex(whole[2], r"^cim - dim, error_rate over 2 conditions: [+-][0-9.]+ "
                                       r"\[[+-][0-9.]+, [+-][0-9.]+\] points")
            self.assertNotIn("not yet", whole[3])
            shutil.rmtree(os.path.join(tmp, "results", "cim_paper", "eval", "dim", "seed1",
                                       "town-b-dense"))
            part = row()
            self.assertEqual(part[3], "not yet (the seed counts differ across the conditions)")
            self.assertIn("town-a-regular-100 2 x 2, town-b-dense-100 2 x 1", part[2])

    def test_the_compute_line_sums_the_records_epoch_seconds_by_group_and_device(self):
        with scratch_checkout("cd_compute_") as tmp:
            doc = load_verdicts_doc(tmp)
            self.assertIn("): no run yet.", doc.compute_line())
            rec = dict(best_epoch=2, epochs_done=3, best_loss=0.5)
            write_run_record(tmp, "bc-oh", 0, "cpu", metrics=[{"seconds": 1800}, {"seconds": 900}],
                             **rec)
            write_run_record(tmp, "bc-oh", 1, "cpu", metrics=[{"seconds": 900}], **rec)
            write_run_record(tmp, "keyframe", 0, "cuda", metrics=[{"seconds": 360}], **rec)
            write_run_record(tmp, "residual", 0, "cuda", kind="cuda", metrics=[{"seconds": 36}],
                             **rec)
            write_run_record(tmp, "residual", 3, "cpu", kind="retrain", metrics=[{"seconds": 720}],
                             **rec)
            write_run_record(tmp, "keyframe", 1, "cpu", kind="cpu", metrics=[{"seconds": 180}],
                             **rec)
            write_run_record(tmp, "residual-b2", 0, "cpu", metrics=[{"seconds": 540}], **rec)
            line = doc.compute_line()
            self.assertTrue(line.endswith("section 7: cpu 1.00 h over 2 runs, cuda 0.10 h over 1 "
                                          "run; the ablations: cpu 0.15 h over 1 run; the device "
                                          "check: cuda 0.01 h over 1 run; trained again on the "
                                          "CPU: cpu 0.05 h over 1 run; retrains: cpu 0.20 h over "
                                          "1 run."), line)
            lines = doc.runs_section()
            at = [i for i, x in enumerate(lines) if x.startswith("- **Retrains**")]
            self.assertEqual(len(at), 1)  # the retrain's table: its one run, data D2 (odd seed)
            self.assertEqual(lines[at[0] + 4], "| residual | 3 | D2 | cpu | not recorded | ? | "
                                               "2 of 3 | 0.50000 |")

    def test_free_mode_rows_read_their_own_results_and_stay_interim_until_five_seeds(self):
        # A checkout of its own: residual seeds 0-2 and bc-oh seeds 0-1 "evaluated" in free
        # mode (results/verdicts-free) by copies of the kept 25-task runs; route mode empty.
        with scratch_checkout("cd_free_") as tmp:
            success = {}
            for m, seeds in (("residual", (0, 1, 2)), ("bc-oh", (0, 1))):
                success.update((k, success_share(eps)) for k, eps in copy_kept_seeds(
                    tmp, (m,), seeds, results="verdicts-free").items())
            doc = load_verdicts_doc(tmp)
            rows = doc.free_rows()
            self.assertIn("in free mode", rows[0][0])
            self.assertIn("residual beats bc-oh", rows[0][0])
            self.assertIn("(3 x 2 seeds)", rows[0][2])
            self.assertEqual(rows[0][3], "not yet (interim: 3 of 5 and 2 of 5 planned seeds "
                                         "evaluated)")
            a = sum(success["residual", s, c] for s in (0, 1, 2) for c in CONDITIONS) / 18
            b = sum(success["bc-oh", s, c] for s in (0, 1) for c in CONDITIONS) / 12
            self.assertIn("over 6 conditions: %+.1f [" % (100 * (a - b)), rows[0][2])
            self.assertEqual([r[2] for r in rows[1:]], ["pending: the free-mode runs are not "
                                                        "evaluated yet"] * 2)  # keyframe, dagger
            self.assertIn("pending", doc.primary_rows()[0][2])  # route mode's rows: untouched

    def test_the_device_rows_pair_seeds_and_match_devices(self):
        # A checkout of its own: residual (CPU) seeds 0-2 and residual-cuda seeds 0-2 and 4
        # "evaluated" by copies of the kept 25-task runs (residual-cuda's are keyframe's,
        # relabelled), bc-oh seeds 0-1. Oracle: each seed's mean success over the six
        # conditions by hand, statsmodels' t interval of the paired differences.
        from statsmodels.stats.weightstats import DescrStatsW
        with scratch_checkout("cd_device_") as tmp:
            endpoint = {}
            for label, src_m, seeds in (("residual", "residual", (0, 1, 2)),
                                        ("residual-cuda", "keyframe", (0, 1, 2, 4)),
                                        ("bc-oh", "bc-oh", (0, 1))):
                for s in seeds:
                    endpoint[label, s] = 100 * sum(
                        success_share(copy_kept_run(tmp, label, s, c, src_m, s % 3))
                        for c in CONDITIONS) / 6
            for s in (0, 1):
                write_run_record(tmp, "bc-oh", s, "cuda")
            doc = load_verdicts_doc(tmp)
            rows = doc.device_rows()
            diffs = [endpoint["residual-cuda", s] - endpoint["residual", s] for s in (0, 1, 2)]
            lo, hi = DescrStatsW(diffs).tconfint_mean(alpha=0.05)
            self.assertIn("paired by seed (3 seeds), t 95%%: %+.1f [%+.1f, %+.1f] points" % (
                sum(diffs) / 3, lo, hi), rows[0][2])
            self.assertEqual(rows[0][3], "not yet (interim: 3 of 10 seeds)")
            # Device-matched: residual-cuda's four seeds against bc-oh's two, by report.
            self.assertIn("residual-cuda - bc-oh, success_rate over 6 conditions", rows[2][2])
            self.assertIn("(4 x 2 seeds)", rows[2][2])
            a = sum(endpoint["residual-cuda", s] for s in (0, 1, 2, 4)) / 4
            b = sum(endpoint["bc-oh", s] for s in (0, 1)) / 2
            self.assertIn("%+.1f [" % (a - b), rows[2][2])
            self.assertIn("pending", rows[3][2])  # keyframe: nothing evaluated
            # Protocol section 11 (session 35): a bc-oh seed trained on the CPU leaves the
            # device-matched comparison and its plan; the CPU comparison takes it and says so.
            for c in CONDITIONS:
                copy_kept_run(tmp, "bc-oh", 2, c, "bc-oh", 2)
            write_run_record(tmp, "bc-oh", 2, "cpu")
            for s in (0, 1, 2):
                write_run_record(tmp, "residual", s, "cpu")
            doc = load_verdicts_doc(tmp)
            matched = doc.device_rows()[2]
            self.assertIn("(4 x 2 seeds)", matched[2])
            self.assertIn("%+.1f [" % (a - b), matched[2])
            self.assertTrue(matched[3].startswith("not yet (interim: 4 of 10 and 2 of 9 planned"),
                            matched[3])
            cpu = doc.primary_rows()[0]
            self.assertIn("(3 x 3 seeds); devices mixed: bc-oh on cpu (seeds 2), cuda (seeds 0-1)",
                          cpu[2])
            self.assertNotIn("device confounded", cpu[2])
            self.assertEqual(doc.primary_comparison()[0], "residual")

    def test_keyframe_trained_again_on_the_cpu_gives_its_device_rows(self):
        # Protocol section 11 (session 40). A checkout of its own: residual (CPU), keyframe
        # (CUDA), keyframe-cpu (records under results/verdicts/cpu) and residual-cuda at seeds
        # 0-9, two-stream keyframe (CPU) at 0-4, "evaluated" by copies of the kept 25-task runs.
        # Oracle: mean success by hand, statsmodels' t interval of the paired differences.
        from statsmodels.stats.weightstats import DescrStatsW
        with scratch_checkout("cd_cpu_") as tmp:
            endpoint, dense = {}, {}
            for label, src, kind, device in (("residual", "residual", "train", "cpu"),
                                             ("keyframe", "keyframe", "train", "cuda"),
                                             ("keyframe-cpu", "bc-oh", "cpu", "cpu"),
                                             ("residual-cuda", "residual", "cuda", "cuda")):
                for s in range(10):
                    success = {c: success_share(copy_kept_run(tmp, label, s, c, src, s % 3))
                               for c in CONDITIONS}
                    endpoint[label, s] = 100 * sum(success.values()) / 6
                    dense[label, s] = success["a-dense"]
                    write_run_record(tmp, label.split("-")[0], s, device, kind)
            for s in range(5):
                dense["two-stream-keyframe", s] = success_share(copy_kept_run(
                    tmp, "two-stream-keyframe", s, "a-dense", "residual", s % 3))
                write_run_record(tmp, "two-stream-keyframe", s, "cpu")
            doc = load_verdicts_doc(tmp)
            rows = doc.device_rows()
            diffs = [endpoint["keyframe", s] - endpoint["keyframe-cpu", s] for s in range(10)]
            lo, hi = DescrStatsW(diffs).tconfint_mean(alpha=0.05)
            self.assertIn("keyframe (CUDA) - keyframe (CPU), mean success over the six conditions, "
                          "paired by seed (10 seeds), t 95%%: %+.1f [%+.1f, %+.1f] points" % (
                              sum(diffs) / 10, lo, hi), rows[1][2])
            self.assertFalse(rows[1][3].startswith("not yet"), rows[1][3])
            cpu, cuda = rows[-1], rows[-2]
            self.assertIn("residual - keyframe-cpu, success_rate over 6 conditions: %+.1f [" % (
                sum(endpoint["residual", s] - endpoint["keyframe-cpu", s] for s in range(10)) / 10),
                cpu[2])
            self.assertIn("(10 x 10 seeds)", cpu[2])
            self.assertEqual(cpu[1], cuda[1])  # the paper's figures: residual's and keyframe's
            # Both device-matched comparisons have their seeds: one verdict from the two.
            alone = doc.residual_vs_row("x", "residual", "keyframe-cpu", "", "")[0][3]
            self.assertEqual(cpu[3], doc.device_word(("on the CPU", alone), ("on CUDA", cuda[3])))
            # ... and it decides keyframe's primary row (protocol section 11, session 40 (a)).
            self.assertEqual(doc.primary_rows()[1][3], "%s (by the device-matched comparison on "
                                                       "the CPU; protocol section 11)" % cpu[3])
            # Table 11: two-stream keyframe against keyframe-cpu, the device-matched comparison.
            abl = doc.ablation_rows()[1]
            main, matched = abl[2].split("; device-matched (cpu): ")
            self.assertIn("devices: two-stream-keyframe on cpu (seeds 0-4); keyframe on cuda "
                          "(seeds 0-9)", main)
            self.assertTrue(matched.startswith("%+.1f [" % (
                100 * (sum(dense["two-stream-keyframe", s] for s in range(5)) / 5 -
                       sum(dense["keyframe-cpu", s] for s in range(10)) / 10))), matched)
            self.assertTrue(matched.endswith("(5 x 10 seeds)"), matched)
            self.assertIn("; device-matched: ", abl[3])
            # residual's CUDA runs short of keyframe's seeds: the CPU row alone decides keyframe's
            # primary row (protocol section 11, session 40 (a)).
            for s in (8, 9):
                shutil.rmtree(os.path.join(tmp, "results", "verdicts", "eval", "residual-cuda",
                                           "seed%d" % s))
            doc = load_verdicts_doc(tmp)
            primary = doc.primary_rows()
            key = primary[1]
            self.assertIn("residual beats keyframe", key[0])
            self.assertEqual(key[3], "%s (by the device-matched comparison on the CPU; protocol "
                                     "section 11)" % alone)
            self.assertIn("; device-matched on the CPU, residual - keyframe-cpu: %+.1f [" % (
                sum(endpoint["residual", s] - endpoint["keyframe-cpu", s] for s in range(10)) / 10),
                key[2])
            # With keyframe-cpu short of its ten seeds, all three wait.
            for s in range(3, 10):
                shutil.rmtree(os.path.join(tmp, "results", "verdicts", "eval", "keyframe-cpu",
                                           "seed%d" % s))
            doc = load_verdicts_doc(tmp)
            self.assertEqual(doc.ablation_rows()[1][3],
                             "not yet (interim: keyframe-cpu has 3 of 10 planned seeds evaluated)")
            self.assertEqual(doc.device_rows()[-1][3],
                             "not yet (interim: 10 of 10 and 3 of 10 planned seeds evaluated)")
            self.assertEqual(doc.primary_rows()[1][3],
                             "not yet (interim: residual's CUDA runs have 8 of the 10 seeds of "
                             "keyframe; protocol section 11; or the device-matched row on the "
                             "CPU below, with 3 of keyframe-cpu's 10 seeds)")

    def test_superseded_records_are_listed_beside_the_runs_that_replaced_them(self):
        # Protocol section 10: a record a retrain replaced stays listed, with its why.txt, in
        # its own table; the kept run of the same method and seed stays in the runs table.
        with scratch_checkout("cd_superseded_") as tmp:
            epochs = {"best_epoch": 7, "epochs_done": 8}
            write_run_record(tmp, "residual.record", 13, "cpu", runtime={
                "libtorch": "1.13.0", "cpu": "AMD EPYC", "cpu_kernels": "AVX2"},
                best_loss=0.150381, **epochs)
            old = write_run_record(tmp, "residual.record", 13, "cpu", kind="superseded",
                                   runtime={"libtorch": "1.13.0"}, best_loss=0.164951, **epochs)
            with open(os.path.join(old, "why.txt"), "w") as f:
                f.write("Trained on another\nmachine.\n")
            lines = load_verdicts_doc(tmp).runs_section()
            self.assertIn("| residual | 13 | D2 | cpu | AMD EPYC (AVX2) | 1.13.0 | 7 of 8 | "
                          "0.15038 |", lines)
            self.assertIn("| residual | 13 | D2 | cpu | not recorded | 1.13.0 | 7 of 8 | "
                          "0.16495 | Trained on another machine. |", lines)
            # The superseded record is not one of the kept runs.
            self.assertEqual(sum("| residual | 13 |" in line for line in lines), 2)

    def test_the_power_rule_judges_the_primary_comparison_of_the_day(self):
        # A checkout of its own: residual and bc-oh at ten seeds, residual-cuda at eight, by
        # copies of the kept 25-task runs (seed s copies the kept seed s % 3; residual-cuda's
        # are keyframe's). Protocol section 7 and section 11's amendments: the primary
        # comparison is the CPU one while residual-cuda lacks seeds, and both stay interim;
        # at ten seeds a half-width over 6 adds seeds 10-14 to residual and bc-oh.
        import re
        with scratch_checkout("cd_power_") as tmp:
            for label, src_m, seeds in (("residual", "residual", range(10)),
                                        ("bc-oh", "bc-oh", range(10)),
                                        ("residual-cuda", "keyframe", range(8))):
                for s in seeds:
                    for c in CONDITIONS:
                        copy_kept_run(tmp, label, s, c, src_m, s % 3)
                    if label == "bc-oh":
                        write_run_record(tmp, label, s, "cuda")
            doc = load_verdicts_doc(tmp)
            cpu = doc.primary_rows()[0]
            lo, hi = map(float, re.search(r"\[([-+.\d]+), ([-+.\d]+)\] points", cpu[2]).groups())
            power = doc.power_row()
            self.assertIn("residual - bc-oh: half-width %.1f points (10 x 10 seeds)" % (
                (hi - lo) / 2), power[2])
            half = float(re.search(r"half-width ([\d.]+)", power[2]).group(1))
            if half > 6:
                self.assertTrue(power[3].startswith("target not met at 10 seeds: seeds 10-14"),
                                power[3])
                self.assertTrue(cpu[3].startswith("not yet (interim: 10 of 15 and 10 of 15"),
                                cpu[3])
            else:
                self.assertEqual(power[3], "target met")
                self.assertEqual(cpu[3], "not yet (interim: residual's CUDA runs have 8 of the "
                                 "10 seeds of bc-oh; protocol section 11)")
            # The other branch, by moving the target: a fresh module for each.
            doc = load_verdicts_doc(tmp)
            doc.POWER_TARGET = 0.0 if half <= 6 else 100.0
            power, cpu = doc.power_row(), doc.primary_rows()[0]
            if half <= 6:
                self.assertTrue(power[3].startswith("target not met at 10 seeds"), power[3])
                self.assertIn("10 of 15 and 10 of 15", cpu[3])
            else:
                self.assertEqual(power[3], "target met")
                self.assertIn("residual's CUDA runs have 8 of the 10 seeds of bc-oh", cpu[3])
            # Once residual-cuda has bc-oh's seeds, it is the primary comparison.
            for s in (8, 9):
                for c in CONDITIONS:
                    copy_kept_run(tmp, "residual-cuda", s, c, "keyframe", s % 3)
            doc = load_verdicts_doc(tmp)
            doc.POWER_TARGET = 100.0
            self.assertIn("residual-cuda - bc-oh: half-width", doc.power_row()[2])
            self.assertIn("(10 x 10 seeds)", doc.power_row()[2])
            self.assertNotIn("CUDA runs have", doc.primary_rows()[0][3])

    def test_the_table10_row_is_each_seeds_green_light_rate_with_its_t_interval(self):
        # Three seeds of each method "evaluated" by copies of the kept 25-task runs; the oracle
        # pools each run's green entries over its passages by hand and takes statsmodels' t
        # interval over seeds (cut to 0-100 %).
        from statsmodels.stats.weightstats import DescrStatsW
        with scratch_checkout("cd_t10_") as tmp:
            rates = {}
            for m in ("bc-oh", "keyframe", "residual"):
                for s in range(3):
                    for c in CONDITIONS:
                        eps = copy_kept_run(tmp, m, s, c)
                        if c == "a-dense":
                            rates.setdefault(m, []).append(
                                100 * sum(e["green_light_entries"] for e in eps) /
                                sum(e["light_passages"] for e in eps))
            doc = load_verdicts_doc(tmp)
            row = doc.table10_row()
            for m, r in rates.items():
                lo, hi = DescrStatsW(r).tconfint_mean(alpha=0.05)
                self.assertIn("%s %.1f [%.1f, %.1f] (3 seeds)" % (
                    m, sum(r) / 3, max(0, lo), min(100, hi)), row[2])
            self.assertEqual(row[3], "not yet (interim: bc-oh 3, keyframe 3, residual 3 of 10 seeds)")

    def test_the_ablation_rows_name_their_devices_and_add_the_device_matched_comparison(self):
        # Protocol section 11 (session 40). A checkout of its own: two-stream bc-oh and
        # two-stream keyframe "trained" on the CPU at seeds 0-4, bc-oh at seeds 0-9 (0-7 CUDA,
        # 8-9 CPU) and keyframe at 0-9 (all CUDA), residual-b2 and residual (all CPU), each
        # "evaluated" by copies of the kept 25-task runs. Oracle: the mean success on a-dense
        # of each side by hand.
        with scratch_checkout("cd_abl_") as tmp:
            dense = {}
            for label, src, seeds, cpu in (("two-stream-bc-oh", "residual", 5, 5),
                                           ("two-stream-keyframe", "bc-oh", 5, 5),
                                           ("residual-b2", "keyframe", 5, 5),
                                           ("bc-oh", "bc-oh", 10, 2), ("keyframe", "keyframe", 10, 0),
                                           ("residual", "residual", 10, 10)):
                ablation = label not in ("bc-oh", "keyframe", "residual")
                for s in range(seeds):
                    for c in (["a-dense"] if ablation else CONDITIONS):
                        eps = copy_kept_run(tmp, label, s, c, src, s % 3)
                        if c == "a-dense":
                            dense[label, s] = success_share(eps)
                    write_run_record(tmp, label, s, "cpu" if s >= seeds - cpu else "cuda")
            doc = load_verdicts_doc(tmp)

            def mean(label, seeds):
                return 100 * sum(dense[label, s] for s in seeds) / len(seeds)

            bc, kf, b2, b4 = doc.ablation_rows()
            main, matched = bc[2].split("; device-matched (cpu): ")
            self.assertIn("two-stream-bc-oh - bc-oh, success_rate over 1 condition: %+.1f [" % (
                mean("two-stream-bc-oh", range(5)) - mean("bc-oh", range(10))), main)
            self.assertIn("(5 x 10 seeds); devices: two-stream-bc-oh on cpu (seeds 0-4); bc-oh "
                          "on cpu (seeds 8-9), cuda (seeds 0-7)", main)
            self.assertTrue(matched.startswith("%+.1f [" % (
                mean("two-stream-bc-oh", range(5)) - mean("bc-oh", (8, 9)))), matched)
            self.assertTrue(matched.endswith("(5 x 2 seeds)"), matched)
            self.assertIn("; device-matched: ", bc[3])  # both words, by device_word
            # keyframe has no CPU seed: confounded, no matched comparison.
            self.assertNotIn("device-matched", kf[2])
            self.assertIn("devices: two-stream-keyframe on cpu (seeds 0-4); keyframe on cuda "
                          "(seeds 0-9)", kf[2])
            self.assertTrue(kf[3].endswith(" (device-confounded)"), kf[3])
            # B.5: one device on both sides, so nothing is added.
            self.assertIn("residual-b2 - residual, success_rate over 1 condition: %+.1f [" % (
                mean("residual-b2", range(5)) - mean("residual", range(10))), b2[2])
            self.assertTrue(b2[2].endswith("(5 x 10 seeds)"), b2[2])
            self.assertFalse(b2[3].startswith("not yet") or "device" in b2[3], b2[3])
            self.assertEqual(b4[3], "not yet")  # no residual-b4 run
            # Interim below five ablation seeds, whatever the devices say.
            shutil.rmtree(os.path.join(tmp, "results", "verdicts", "eval", "two-stream-bc-oh",
                                       "seed4"))
            row = doc.ablation_rows()[0]
            self.assertEqual(row[3], "not yet (interim: 4 of 5 and 10 of 10 planned seeds "
                                     "evaluated)")
            self.assertIn("(4 x 2 seeds)", row[2])
            # Once section 7 adds seeds 10-14 to bc-oh, its plan is 15.
            for s in range(10, 12):
                for c in CONDITIONS:
                    copy_kept_run(tmp, "bc-oh", s, c, "bc-oh", s % 3)
            row = load_verdicts_doc(tmp).ablation_rows()[0]
            self.assertTrue(row[3].startswith("not yet (interim: 4 of 5 and 12 of 15 planned"),
                            row[3])

    def test_device_word_keeps_a_verdict_only_where_the_device_matched_one_agrees(self):
        doc = load_verdicts_doc(ROOT)
        nr = "not resolved at this power (half-width %.1f points)"
        all_, matched = "over all seeds", "device-matched"
        self.assertEqual(doc.device_word((all_, "confirmed"), (matched, "confirmed")),
                         "confirmed; device-matched: confirmed")
        self.assertEqual(doc.device_word((all_, nr % 5), (matched, nr % 9)),
                         nr % 5 + "; device-matched: " + nr % 9)
        for a, b in (("confirmed", nr % 9), ("refuted", "confirmed"), (nr % 5, "refuted")):
            self.assertEqual(doc.device_word((all_, a), (matched, b)),
                             "not resolved at this power (device-dependent: over all seeds: %s; "
                             "device-matched: %s)" % (a, b))
        self.assertEqual(doc.device_word(("on the CPU", "refuted"), ("on CUDA", "refuted")),
                         "refuted; on CUDA: refuted")

    def test_the_probe_row_is_welchs_interval_of_the_kept_probes(self):
        # Hand-made probe reports of 3 residual and 4 bc-oh seeds; the oracle is statsmodels'
        # two-sample t interval with unequal variances.
        import json
        from statsmodels.stats.weightstats import CompareMeans, DescrStatsW
        with scratch_checkout("cd_probe_") as tmp:
            values = {"residual": [(0.1, 0.30), (0.2, 0.35), (0.15, 0.20)],
                      "bc-oh": [(0.3, 0.5), (0.25, 0.45), (0.4, 0.6), (0.35, 0.52)]}
            for m, rows in values.items():
                for s, (free, blocked) in enumerate(rows):
                    d = os.path.join(tmp, "results", "verdicts", "probe", "seed%d" % s)
                    os.makedirs(d, exist_ok=True)
                    with open(os.path.join(d, m + ".json"), "w") as f:
                        json.dump({"path_free": {"history_effect": free},
                                   "blocked": {"history_effect": blocked}}, f)
            doc = load_verdicts_doc(tmp)
            row = doc.probe_row()
            for k, name in ((0, "path free"), (1, "blocked")):
                a = [v[k] for v in values["residual"]]
                b = [v[k] for v in values["bc-oh"]]
                lo, hi = CompareMeans(DescrStatsW(a), DescrStatsW(b)).tconfint_diff(
                    alpha=0.05, usevar="unequal")
                d = sum(a) / len(a) - sum(b) / len(b)
                self.assertIn("%s %+.3f [%+.3f, %+.3f]" % (name, d, lo, hi), row[2])
            self.assertIn("(3 x 4 seeds)", row[2])
            self.assertIn("interim: 3 of 10 and 4 of 10", row[3])
            doc.PLANNED.update({"residual": 3, "bc-oh": 4})  # every planned seed in: a verdict
            os.environ["ROOT"] = tmp
            try:
                doc.ROOT = tmp
                self.assertEqual(doc.probe_row()[3], "confirmed on path free, blocked")
            finally:
                del os.environ["ROOT"]

    def test_the_stall_row_is_welchs_interval_of_the_retrains_against_bc_oh(self):
        # Hand-made stop-and-go summaries of 3 residual retrains and 4 bc-oh seeds, one bc-oh
        # run with no event (stall_rate null: left out); the oracle is statsmodels' two-sample
        # t interval with unequal variances.
        import json
        from statsmodels.stats.weightstats import CompareMeans, DescrStatsW
        with scratch_checkout("cd_stall_") as tmp:
            values = {"residual-retrain": [(0.10, 0.0), (0.20, 0.05), (0.05, 0.10)],
                      "bc-oh": [(0.30, 0.10), (0.45, 0.0), (0.40, 0.20), (0.35, None),
                                (0.5, 0.3)]}
            doc = load_verdicts_doc(tmp)
            self.assertTrue(doc.stall_row()[2].startswith("pending"))  # nothing evaluated yet
            for m, rows in values.items():
                for s, pair in enumerate(rows):
                    for suite, rate in zip(("a-stopgo", "b-stopgo"), pair):
                        d = os.path.join(tmp, "results", "verdicts", "eval", m, "seed%d" % s, suite)
                        os.makedirs(d)
                        with open(os.path.join(d, "results.json"), "w") as f:
                            json.dump({"summary": {"stall_rate": rate}}, f)
            row = doc.stall_row()
            for k, name in ((0, "town-a"), (1, "town-b")):
                a = [100 * v[k] for v in values["residual-retrain"]]
                b = [100 * v[k] for v in values["bc-oh"] if v[k] is not None]
                lo, hi = CompareMeans(DescrStatsW(a), DescrStatsW(b)).tconfint_diff(
                    alpha=0.05, usevar="unequal")
                d = sum(a) / len(a) - sum(b) / len(b)
                self.assertIn("%s %+.1f [%+.1f, %+.1f]" % (name, d, lo, hi), row[2])
            self.assertIn("3 x 5 seeds", row[2])
            self.assertIn("3 x 4 seeds", row[2])  # town-b: bc-oh's eventless run left out
            self.assertEqual(row[3], "not yet (interim: 3 of 5 retrains evaluated)")
            doc.RETRAINS = 3  # every retrain in: a verdict per suite
            self.assertEqual(doc.stall_row()[3],
                             "confirmed on town-a; not resolved at this power on town-b")

    def test_the_readme_fits_in_250_lines(self):
        with open(os.path.join(ROOT, "README.md"), encoding="utf-8") as f:
            self.assertLessEqual(len(f.read().splitlines()), 250)

    def test_every_relative_link_resolves(self):
        checked = 0
        for page in pages():
            with open(page, encoding="utf-8") as f:
                text = without_code(f.read())
            for target in re.findall(r"\]\(([^)\s]+)\)", text):
                if re.match(r"[a-z]+:", target):
                    continue  # http(s), mailto: not fetched
                path, _, anchor = target.partition("#")
                dest = os.path.normpath(os.path.join(os.path.dirname(page), path)) if path else page
                rel = os.path.relpath(page, ROOT)
                self.assertTrue(os.path.exists(dest), "%s: %s does not exist" % (rel, target))
                if anchor:
                    self.assertIn(anchor, anchors(dest), "%s: no heading #%s in %s" %
                                  (rel, anchor, os.path.relpath(dest, ROOT)))
                checked += 1
        self.assertGreater(checked, 20)

    def test_the_configuration_reference_is_generated(self):
        r = subprocess.run([BIN, "config", "--reference"], capture_output=True, text=True)
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(ROOT, "docs", "configuration.md"), encoding="utf-8") as f:
            self.assertEqual(f.read(), r.stdout,
                             "docs/configuration.md is stale: regenerate it with "
                             "`build/causaldrive config --reference > docs/configuration.md`")
        # It names every table and key a config may hold, with the built-in defaults.
        self.assertIn("## [train]", r.stdout)
        self.assertIn("| `situation_weights` | text | `\"auto\"` | `\"auto\"`, `\"none\"`, "
                      "`\"balanced\"` |", r.stdout)


if __name__ == "__main__":
    unittest.main()
