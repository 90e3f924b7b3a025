#!/usr/bin/env python3
"""docs/verdicts.md from the kept results (issue 47, docs/protocol.md section 8): one row per
claim of both papers, each number produced by `causaldrive report --json` over kept
evaluations, none typed by hand. A claim whose runs are not kept yet says so.

  scripts/verdicts_doc.py            # writes docs/verdicts.md
  scripts/verdicts_doc.py --check    # exit 1 when docs/verdicts.md differs from what the kept
                                     # results give (the test that keeps the page true)

CD (the binary, default build/causaldrive) and ROOT (the checkout, default this script's) are
read from the environment.
"""
import functools
import glob
import json
import os
import subprocess
import sys

ROOT = os.environ.get("ROOT", os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
CD = os.environ.get("CD", os.path.join(ROOT, "build", "causaldrive"))
PAGE = os.path.join(ROOT, "docs", "verdicts.md")


def report(dirs, *args):
    """`causaldrive report DIRS --json ARGS` as a dict (dirs relative to ROOT)."""
    r = subprocess.run([CD, "report", *dirs, "--json", *args], cwd=ROOT, capture_output=True,
                       text=True, timeout=600)
    if r.returncode != 0:
        raise SystemExit("verdicts_doc.py: report failed: " + r.stderr.strip())
    return json.loads(r.stdout)


def pts(x):
    return "%+.1f" % (100 * x)


def compare_over(dirs, a, b, metric):
    """report --compare A B over DIRS: the comparison over the conditions (or the one
    condition's) and the conditions' rows. The comparison is None where there are several
    conditions and a label has different seed counts across them (report gives no row over
    them), e.g. while an added seed is evaluated condition by condition."""
    c = report(dirs, "--metrics", "outcomes", "--compare", a, b, "--compare-metric", metric)
    conditions = c["compare"]["conditions"]
    over = c["compare"].get("over_conditions")
    if over is None and len(conditions) == 1:
        over = conditions[0]
    return over, conditions


def compare_row(claim, paper, dirs, a, b, metric, a_better_is_claim, command):
    """A claim "A is better than B" (or, with a_better_is_claim False, "B better than A")
    judged by report --compare over the conditions both have."""
    over, conditions = compare_over(dirs, a, b, metric)
    n = len(conditions)
    if over is None:
        counts = ", ".join("%s %d x %d" % (r["condition"], r["seeds_a"], r["seeds_b"])
                           for r in conditions)
        return [claim, paper, "%s - %s, %s over %d conditions: no interval over them while the "
                "seed counts differ (seeds of A x B: %s)" % (a, b, metric, n, counts),
                "not yet (the seed counts differ across the conditions)", "`%s`" % command]
    verdict = over["verdict"]
    wanted = "A better" if a_better_is_claim else "B better"
    if verdict == "not resolved":
        word = "not resolved at this power (half-width %.1f points)" % (
            50 * (over["hi"] - over["lo"]))
    else:
        word = "confirmed" if verdict == wanted else "refuted"
    ours = "%s - %s, %s over %d condition%s: %s [%s, %s] points, P(A > B) %.2f" % (
        a, b, metric, n, "" if n == 1 else "s", pts(over["difference"]), pts(over["lo"]),
        pts(over["hi"]), over["p_improvement"])
    return [claim, paper, ours, word, "`%s`" % command]


def iqm_row(claim, paper, envs, a, b, command):
    """A claim "A's return beats B's on each of ENVS" (MuJoCo-Image) judged per environment by
    report --compare with iqm_return over the kept evaluations."""
    c = report(["results/mujoco_paper/eval"], "--compare", a, b, "--compare-metric", "iqm_return")
    by_env = {r["condition"]: r for r in c["compare"]["conditions"]}
    parts, words = [], {}
    for env in envs:
        r = by_env.get(env)
        if r is None:
            parts.append("%s: no kept runs" % env)
            words.setdefault("not testable here", []).append(env)
            continue
        parts.append("%s %+.1f [%+.1f, %+.1f] (%d x %d seeds)" % (
            env, r["difference"], r["lo"], r["hi"], r["seeds_a"], r["seeds_b"]))
        words.setdefault(claim_word(r["verdict"]), []).append(env)
    ours = "%s - %s, IQM return: %s" % (a, b, "; ".join(parts))
    return [claim, paper, ours, verdict_by_part(words), "`%s`" % command]


def claim_word(verdict):
    """report --compare's verdict on "A better than B" as the claim's word (section 8)."""
    return {"A better": "confirmed", "B better": "refuted"}.get(verdict,
                                                                "not resolved at this power")


def verdict_by_part(words):
    """{verdict: [parts]} -> "confirmed on x; not resolved at this power on y", or
    "confirmed" when every part is."""
    if set(words) == {"confirmed"}:
        return "confirmed"
    order = ["confirmed", "refuted", "not resolved at this power", "not yet",
             "not testable here"]
    return "; ".join("%s on %s" % (w, ", ".join(words[w])) for w in order if w in words)


def dirs_of(*patterns):
    out = []
    for p in patterns:
        out += sorted(glob.glob(os.path.join(ROOT, p)))
    return [os.path.relpath(d, ROOT) for d in out]


# Section 2's six conditions (the folder names of `scripts/verdicts.sh eval`) and section 7's
# planned training seeds per method.
CONDITIONS = ["a-regular", "a-dense", "a-regular-shifted", "a-dense-shifted", "b-regular",
              "b-dense"]
PLANNED = {"residual": 10, "bc-oh": 10, "keyframe": 10, "dagger": 10, "bc-so": 5, "hd": 5,
           "fca": 5}
ABLATION_PLANNED = 5  # table 11 and B.5: each ablation at 5 training seeds (the protocol)
# Seed 001's tables 7-9 (appendix B.4): collision and timeout %, in the order of CONDITIONS'
# towns and traffic (training conditions regular, dense; new weather regular, dense; new town
# regular, dense). Success is what neither took; the paper's primary endpoint is their mean.
PAPER_FAILURES = {
    "residual": [(6.8, 15.2), (25.0, 23.3), (5.7, 3.7), (18.0, 6.3), (32.7, 28.0), (50.3, 30.7)],
    "bc-oh": [(11.1, 21.9), (30.2, 36.1), (7.0, 16.0), (18.3, 16.3), (33.0, 42.0), (43.3, 52.0)],
    "keyframe": [(13.8, 11.9), (33.9, 24.8), (7.3, 9.3), (22.7, 11.7), (34.3, 31.7), (48.3, 38.0)],
    "dagger": [(14.8, 15.9), (35.0, 23.0), (12.0, 10.7), (22.7, 13.3), (31.3, 36.0), (52.3, 36.7)],
    "bc-so": [(53.0, 10.2), (76.4, 11.1), (31.7, 8.7), (42.3, 6.3), (52.0, 30.3), (73.0, 22.3)],
    "hd": [(18.3, 12.2), (45.3, 20.3), (11.0, 11.3), (21.0, 12.3), (30.7, 37.7), (55.3, 34.0)],
    "fca": [(14.7, 27.3), (34.4, 35.3), (9.0, 22.3), (18.7, 23.0), (31.3, 48.3), (49.0, 43.3)],
}


def paper_success(label):
    """The paper's mean success of LABEL's method over the six conditions (tables 7-9)."""
    m = base_of(label)[0]
    return sum(100 - c - t for c, t in PAPER_FAILURES[m]) / len(PAPER_FAILURES[m])


def evaluated_seeds(method, results="verdicts"):
    """The seeds of METHOD with a kept evaluation in every condition of section 2 (under
    results/RESULTS: verdicts, or verdicts-free for the free-mode endpoint): only whole seeds
    enter a comparison, since report pairs a label's k-th run across conditions."""
    root = os.path.join(ROOT, "results", results, "eval", method)
    seeds = []
    for d in sorted(glob.glob(os.path.join(root, "seed*")), key=lambda d: int(d[len(root) + 5:])):
        if all(os.path.exists(os.path.join(d, c, "results.json")) for c in CONDITIONS):
            seeds.append(d)
    return seeds


KINDS = ("cpu", "cuda", "retrain")  # section 11's runs: label METHOD-KIND, folder KIND/seedN/METHOD


def base_of(label):
    """LABEL's method and the folder its runs trained into: (keyframe, cpu) for keyframe-cpu,
    (residual, cuda) for residual-cuda, (bc-oh, train) for bc-oh."""
    for kind in KINDS:
        if label.endswith("-" + kind):
            return label[:-len(kind) - 1], kind
    return label, "train"


def device_of(label, seed_dir):
    """The device that LABEL's run of the seed of SEED_DIR (a .../seedN folder) trained on, from
    its kept run record (None without one)."""
    method, kind = base_of(label)
    base = os.path.join(ROOT, "results", "verdicts", kind, os.path.basename(seed_dir), method)
    for path in (base, base + ".record"):
        try:
            with open(os.path.join(path, "checkpoint.json")) as f:
                return json.load(f).get("runtime", {}).get("device")
        except OSError:
            continue
    return None


def welch(a, b):
    """mean(A) - mean(B), the half-width of Welch's 95% interval (scipy), and both means."""
    try:
        from scipy import stats
    except ImportError:
        raise SystemExit("verdicts_doc.py: Welch's interval needs scipy (Debian: python3-scipy, "
                         "which /usr/bin/python3 has with the project's setup)")
    ma, mb = sum(a) / len(a), sum(b) / len(b)
    va = sum((x - ma) ** 2 for x in a) / (len(a) - 1) / len(a)
    vb = sum((x - mb) ** 2 for x in b) / (len(b) - 1) / len(b)
    se = (va + vb) ** 0.5
    df = (va + vb) ** 2 / (va ** 2 / (len(a) - 1) + vb ** 2 / (len(b) - 1)) if se > 0 else 1
    return ma - mb, stats.t.ppf(0.975, df) * se, ma, mb


RETRAINS = 5  # protocol section 11 (session 39): residual retrained at seeds 0-4


def stall_row():
    """Section 2's stop-and-go stall rate (protocol section 11, session 39): residual's
    retrains (residual-retrain: other weights of the same recipe) against bc-oh's section-7
    runs, per suite, the mean of the per-seed stall_rate with Welch's 95% interval; interim
    until the five retrains are in."""
    claim = ("Seed 001 (secondary): residual stalls less than bc-oh at stop-and-go events "
             "(stall rate per event)")
    cmd = "`TRAIN=retrain METHODS=residual scripts/verdicts.sh train secondary`"
    rates = {}
    for m in ("residual-retrain", "bc-oh"):
        for suite in ("a-stopgo", "b-stopgo"):
            for path in glob.glob(os.path.join(ROOT, "results", "verdicts", "eval", m, "seed*",
                                               suite, "results.json")):
                with open(path) as f:
                    rate = json.load(f)["summary"]["stall_rate"]
                if rate is not None:  # no stop-and-go event in the run
                    rates.setdefault((m, suite), []).append(100 * rate)
    n = {m: min(len(rates.get((m, s), [])) for s in ("a-stopgo", "b-stopgo"))
         for m in ("residual-retrain", "bc-oh")}
    paper = "(the paper's thesis; no stall rate published)"
    if n["residual-retrain"] < 2 or n["bc-oh"] < 2:
        return [claim, paper, "pending: fewer than 2 seeds of residual's retrains (residual's "
                "section-7 weights, 8 MB, are not kept)", "not yet", cmd]
    parts, words = [], {}
    for suite, name in (("a-stopgo", "town-a"), ("b-stopgo", "town-b")):
        a, b = rates["residual-retrain", suite], rates["bc-oh", suite]
        d, half, ma, mb = welch(a, b)
        parts.append("%s %+.1f [%+.1f, %+.1f] (%.1f against %.1f %%; %d x %d seeds)" % (
            name, d, d - half, d + half, ma, mb, len(a), len(b)))
        word = ("confirmed" if d + half < 0 else "refuted" if d - half > 0 else
                "not resolved at this power")
        words.setdefault(word, []).append(name)
    ours = ("residual-retrain - bc-oh, stall rate in points, Welch 95%%: %s; residual's are "
            "retrains, other weights of its recipe" % "; ".join(parts))
    verdict = verdict_by_part(words)
    if n["residual-retrain"] < RETRAINS:
        verdict = "not yet (interim: %d of %d retrains evaluated)" % (n["residual-retrain"],
                                                                      RETRAINS)
    return [claim, paper, ours, verdict, cmd]


def probe_row():
    """The probe's claim (protocol section 11): residual's history effect is below bc-oh's, in
    the path-free and the blocked stopped frames; per group the difference of the means over
    training seeds with Welch's 95% interval (scipy), the verdict by section 8's rule."""
    claim = "Seed 001: residual relies less on the past (probe: history effect below bc-oh's)"
    cmd = "`scripts/verdicts.sh probe`"
    root = os.path.join(ROOT, "results", "verdicts", "probe")
    vals, devices = {}, {}
    for m in ("residual", "bc-oh"):
        for path in glob.glob(os.path.join(root, "seed*", m + ".json")):
            with open(path) as f:
                vals.setdefault(m, []).append(json.load(f))
            devices.setdefault(m, set()).add(device_of(m, os.path.dirname(path)))
    if len(vals.get("residual", [])) < 2 or len(vals.get("bc-oh", [])) < 2:
        return [claim, "", "pending: fewer than 2 probed seeds of each", "not yet", cmd]
    parts, words = [], {}
    for group, name in (("path_free", "path free"), ("blocked", "blocked")):
        a = [r[group]["history_effect"] for r in vals["residual"]
             if r[group]["history_effect"] is not None]
        b = [r[group]["history_effect"] for r in vals["bc-oh"]
             if r[group]["history_effect"] is not None]
        d, half, ma, mb = welch(a, b)
        parts.append("%s %+.3f [%+.3f, %+.3f] (%.3f against %.3f)" % (
            name, d, d - half, d + half, ma, mb))
        word = ("confirmed" if d + half < 0 else "refuted" if d - half > 0 else
                "not resolved at this power (half-width %.3f)" % half)
        words.setdefault(word, []).append(name)
    ours = "residual - bc-oh, history effect, Welch 95%%: %s (%d x %d seeds)" % (
        "; ".join(parts), len(vals["residual"]), len(vals["bc-oh"]))
    if not devices["residual"] & devices["bc-oh"]:
        ours += "; device confounded: residual on %s, bc-oh on %s" % (
            "/".join(sorted(map(str, devices["residual"]))),
            "/".join(sorted(map(str, devices["bc-oh"]))))
    verdict = "; ".join("%s on %s" % (w, ", ".join(g)) for w, g in words.items())
    if len(vals["residual"]) < PLANNED["residual"] or len(vals["bc-oh"]) < PLANNED["bc-oh"]:
        verdict = "not yet (interim: %d of %d and %d of %d planned seeds probed)" % (
            len(vals["residual"]), PLANNED["residual"], len(vals["bc-oh"]), PLANNED["bc-oh"])
    return [claim, "(the paper's thesis; no figure)", ours, verdict, cmd]


def t_interval_raw(values):
    """Mean and Student t 95% interval over seeds (scipy)."""
    from scipy import stats
    n = len(values)
    mean = sum(values) / n
    if n < 2:
        return mean, None, None
    sd = (sum((x - mean) ** 2 for x in values) / (n - 1)) ** 0.5
    half = stats.t.ppf(0.975, n - 1) * sd / n ** 0.5
    return mean, mean - half, mean + half


def t_interval(values):
    """t_interval_raw of a rate in %, cut to 0-100."""
    mean, lo, hi = t_interval_raw(values)
    if lo is None:
        return mean, None, None
    return mean, max(0.0, lo), min(100.0, hi)  # a rate in %: within 0-100


def table10_row():
    """Table 10 (protocol section 2): each of bc-oh, keyframe, residual's green-light rate on
    verdicts-town-a-dense (clean), per training seed from report --metrics lights, with its t
    interval over seeds against the paper's figure (section 8: inside reproduces)."""
    claim = "Seed 001 table 10: green-light rate (BCOH / KeyFrame / residual)"
    paper = {"bc-oh": 30.6, "keyframe": 42.1, "residual": 66.3}
    cmd = "`scripts/verdicts.sh report`"
    parts, words, counts = [], {}, []
    for m in ("bc-oh", "keyframe", "residual"):
        dirs = [os.path.relpath(os.path.join(d, "a-dense"), ROOT) for d in evaluated_seeds(m)]
        if not dirs:
            continue
        rates = [c["mean"] for d in dirs
                 for c in report([d], "--metrics", "lights")["cells"]
                 if c["metric"] == "green_light_rate" and c["mean"] is not None]
        mean, lo, hi = t_interval([100 * r for r in rates])
        counts.append((m, len(rates)))
        if lo is None:
            parts.append("%s %.1f (1 seed)" % (m, mean))
            continue
        parts.append("%s %.1f [%.1f, %.1f] (%d seeds)" % (m, mean, lo, hi, len(rates)))
        word = ("reproduces" if lo <= paper[m] <= hi else
                "does not reproduce (higher)" if lo > paper[m] else
                "does not reproduce (lower)")
        words.setdefault(word, []).append(m)
    paper_text = "30.6 / 42.1 / 66.3 %"
    if not parts:
        return [claim, paper_text, "pending: the protocol's runs (docs/protocol.md) are not "
                "evaluated yet", "not yet", cmd]
    verdict = "; ".join("%s for %s" % (w, ", ".join(g)) for w, g in words.items())
    if len(counts) < 3 or any(n < PLANNED[m] for m, n in counts):
        verdict = "not yet (interim: %s of 10 seeds)" % ", ".join(
            "%s %d" % (m, n) for m, n in counts)
    return [claim, paper_text, "green-light rate %, t 95% over seeds: " + "; ".join(parts),
            verdict or "not yet", cmd]


# Section 2's ablations (protocol section 11): claim, paper figure, label, base method, and
# whether the claim is that the ablation is the better.
ABLATIONS = (
    ("Seed 001 table 11: two streams alone do not help bc-oh (two-stream bc-oh below "
     "bc-oh)", "23.7 against 34.1 % success", "two-stream-bc-oh", "bc-oh", False),
    ("Seed 001 table 11: two streams alone do not help keyframe (two-stream keyframe "
     "below keyframe)", "38.7 against 41.9 % success", "two-stream-keyframe", "keyframe",
     False),
    ("Seed 001 B.5: residual with 2 memory branches beats 1", "52.6 against 52.0 %",
     "residual-b2", "residual", True),
    ("Seed 001 B.5: residual with 4 memory branches falls below 1", "50.7 against 52.0 %",
     "residual-b4", "residual", False))


def ablation_rows():
    """Tables 11 and B.5 (protocol section 11): each ablation against its base method on
    verdicts-town-a-dense, by report --compare (success rate), interim until the ablation's
    five seeds and the base method's planned ones (planned: seeds 10-14 too once added) are
    evaluated. Where the two sides trained on other devices (session 40), the row names them
    and adds the device-matched comparison against the base method's seeds on the ablation's
    device, or else against the base method trained again on the CPU (METHOD-cpu, interim
    until its planned seeds), if there are any (device_word); without one, the verdict is
    marked device-confounded."""
    cmd = "scripts/verdicts.sh secondary"
    out = []
    for claim, paper, label, base, ablation_better in ABLATIONS:
        root = os.path.join(ROOT, "results", "verdicts", "eval")
        abl = [d for d in sorted(glob.glob(os.path.join(root, label, "seed*")))
               if os.path.exists(os.path.join(d, "a-dense", "results.json"))]
        ref = evaluated_seeds(base)
        if not abl or not ref:
            out.append([claim, paper, "pending: the protocol's runs (docs/protocol.md) are not "
                        "evaluated yet", "not yet", "`%s`" % cmd])
            continue

        def compare(ref_label, ref_seeds):
            dirs = [os.path.relpath(os.path.join(d, "a-dense"), ROOT) for d in abl + ref_seeds]
            r = compare_row(claim, paper, dirs, label, ref_label, "success_rate", ablation_better,
                            cmd)
            r[2] += " (%d x %d seeds)" % (len(abl), len(ref_seeds))
            return r

        row = compare(base, ref)
        abl_dev, ref_dev = devices_of(label, abl), devices_of(base, ref)
        matched = again = None
        if len(set(abl_dev) | set(ref_dev)) > 1:
            row[2] += "; devices: %s; %s" % (on_devices(label, abl_dev), on_devices(base, ref_dev))
            dev = next(iter(abl_dev)) if len(abl_dev) == 1 else None
            if dev in ref_dev:  # the base method's own seeds on the ablation's device
                matched = compare(base, [d for d in ref if device_of(base, d) == dev])
            elif dev == "cpu" and evaluated_seeds(base + "-cpu"):  # trained again (session 40)
                again = evaluated_seeds(base + "-cpu")
                matched = compare(base + "-cpu", again)
            if matched is not None:
                row[2] += "; device-matched (%s): %s" % (dev, matched[2].split(": ", 1)[1])
        if len(abl) < ABLATION_PLANNED or len(ref) < planned(base):
            row[3] = "not yet (interim: %d of %d and %d of %d planned seeds evaluated)" % (
                len(abl), ABLATION_PLANNED, len(ref), planned(base))
        elif again and len(again) < planned(base + "-cpu"):
            row[3] = "not yet (interim: %s-cpu has %d of %d planned seeds evaluated)" % (
                base, len(again), planned(base + "-cpu"))
        elif matched is not None:
            row[3] = device_word(("over all seeds", row[3]), ("device-matched", matched[3]))
        elif len(set(abl_dev) | set(ref_dev)) > 1:
            row[3] += " (device-confounded)"
        out.append(row)
    return out


def on_devices(label, by_device):
    """"LABEL on cpu (seeds 0-4)", "LABEL on cpu (seeds 10-14), cuda (seeds 0-9)": BY_DEVICE
    is devices_of's {device: [seed numbers]}."""
    return "%s on %s" % (label, ", ".join("%s (seeds %s)" % (dev, seed_ranges(n))
                                       for dev, n in sorted(by_device.items())))


def device_word(*named):
    """Protocol section 11 (session 40): one verdict from comparisons of one claim on other
    devices, NAMED (name, word) pairs, the row's own first: its word when all say the same
    (confirmed, refuted, not resolved) with the others' words after it, otherwise not resolved
    (device-dependent), naming each."""
    def kind(w):
        return "not resolved" if w.startswith("not resolved") else w
    if len({kind(w) for _, w in named}) == 1:
        return "; ".join([named[0][1]] + ["%s: %s" % nw for nw in named[1:]])
    return "not resolved at this power (device-dependent: %s)" % "; ".join(
        "%s: %s" % nw for nw in named)


def residual_vs_row(claim, label, m, pending, pending_cmd, device=None, results="verdicts",
                    plan=None, cmd="scripts/verdicts.sh report"):
    """Tables 7-9's row of residual's runs LABEL (residual, or the device check's
    residual-cuda) against method M: report --compare over the six conditions, on the seeds
    evaluated in all six under results/RESULTS (with DEVICE, only M's seeds trained on it: the
    device-matched rows); interim, with no verdict, until every planned seed of both is in
    (PLAN: label -> planned seeds, `planned` by default). CMD made the row. Returns the row and
    the two lists of seed folders, or the pending row and None."""
    plan = plan or planned
    res, other = evaluated_seeds(label, results), evaluated_seeds(m, results)
    planned_res, planned_other = plan(label), plan(m)
    if device is not None:
        # Section 11 (session 35): M's seeds trained elsewhere leave this comparison and its plan.
        kept = [d for d in other if device_of(m, d) == device]
        planned_other -= len(other) - len(kept)
        other = kept
    paper = "mean success %.1f against %.1f %%" % (paper_success("residual"), paper_success(m))
    if not res or not other:
        return [claim, paper, pending, "not yet", pending_cmd], None
    row = compare_row(claim, paper, seed_dirs(res + other), label, m, "success_rate", True, cmd)
    row[2] += " (%d x %d seeds)" % (len(res), len(other))
    if len(res) < planned_res or len(other) < planned_other:
        row[3] = "not yet (interim: %d of %d and %d of %d planned seeds evaluated)" % (
            len(res), planned_res, len(other), planned_other)
    return row, (res, other)


def devices_of(method, seeds):
    """{device: [seed numbers]} of METHOD's seed folders SEEDS, from their run records."""
    out = {}
    for d in seeds:
        out.setdefault(str(device_of(method, d)), []).append(int(os.path.basename(d)[4:]))
    return out


def seed_ranges(numbers):
    """[0, 1, 2, 5, 7, 8] -> "0-2, 5, 7-8"."""
    parts, numbers = [], sorted(numbers)
    start = prev = numbers[0]
    for n in numbers[1:] + [None]:
        if n is not None and n == prev + 1:
            prev = n
            continue
        parts.append(str(start) if start == prev else "%d-%d" % (start, prev))
        start = prev = n
    return ", ".join(parts)


def seed_dirs(seeds):
    """The six condition folders of each seed folder, relative to ROOT."""
    return [os.path.relpath(os.path.join(d, c), ROOT) for d in seeds for c in CONDITIONS]


POWER_TARGET = 6.0  # protocol section 7: the half-width of residual - bc-oh, in points
ADDED_SEEDS = 5     # seeds 10-14, added when ten do not reach it


def primary_comparison():
    """The primary comparison of the day (protocol section 11, sessions 30-31): residual on
    CUDA against bc-oh once its CUDA runs have as many whole seeds as bc-oh's, otherwise
    residual on the CPU against bc-oh. Returns (label, residual's seeds, bc-oh's seeds, the
    comparison over the six conditions), or None before both have a seed."""
    cuda, other = evaluated_seeds("residual-cuda"), evaluated_seeds("bc-oh")
    # Section 11 (session 35): with some of bc-oh's seeds trained on the CPU, the device-matched
    # comparison cannot hold all of them, and the CPU one stays the primary.
    all_cuda = all(device_of("bc-oh", d) == "cuda" for d in other)
    label = "residual-cuda" if cuda and all_cuda and len(cuda) >= len(other) else "residual"
    res = evaluated_seeds(label)
    if not res or not other:
        return None
    return label, res, other, compare_over(seed_dirs(res + other), label, "bc-oh",
                                           "success_rate")[0]


@functools.lru_cache(maxsize=None)
def seeds_added():
    """Whether section 7's rule has added seeds 10-14 to residual (both devices) and bc-oh:
    some seed above 9 of theirs is evaluated, or the primary comparison at ten seeds or more
    of both misses the power target."""
    if any(int(os.path.basename(d)[4:]) >= PLANNED["residual"]
           for m in ("residual", "residual-cuda", "bc-oh") for d in evaluated_seeds(m)):
        return True
    p = primary_comparison()
    return (p is not None and min(len(p[1]), len(p[2])) >= PLANNED["residual"]
            and 50 * (p[3]["hi"] - p[3]["lo"]) > POWER_TARGET)


def planned(label):
    """LABEL's planned seeds: section 7's (a method trained again on the CPU, METHOD-cpu: its
    method's), plus seeds 10-14 for residual (both devices) and bc-oh once the power rule has
    added them."""
    base = PLANNED[base_of(label)[0]]
    if label in ("residual", "residual-cuda", "bc-oh") and seeds_added():
        return base + ADDED_SEEDS
    return base


def power_row():
    """Section 7's power target on the primary comparison of the day: its half-width against
    6 points, and what the rule does at ten seeds."""
    claim = "Power (protocol section 7): the primary comparison's 95% half-width is at most 6 points"
    cmd = "`scripts/verdicts.sh report`"
    p = primary_comparison()
    if p is None:
        return [claim, "(no paper figure)", "pending: residual and bc-oh are not evaluated yet",
                "not yet", cmd]
    label, res, other, over = p
    half = 50 * (over["hi"] - over["lo"])
    n = min(len(res), len(other))
    ours = "%s - bc-oh: half-width %.1f points (%d x %d seeds)" % (label, half, len(res),
                                                                   len(other))
    if half <= POWER_TARGET:
        word = "target met"
        if seeds_added():  # section 7: added seeds are never dropped
            word += " (seeds 10-14 were added at ten seeds and stay planned: section 7)"
    elif n >= PLANNED["residual"] + ADDED_SEEDS:
        word = "target not met at %d seeds, the most section 7 allows" % n
    elif seeds_added():
        word = ("target not met at %d seeds: seeds 10-14 added to residual (CPU and CUDA) and "
                "bc-oh (section 7)" % n)
    else:
        word = "not yet (interim: %d of %d seeds)" % (n, PLANNED["residual"])
    return [claim, "(no paper figure)", ours, word, cmd]


BASELINES = ["bc-oh", "keyframe", "dagger", "bc-so", "hd", "fca"]  # section 3, against residual
ABLATION_LABELS = [a[2] for a in ABLATIONS]  # section 2's ablations (table 11, B.5)
AGAIN_ON_CPU = ["keyframe"]  # section 11 (session 40): trained again on the CPU, METHOD-cpu


def primary_rows():
    """Tables 7-9, the primary endpoint (protocol section 2): residual against each method
    (residual_vs_row), with the devices named where they differ."""
    out = []
    for m in BASELINES:
        claim = "Seed 001 tables 7-9: residual beats %s (%s)" % (
            m, "primary endpoint" if m == "bc-oh" else "the primary endpoint's mean")
        row, seeds = residual_vs_row(
            claim, "residual", m, "pending: the protocol's runs (docs/protocol.md) are not "
            "evaluated yet", "`scripts/verdicts.sh report`")
        if seeds:
            res_devices, by_device = set(devices_of("residual", seeds[0])), devices_of(m, seeds[1])
            if not res_devices & set(by_device):
                row[2] += "; device confounded: residual on %s, %s on %s" % (
                    "/".join(sorted(res_devices)), m, "/".join(sorted(by_device)))
            elif len(by_device) > 1:
                row[2] += "; devices mixed: " + on_devices(m, by_device)
            # Section 11 (session 30): the device-matched comparison becomes the primary one
            # once residual's CUDA runs have the other's seeds (all trained on CUDA: session
            # 35); until then both wait. Session 40 (a): for a method trained again on the CPU,
            # the device-matched row on the CPU decides once its seeds are in (with both
            # device-matched rows complete, its verdict is device_word's of the two).
            cuda = len(evaluated_seeds("residual-cuda"))
            confounded = m in ("bc-oh", "keyframe") and set(by_device) == {"cuda"} and \
                not row[3].startswith("not yet")
            matched = cpu_matched_row(m) if confounded and m in AGAIN_ON_CPU else None
            if matched is not None and not matched[3].startswith("not yet"):
                row[2] += "; device-matched on the CPU, residual - %s-cpu: %s" % (
                    m, matched[2].split(": ", 1)[1])
                row[3] = "%s (by the device-matched comparison on the CPU; protocol section " \
                         "11)" % matched[3]
            elif confounded and cuda < len(seeds[1]):
                row[3] = ("not yet (interim: residual's CUDA runs have %d of the %d seeds of "
                          "%s; protocol section 11)" % (cuda, len(seeds[1]), m))
                if matched is not None:
                    row[3] = row[3][:-1] + (
                        "; or the device-matched row on the CPU below, with %d of %s-cpu's %d "
                        "seeds)" % (len(evaluated_seeds(m + "-cpu")), m, planned(m + "-cpu")))
        out.append(row)
    return out


# Tables 7, 8 and 9 each: the CONDITIONS (and PAPER_FAILURES) index of their regular and
# dense conditions.
TABLES = [("7", "the training town", 0, 1),
          ("8", "new weather; here the shifted sensor, the BEV's stand-in", 2, 3),
          ("9", "the new town", 4, 5)]


def table_rows():
    """Tables 7, 8 and 9 one by one: residual - bc-oh (the primary pair) in each of the
    table's two conditions, a secondary comparison per condition (protocol section 2), on the
    seeds of the primary row; interim as it is. Every method's per-condition comparisons are
    in results/verdicts/primary.md."""
    res, other = evaluated_seeds("residual"), evaluated_seeds("bc-oh")
    out = []
    for table, what, *idx in TABLES:
        claim = ("Seed 001 table %s (%s), per condition (secondary): residual beats bc-oh"
                 % (table, what))
        paper = "; ".join("%s %.1f against %.1f %%" % (
            word, *(100 - sum(PAPER_FAILURES[m][i]) for m in ("residual", "bc-oh")))
            for word, i in zip(("regular", "dense"), idx))
        cmd = "`scripts/verdicts.sh report`"
        if not res or not other:
            out.append([claim, paper, "pending: the protocol's runs (docs/protocol.md) are not "
                        "evaluated yet", "not yet", cmd])
            continue
        parts, words = [], {}
        for word, i in zip(("regular", "dense"), idx):
            r = compare_over([os.path.relpath(os.path.join(d, CONDITIONS[i]), ROOT)
                              for d in res + other], "residual", "bc-oh", "success_rate")[0]
            parts.append("%s %s [%s, %s]" % (word, pts(r["difference"]), pts(r["lo"]),
                                             pts(r["hi"])))
            words.setdefault(claim_word(r["verdict"]), []).append(word)
        ours = "residual - bc-oh, success_rate in points: %s (%d x %d seeds)" % (
            "; ".join(parts), len(res), len(other))
        verdict = verdict_by_part(words)
        if len(res) < planned("residual") or len(other) < planned("bc-oh"):
            verdict = "not yet (interim: %d of %d and %d of %d planned seeds evaluated)" % (
                len(res), planned("residual"), len(other), planned("bc-oh"))
        out.append([claim, paper, ours, verdict, cmd])
    return out


def failure_rows(primary):
    """Section 2's secondary endpoints copycat_rate and collision_rate: residual's rate against
    each baseline's over the six conditions (report --compare, lower is better), on the seeds
    of the primary rows PRIMARY (primary_rows' output, in BASELINES' order); a baseline whose
    primary row is interim is "not yet" here too. A baseline whose seeds trained on other
    devices than residual's has them named (section 11, session 40: keyframe's CUDA runs stay
    its runs here)."""
    interim = {m for m, row in zip(BASELINES, primary) if row[3].startswith("not yet")}
    res = evaluated_seeds("residual")
    res_devices = set(devices_of("residual", res))
    mean_collision = {m: sum(c for c, _ in PAPER_FAILURES[m]) / len(PAPER_FAILURES[m])
                      for m in ["residual"] + BASELINES}
    out = []
    for metric, claim, paper in (
            ("copycat_rate", "Seed 001 (secondary): residual's copycat rate (stuck + restart "
             "stall + stopped free) is below each baseline's, over the six conditions",
             "(the papers' thesis; no copycat rate published)"),
            ("collision_rate", "Seed 001 (secondary): residual's collision rate is below each "
             "baseline's, over the six conditions",
             "mean collision %.1f against %s %%" % (mean_collision["residual"], ", ".join(
                 "%s %.1f" % (m, mean_collision[m]) for m in BASELINES)))):
        parts, words = [], {}
        for m in BASELINES:
            other = evaluated_seeds(m)
            if not res or not other:
                parts.append("%s pending" % m)
                words.setdefault("not yet", []).append(m)
                continue
            over = compare_over(seed_dirs(res + other), "residual", m, metric)[0]
            devices = devices_of(m, other)
            parts.append("%s %s [%s, %s] (%d x %d seeds%s)" % (
                m, pts(over["difference"]), pts(over["lo"]), pts(over["hi"]), len(res),
                len(other), "" if set(devices) == res_devices else
                "; " + on_devices(m, devices)))
            words.setdefault("not yet" if m in interim else claim_word(over["verdict"]),
                             []).append(m)
        ours = "residual - baseline, %s in points: %s" % (metric, "; ".join(parts))
        out.append([claim, paper, ours, verdict_by_part(words), "`scripts/verdicts.sh report`"])
    return out


FREE_PLANNED = 5  # section 2: the free-mode endpoint at 5 seeds each where compute allows
FREE_CMD = "MODE=free scripts/verdicts.sh data train eval report"


def free_rows():
    """Section 2's free-mode endpoint (secondary; `MODE=free scripts/verdicts.sh`): residual
    against bc-oh, keyframe and dagger on the mean success over the six conditions with the
    agents steering, on the seeds evaluated in all six; interim until 5 seeds of each."""
    return [residual_vs_row(
        "Seed 001 tables 7-9 in free mode (the agents steer; secondary): residual beats %s" % m,
        "residual", m, "pending: the free-mode runs are not evaluated yet", "`%s`" % FREE_CMD,
        results="verdicts-free", plan=lambda label: FREE_PLANNED, cmd=FREE_CMD)[0]
        for m in ("bc-oh", "keyframe", "dagger")]


def primary_endpoint(seed_dir):
    """One run's primary endpoint (protocol section 2): its mean success rate in % over the six
    conditions, from report --metrics outcomes of its kept evaluations."""
    rates = [c["mean"] for c in report(seed_dirs([seed_dir]), "--metrics", "outcomes")["cells"]
             if c["metric"] == "success_rate"]
    if len(rates) != len(CONDITIONS):
        raise SystemExit("verdicts_doc.py: %s: %d of the six conditions reported" % (
            seed_dir, len(rates)))
    return 100 * sum(rates) / len(rates)


def device_effect_row(method, cuda_label, cpu_label, cmd):
    """A device check (protocol section 11, sessions 30 and 40): METHOD's runs trained on CUDA
    (CUDA_LABEL) minus its runs of the same seeds trained on the CPU (CPU_LABEL), the primary
    endpoint paired by seed with a t interval over the seeds evaluated in both; interim until
    METHOD's planned seeds."""
    claim = "Device check: training on CUDA instead of the CPU moves %s's primary endpoint" % method
    paper = ("(no paper figure; protocol section 11. The device and the libtorch build change "
             "together: the runs table below names both)")
    cpu = {os.path.basename(d): d for d in evaluated_seeds(cpu_label)}
    gpu = {os.path.basename(d): d for d in evaluated_seeds(cuda_label)}
    both = sorted(set(cpu) & set(gpu), key=lambda s: int(s[4:]))
    if len(both) < 2:
        return [claim, paper, "pending: %d seed%s evaluated with both devices" % (
            len(both), "" if len(both) == 1 else "s"), "not yet", cmd]
    diffs = [primary_endpoint(gpu[s]) - primary_endpoint(cpu[s]) for s in both]
    mean, lo, hi = t_interval_raw(diffs)
    ours = ("%s (CUDA) - %s (CPU), mean success over the six conditions, paired by seed (%d "
            "seeds), t 95%%: %+.1f [%+.1f, %+.1f] points" % (method, method, len(both), mean,
                                                             lo, hi))
    if lo > 0 or hi < 0:
        word = "the device moves it (%s on CUDA)" % ("higher" if lo > 0 else "lower")
    else:
        word = "no device effect resolved (half-width %.1f points)" % ((hi - lo) / 2)
    if len(both) < planned(method):
        word = "not yet (interim: %d of %d seeds)" % (len(both), planned(method))
    return [claim, paper, ours, word, cmd]


def device_rows():
    """The device checks (protocol section 11): (a) residual trained on CUDA minus residual
    trained on the CPU (session 30), and keyframe's section-7 runs (CUDA) minus keyframe
    trained again on the CPU (keyframe-cpu, session 40), each paired by seed; (b) the
    device-matched comparisons: residual (CUDA) - bc-oh and - keyframe, all on CUDA, and
    residual (CPU) - keyframe-cpu, all on the CPU, by report --compare as the primary rows.
    Where both of keyframe's device-matched comparisons have their planned seeds, the CPU row's
    verdict is device_word's of the two. Interim until the planned seeds of each."""
    out = [device_effect_row("residual", "residual-cuda", "residual", CUDA_CMD)]
    out += [device_effect_row(m, m, m + "-cpu", CPU_CMD % m) for m in AGAIN_ON_CPU]
    return out + [list(cuda_matched_row(m)) for m in ("bc-oh", "keyframe")] + [
        list(cpu_matched_row(m)) for m in AGAIN_ON_CPU]


ENDPOINT = {"bc-oh": "primary endpoint"}  # the others: the primary endpoint's mean
CUDA_CMD = "`TRAIN=cuda METHODS=residual scripts/verdicts.sh eval report`"
CPU_CMD = "`TRAIN=cpu METHODS=%s scripts/verdicts.sh train eval report`"


@functools.lru_cache(maxsize=None)
def cuda_matched_row(m):
    """Section 11 (session 30): residual (CUDA) - M over M's CUDA seeds, all on CUDA (a tuple:
    computed once, read by cpu_matched_row and device_rows)."""
    claim = ("Seed 001 tables 7-9, device-matched: residual beats %s, all trained on CUDA "
             "(%s)" % (m, ENDPOINT.get(m, "the primary endpoint's mean")))
    return tuple(residual_vs_row(claim, "residual-cuda", m,
                                 "pending: residual's CUDA runs are not evaluated yet", CUDA_CMD,
                                 device="cuda")[0])


@functools.lru_cache(maxsize=None)
def cpu_matched_row(m):
    """Section 11 (session 40): residual (CPU) - M-cpu, M trained again on this CPU. Where the
    CUDA-matched row has its planned seeds too, the verdict is device_word's of the two (a
    tuple: computed once, read by primary_rows and device_rows)."""
    claim = ("Seed 001 tables 7-9, device-matched: residual beats %s, both trained on this "
             "CPU (%s trained again: %s-cpu; %s)" % (
                 m, m, m, ENDPOINT.get(m, "the primary endpoint's mean")))
    row = residual_vs_row(claim, "residual", m + "-cpu",
                          "pending: %s's CPU runs are not evaluated yet" % m, CPU_CMD % m)[0]
    cuda = cuda_matched_row(m)[3]
    if not row[3].startswith("not yet") and not cuda.startswith("not yet"):
        row[3] = device_word(("on the CPU", row[3]), ("on CUDA", cuda))
    return tuple(row)


CIM_EVAL = "results/cim_paper/eval"
CIM_ROWS = ["cim", "dim", "rip", "cim-mlp", "cim-entangled", "cim-fewshot", "cim-mlp-fewshot"]


def cim_paper_seeds():
    """How many training seeds seed 000's rows rest on: "N seeds", or the range with the count
    per model while an added seed is evaluated model by model."""
    n = {m: len(dirs_of(CIM_EVAL + "/" + m + "/seed*")) for m in CIM_ROWS}
    counts = sorted(set(n.values()))
    if len(counts) == 1:
        return "%d seeds" % counts[0]
    return "%d-%d seeds: %s" % (counts[0], counts[-1],
                                ", ".join("%s %d" % (m, n[m]) for m in CIM_ROWS))


def rows():
    E = CIM_EVAL
    cim_cmd = "scripts/cim_paper.sh intervals"
    out = [
        compare_row("Seed 000 table 1: CIM's error is below DIM's", "20 / 38 % against DIM's 65-83 %",
                    dirs_of(E + "/dim", E + "/cim"), "cim", "dim", "error_rate", True, cim_cmd),
        compare_row("Seed 000 table 1: CIM's error is below RIP's", "20 / 38 % against RIP's 65-83 %",
                    dirs_of(E + "/rip", E + "/cim"), "cim", "rip", "error_rate", True, cim_cmd),
        compare_row("Seed 000 table 2: CIM is better than CIM-MLP", "20 / 38 % against 22 / 42 %",
                    dirs_of(E + "/cim", E + "/cim-mlp"), "cim", "cim-mlp", "error_rate", True,
                    cim_cmd),
        compare_row("Seed 000 table 2: CIM-entangled gets stuck (more error than CIM)",
                    "81 / 78 % error, inertia 77 / 68 %",
                    dirs_of(E + "/cim", E + "/cim-entangled"), "cim", "cim-entangled",
                    "error_rate", True, cim_cmd),
        compare_row("Seed 000 table 3: few-shot CIM beats few-shot CIM-MLP (town-c)",
                    "29 against 38 %", dirs_of(E + "/cim-fewshot", E + "/cim-mlp-fewshot"),
                    "cim-fewshot", "cim-mlp-fewshot", "error_rate", True, cim_cmd),
        compare_row("Families: seed 001's residual beside seed 000's cim (route mode, 4 conditions)",
                    "(no paper figure)",
                    dirs_of("results/residual_paper/eval/residual/seed*/town-?-regular",
                            "results/residual_paper/eval/residual/seed*/town-?-dense",
                            "results/residual_paper/eval/cim/seed*/town-?-regular",
                            "results/residual_paper/eval/cim/seed*/town-?-dense"),
                    "residual", "cim", "success_rate", True, "scripts/residual_paper.sh families"),
    ]
    t13 = ["ant", "reacher", "humanoid"]
    out += [
        iqm_row("Seed 001 table 13: residual's return beats BCOH's (Ant, Reacher, Humanoid)",
                "860 / -62 / 372 against 746 / -81 / 258", t13, "residual", "bc-oh",
                "scripts/mujoco_paper.sh table"),
        iqm_row("Seed 001 table 13: residual's return beats KeyFrame's (Ant, Reacher, Humanoid)",
                "860 / -62 / 372 against 790 / -71 / 294", t13, "residual", "keyframe",
                "scripts/mujoco_paper.sh table"),
    ]
    primary = primary_rows()
    out += primary
    out += table_rows()
    out += failure_rows(primary)
    out += device_rows()
    out.append(power_row())
    out += free_rows()
    out.append(table10_row())
    out += ablation_rows()
    out.append(probe_row())
    out.append(stall_row())
    return out


def run_records(kind, results="verdicts"):
    """(seed, method, folder, checkpoint.json) of each run record under
    results/RESULTS/KIND/seedN/: METHOD/, or METHOD.record/ for a run whose weights are over
    5 MB (its record kept, its weights not)."""
    for path in glob.glob(os.path.join(ROOT, "results", results, kind, "seed*", "*",
                                       "checkpoint.json")):
        folder = os.path.dirname(path)
        with open(path) as f:
            ck = json.load(f)
        method = os.path.basename(folder)
        if method.endswith(".record"):
            method = method[:-len(".record")]
        yield int(os.path.basename(os.path.dirname(folder))[4:]), method, folder, ck


RUNS_HEAD = ["| method | seed | data | device | CPU | libtorch | best epoch of | validation loss |",
             "|---|---:|---|---|---|---|---|---:|"]  # run_line's columns


def run_line(method, seed, cols):
    """A runs table's row: METHOD, SEED and run_columns' COLS."""
    return "| %s | %d | %s | %s | %s | %s | %s | %.5f |" % ((method, seed) + cols)


def run_columns(ck, seed):
    """A training run's columns of the runs tables from its checkpoint.json CK: data folder,
    device, CPU (and its kernels), libtorch, best epoch, validation loss."""
    rt = ck.get("runtime", {})
    return ("D%d" % (seed % 2 + 1), rt.get("device", "?"),
            "%s (%s)" % (rt["cpu"], rt.get("cpu_kernels", "kernels not recorded")) if "cpu" in rt
            else "not recorded", rt.get("libtorch", "?"),
            "%d of %d" % (ck["best_epoch"], ck["epochs_done"]), ck["best_loss"])


def compute_line():
    """The training compute of the kept run records, by device: the sum of their epochs'
    seconds (checkpoint.json's metrics), per group of runs."""
    groups = [("section 7", "train", "verdicts"), ("the ablations", "train", "verdicts"),
              ("the device check", "cuda", "verdicts"),
              ("trained again on the CPU", "cpu", "verdicts"),
              ("superseded", "superseded", "verdicts"), ("retrains", "retrain", "verdicts"),
              ("free mode", "train", "verdicts-free")]
    parts = []
    for name, kind, results in groups:
        by_device = {}
        for _, method, _, ck in run_records(kind, results):
            if kind == "train" and (method in ABLATION_LABELS) != (name == "the ablations"):
                continue  # section 2's ablations train beside section 7's runs, counted apart
            t = by_device.setdefault(ck.get("runtime", {}).get("device", "?"), [0.0, 0])
            t[0] += sum(e["seconds"] for e in ck.get("metrics", []))
            t[1] += 1
        if by_device:
            parts.append("%s: %s" % (name, ", ".join(
                "%s %.2f h over %d run%s" % (d, t[0] / 3600, t[1], "" if t[1] == 1 else "s")
                for d, t in sorted(by_device.items()))))
    return ("- **Compute** (training only, from the kept run records: the sum of their epochs' "
            "seconds; dagger's records hold its last iteration's epochs; evaluation time is not "
            "recorded; the tuning runs keep no record): " + ("; ".join(parts) if parts else "no run yet") + ".")


def runs_section():
    """Section 10 of the protocol, every run reported: the tuning evaluations kept so far and
    each kept training run of section 7 with its data folder and device."""
    val = os.path.join(ROOT, "results", "residual_paper", "recipe", "eval")
    variants = ["old", "signed", "hold-balanced", "signed-hold-balanced"]
    methods = ["residual", "bc-oh", "keyframe", "dagger", "bc-so", "hd", "fca"]
    tuned = []
    for m in methods:
        done = [v for v in variants
                if all(os.path.exists(os.path.join(val, v, "seed0", m, k, "results.json"))
                       for k in ("regular", "dense"))]
        tuned.append("%s %d/4" % (m, len(done)))
    lines = ["", "## Runs of the protocol so far", "",
             "Every run is listed (protocol section 10), generated from the kept results.", "",
             "- **Tuning** (section 6, seed 0, validation suites; variants evaluated of four): " +
             ", ".join(tuned) + ". The choices: `results/verdicts/tuning.md` "
             "(`scripts/verdicts.sh choose`).",
             "- **Training** (section 7; residual-cuda: the device check of section 11; "
             "keyframe-cpu: keyframe trained again on this CPU, section 11, session 40; then "
             "section 2's ablations: %s), the kept runs:" % ", ".join(ABLATION_LABELS),
             ""] + RUNS_HEAD
    runs = []
    for kind in ("train", "cuda", "cpu"):
        for seed, method, _, ck in run_records(kind):
            if kind != "train":  # section 11's runs: the device check's, or trained again
                method += "-" + kind
            order = methods.index(method) if method in methods else 98 if kind != "train" else 99
            runs.append((order, seed, method, run_columns(ck, seed)))
    lines += [run_line(method, seed, cols) for _, seed, method, cols in sorted(runs)]
    if not runs:
        lines.append("| (none yet) | | | | | | | |")
    # Records a retrain replaced (results/verdicts/superseded/seedN/METHOD.record, each with a
    # why.txt): listed, never read by a comparison.
    old = []
    for seed, method, folder, ck in run_records("superseded"):
        with open(os.path.join(folder, "why.txt")) as f:
            why = " ".join(f.read().split())
        old.append((methods.index(method) if method in methods else 99, seed, method,
                    run_columns(ck, seed), why))
    if old:
        lines += ["", "- **Superseded** (section 10): trained, replaced by the run above of the "
                  "same method and seed before any evaluation of theirs, and kept as records in "
                  "`results/verdicts/superseded/`:", "",
                  "| method | seed | data | device | CPU | libtorch | best epoch of | "
                  "validation loss | why |", "|---|---:|---|---|---|---|---|---:|---|"]
        lines += [run_line(method, seed, cols) + " %s |" % why
                  for _, seed, method, cols, why in sorted(old)]
    retrains = sorted((methods.index(method) if method in methods else 99, seed, method,
                       run_columns(ck, seed)) for seed, method, _, ck in run_records("retrain"))
    if retrains:
        lines += ["", "- **Retrains** (section 11, session 39: residual's stop-and-go stall rate; "
                  "the recipe, data folder and seed of its section-7 run, other weights; "
                  "evaluated on the stop-and-go suites only, labelled METHOD-retrain):", ""]
        lines += RUNS_HEAD + [run_line(method, seed, cols) for _, seed, method, cols in retrains]
    free = sorted((methods.index(method) if method in methods else 99, seed, method,
                   run_columns(ck, seed)) for seed, method, _, ck in run_records("train",
                                                                                 "verdicts-free"))
    head = ("- **Free mode** (section 2's free-mode endpoint, `%s`; results in "
            "`results/verdicts-free/`)" % FREE_CMD)
    if free:
        lines += ["", head + ", the kept runs:", ""] + RUNS_HEAD
        lines += [run_line(method, seed, cols) for _, seed, method, cols in free]
        counts = ((m, len(evaluated_seeds(m, "verdicts-free"))) for m in methods)
        done = ["%s %d" % (m, n) for m, n in counts if n]
        lines += ["", "Seeds evaluated in all six conditions in free mode: %s." % (
            ", ".join(done) if done else "none yet")]
    else:
        lines += ["", head + ": no run trained yet."]
    evaluated = ["%s %d" % (m, len(evaluated_seeds(m))) for m in methods if evaluated_seeds(m)]
    lines += ["", "The CPU is the model the run trained on and ATen's kernels there (`runtime.cpu` "
              "and `cpu_kernels` of its checkpoint.json; "
              "runs trained before those fields existed say \"not recorded\"): the same seed gives "
              "the same bytes on one CPU model, and a retrain on another may differ in rounding "
              "(docs/gpu.md). "
              "Runs trained on a lent GPU are noted in protocol section 11 (docs/gpu.md, "
              "\"Training runs on a lent machine\"). " +
              ("Seeds evaluated in all six conditions of section 2: %s." % ", ".join(evaluated)
               if evaluated else "No section-7 run is evaluated yet.")]
    lines += ["", compute_line()]
    devices = {}
    for _, _, method, (_, device, *_) in runs:
        if base_of(method)[1] == "train":
            devices.setdefault(method, set()).add(device)
    base = devices.get("residual", set())
    confounded = [m for m in methods if m != "residual" and m in devices and base and
                  not devices[m] & base]
    if confounded:
        lines += ["", "Device and method are confounded in residual - %s: residual's runs "
                  "trained on %s, theirs on %s (protocol section 11); what the device does to a "
                  "method's mean is measured only by the device checks above." % (
                      ", ".join(confounded), "/".join(sorted(base)),
                      "/".join(sorted(set().union(*(devices[m] for m in confounded)))))]
    return lines


def page():
    lines = ["# Verdicts", "",
             "[Back to the README](../README.md) · [all pages](README.md)", "",
             "One row per claim of both papers (docs/protocol.md): the claim, the paper's figure, "
             "ours with its 95% interval, the verdict (section 8 of the protocol), and the "
             "command that made the row. Generated by `scripts/verdicts_doc.py` from the kept "
             "results: no number is typed by hand, and a test fails when this page differs from "
             "them. Seed 000's rows come from its kept paper-scale runs (100 tasks x 3 trials x "
             + cim_paper_seeds() + "; error = collision + inertia: the paper's own error needs per-episode "
             "inertia, which the records of seeds 0-2 predate). Table 13's rows judge the kept MuJoCo-Image runs (3 "
             "seeds x 10 episodes per env; IQM return with a two-level bootstrap, which with 3 "
             "seeds understates the spread between seeds). Seed 001's driving rows judge the "
             "protocol's runs, and stay interim (\"not yet\") until every planned seed of both "
             "methods is evaluated.", "",
             "| claim | paper | ours | verdict | command |", "|---|---|---|---|---|"]
    for r in rows():
        lines.append("| " + " | ".join(r) + " |")
    lines += runs_section()
    return "\n".join(lines) + "\n"


def main():
    text = page()
    if "--check" in sys.argv[1:]:
        with open(PAGE, encoding="utf-8") as f:
            if f.read() != text:
                print("docs/verdicts.md differs from the kept results: run scripts/verdicts_doc.py",
                      file=sys.stderr)
                return 1
        return 0
    with open(PAGE + ".tmp", "w", encoding="utf-8") as f:
        f.write(text)
    os.replace(PAGE + ".tmp", PAGE)
    return 0


if __name__ == "__main__":
    sys.exit(main())
