# needs: sumo
"""causaldrive.evaluate: the benchmark runner with a Python policy reproduces `eval`."""
import json
import os
import unittest

import numpy as np

import causaldrive
from support import TempDirCase, cli, read_json, small_suite, write_config


def assert_summaries_close(case, a, b):
    """Equal keys, equal counts and labels, numbers within float32 rounding of the speed."""
    case.assertEqual(set(a), set(b))
    for k in a:
        if isinstance(a[k], float) and isinstance(b[k], float):
            case.assertAlmostEqual(a[k], b[k], delta=1e-6 * max(1.0, abs(b[k])), msg=k)
        elif isinstance(a[k], dict):
            assert_summaries_close(case, a[k], b[k])
        else:
            case.assertEqual(a[k], b[k], k)


class EvaluateTest(TempDirCase):
    def setUp(self):
        super().setUp()
        self.config = write_config(self.dir, "regular")
        self.suite = small_suite(self.dir, tasks=3, trials=1, scenarios=("route", "leader"))

    def cli_eval(self, agent, name, config=None):
        out = os.path.join(self.dir, name)
        cli("eval", "--config", config or self.config, "--agent", agent, "--suite", self.suite,
            "--workers", 2, "--out", out, "--quiet")
        return read_json(os.path.join(out, "results.json"))

    def route_config(self):
        """self.config with a route-mode ego (ego.lateral = "route")."""
        path = os.path.join(self.dir, "route.toml")
        with open(self.config) as f, open(path, "w") as g:
            g.write(f.read() + "[ego]\nlateral = \"route\"\n")
        return path

    def test_expert_and_cs_reproduce_eval(self):
        for agent in ("expert", "cs"):
            ref = self.cli_eval(agent, "cli-" + agent)
            # A built-in agent by name, in this process.
            res = causaldrive.evaluate(agent, self.suite, os.path.join(self.dir, "py-" + agent),
                                       config=self.config)
            self.assertEqual(res["summary"], ref["summary"], agent)
            self.assertEqual([e["outcome"] for e in res["episodes"]],
                             [e["outcome"] for e in ref["episodes"]])
        # cs steers a free ego (the default) with the expert's path tracker, which reads the
        # simulator: as a callable on observations alone it is refused.
        with self.assertRaises(causaldrive.ConfigError) as e:
            causaldrive.Agent("cs", config=self.config)
        self.assertIn("path tracker", str(e.exception))
        # cs as a Python callable in route mode (the observation goes through Python and back).
        route = self.route_config()
        ref = self.cli_eval("cs", "cli-cs-route", route)
        cs = causaldrive.Agent("cs", config=route)
        calls = []

        def policy(obs):
            calls.append(obs["bev"].shape)
            return cs(obs)

        policy.reset = cs.reset
        out = os.path.join(self.dir, "py-callable")
        res = causaldrive.evaluate(policy, self.suite, out, label="python-cs", config=route)
        # The observation's speed is float32 (as in the data files), the runner's a double: the
        # same outcomes, distances equal to float32 rounding.
        self.assertEqual([e["outcome"] for e in res["episodes"]],
                         [e["outcome"] for e in ref["episodes"]])
        assert_summaries_close(self, res["summary"], ref["summary"])
        self.assertEqual(res["label"], "python-cs")
        self.assertEqual(res["agent"], "python")
        self.assertGreater(len(calls), 10)
        self.assertEqual(len(calls[0]), 3)
        on_disk = read_json(os.path.join(out, "results.json"))
        self.assertEqual(on_disk["summary"], res["summary"])
        # report puts it in a table beside the built-in agent.
        table = cli("report", out, os.path.join(self.dir, "cli-cs-route")).stdout
        self.assertIn("python-cs", table)

    def test_history_and_policy_errors(self):
        seen = []

        def stacked(obs):
            seen.append(obs["bev"].shape)
            return np.array([0.0, 1.0, 0.0], dtype=np.float32)

        res = causaldrive.evaluate(stacked, self.suite, os.path.join(self.dir, "hist"),
                                   config=self.config, history=3, history_stride=2, trials=1)
        self.assertEqual(seen[0][0], 3)
        self.assertEqual(len(seen[0]), 4)
        # A policy that never moves: every episode ends in inertia or timeout, none succeeds.
        self.assertEqual(res["summary"]["success_rate"], 0.0)

        def wrong_shape(obs):
            return [0.5, 0.0, 0.0, 0.0]  # (throttle, brake) or (throttle, brake, steer) only

        with self.assertRaises(causaldrive.ConfigError) as e:
            causaldrive.evaluate(wrong_shape, self.suite, os.path.join(self.dir, "bad"),
                                 config=self.config)
        self.assertIn("shape (4,)", str(e.exception))

        def no_steer(obs):
            return [0.5, 0.0]  # a free ego (the default) needs a steer

        with self.assertRaises(causaldrive.ConfigError) as e:
            causaldrive.evaluate(no_steer, self.suite, os.path.join(self.dir, "nosteer"),
                                 config=self.config)
        self.assertIn("shape (2,), expected (3,)", str(e.exception))
        self.assertIn("steer", str(e.exception))
        self.assertFalse(os.path.exists(os.path.join(self.dir, "nosteer", "results.json")))
        # In route mode (throttle, brake) is the action.
        res = causaldrive.evaluate(no_steer, self.suite, os.path.join(self.dir, "route"),
                                   config=self.route_config(), trials=1)
        self.assertEqual(res["summary"]["episodes"], 3)

        count = [0]

        def crashes(obs):
            count[0] += 1
            if count[0] > 50:
                raise ZeroDivisionError("policy bug")
            return [0.3, 0.0, 0.0]

        out = os.path.join(self.dir, "crash")
        with self.assertRaises(ZeroDivisionError):
            causaldrive.evaluate(crashes, self.suite, out, config=self.config)
        self.assertFalse(os.path.exists(os.path.join(out, "results.json")))
        with self.assertRaises(causaldrive.ConfigError):
            causaldrive.evaluate("no-such-agent", self.suite, os.path.join(self.dir, "x"))
        with self.assertRaises(causaldrive.ConfigError):
            causaldrive.evaluate(42, self.suite, os.path.join(self.dir, "y"))

    def test_resume_keeps_recorded_episodes(self):
        out = os.path.join(self.dir, "resume")
        first = causaldrive.evaluate("cs", self.suite, out, config=self.config)
        calls = []

        def never_called(obs):
            calls.append(1)
            return [0.0, 1.0, 0.0]

        # Same folder, another agent: refused, and the records stay.
        with self.assertRaises(causaldrive.ConfigError):
            causaldrive.evaluate(never_called, self.suite, out, config=self.config)
        again = causaldrive.evaluate("cs", self.suite, out, config=self.config)
        self.assertEqual(again["summary"], first["summary"])
        self.assertEqual(calls, [])


if __name__ == "__main__":
    unittest.main()
