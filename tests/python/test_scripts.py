"""The reproduction scripts' command line (scripts/*_paper.sh, run_steps in paper_lib.sh):
several steps run in order, an unknown step is refused before any step runs."""
import os
import subprocess
import unittest

from support import BIN, TempDirCase

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


if __name__ == "__main__":
    unittest.main()
