# needs: sumo
"""The Python example of docs/python.md runs as written (from a scratch folder, against the build)."""
import os
import re
import subprocess
import sys
import unittest

from support import TempDirCase

SOURCE = os.environ.get("CAUSALDRIVE_SOURCE_DIR",
                        os.path.join(os.path.dirname(__file__), "..", ".."))


def readme_example():
    with open(os.path.join(SOURCE, "docs", "python.md")) as f:
        text = f.read()
    m = re.search(r"<!-- python-example: begin -->\s*```python\n(.*?)```\s*"
                  r"<!-- python-example: end -->", text, re.S)
    if not m:
        raise AssertionError("docs/python.md has no python-example block")
    return m.group(1)


class ReadmeExampleTest(TempDirCase):
    def test_example_runs(self):
        script = os.path.join(self.dir, "example.py")
        with open(script, "w") as f:
            f.write(readme_example())
        r = subprocess.run([sys.executable, script], cwd=self.dir, capture_output=True, text=True,
                           timeout=500)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("expert: success", r.stdout)
        self.assertRegex(r.stdout, r"training L1 loss: [0-9.]+")
        self.assertRegex(r.stdout, r"'success_rate': [0-9.]+")
        results = os.path.join(self.dir, "runs", "python-example", "eval", "results.json")
        self.assertTrue(os.path.exists(results))


if __name__ == "__main__":
    unittest.main()
