# needs: sumo, mujoco
"""`report --html` (SPEC section 13) and `eval --record`: the page holds every table row `report`
prints with the same numbers; the recorded frames are the observations the agent received
(h5py against what a Python policy was given); in headless Chromium the page opens from its
file with no console error, the replay's step control advances the frame and the trace
cursor, its failure control goes to the recorded failure, and the screenshot is not blank."""
import html.parser
import json
import os
import re
import shutil
import subprocess
import unittest

import h5py
import numpy as np

import causaldrive
from support import BIN, FAST, TempDirCase, cli, read_json

ROOT = os.environ.get("CAUSALDRIVE_SOURCE_DIR", os.path.join(os.path.dirname(__file__), "..", ".."))
BROWSER = os.path.join(ROOT, "tests", "browser")


class Tables(html.parser.HTMLParser):
    """The rows of the page's metric tables, cell texts in order."""

    def __init__(self):
        super().__init__()
        self.rows, self.row, self.cell, self.depth = [], None, None, 0

    def handle_starttag(self, tag, attrs):
        if tag == "table" and ("class", "metrics") in attrs:
            self.depth += 1
        elif self.depth and tag == "tr":
            self.row = []
        elif self.depth and tag in ("td", "th"):
            self.cell = ""

    def handle_endtag(self, tag):
        if tag == "table" and self.depth:
            self.depth -= 1
        elif self.depth and tag in ("td", "th") and self.cell is not None:
            self.row.append(self.cell.strip())
            self.cell = None
        elif self.depth and tag == "tr" and self.row is not None:
            self.rows.append(self.row)
            self.row = None

    def handle_data(self, data):
        if self.cell is not None:
            self.cell += data


def markdown_rows(text):
    rows = []
    for line in text.splitlines():
        if line.startswith("|") and set(line) - set("|-: "):
            rows.append([c.strip() for c in line.strip()[1:-1].split("|")])
    return rows


class RecordedObservations(TempDirCase):
    def test_the_recorded_frames_are_the_observations_the_agent_received(self):
        seen = []

        def policy(obs):
            seen.append(np.array(obs["bev"], copy=True))
            return (0.6, 0.0, 0.0)

        out = os.path.join(self.dir, "py")
        causaldrive.evaluate(policy, "quickstart", out, settings=FAST, trials=1, record=True)
        res = read_json(os.path.join(out, "results.json"))
        offset = 0
        for i, ep in enumerate(res["episodes"]):
            with h5py.File(os.path.join(out, "episodes", "episode_%06d.h5" % i), "r") as f:
                bev = f["bev"][()]
                self.assertEqual(f.attrs["outcome"].decode(), ep["outcome"])
                self.assertEqual(f.attrs["agent"].decode(), "python")
                # Its action is the agent's, every step.
                np.testing.assert_allclose(f["action"][:, :2], np.tile([0.6, 0.0], (len(bev), 1)),
                                           atol=1e-6)
            np.testing.assert_array_equal(bev, np.stack(seen[offset:offset + len(bev)]))
            offset += len(bev)
        self.assertEqual(offset, len(seen), "one recorded frame per act() call")


class HtmlPage(TempDirCase):
    def setUp(self):
        super().setUp()
        self.run_dir = os.path.join(self.dir, "cs")
        # cs (blind constant speed) collides on the quickstart suite: failures to replay.
        cli("eval", "--agent", "cs", "--suite", "quickstart", "--out", self.run_dir, "--record",
            "--quiet")
        self.page = os.path.join(self.dir, "report.html")
        self.printed = cli("report", self.run_dir, "--html", self.page).stdout
        with open(self.page, encoding="utf-8") as f:
            self.html = f.read()

    def test_the_page_holds_every_table_row_report_prints(self):
        parser = Tables()
        parser.feed(self.html)
        expected = markdown_rows(self.printed)
        self.assertGreater(len(expected), 5)
        self.assertEqual(parser.rows, expected)

    def test_it_needs_nothing_from_the_network(self):
        for needle in ("http://", "https://", "src=\"//"):
            for line in self.html.splitlines():
                if needle in line:
                    self.assertIn("http://www.w3.org/2000/svg", line, line[:200])

    def test_the_replay_plays_in_chromium(self):
        if not (os.path.exists("/usr/bin/chromium") and shutil.which("node") and
                os.path.isdir(os.path.join(BROWSER, "node_modules", "playwright-core"))):
            self.skipTest("no chromium, node or playwright-core (scripts/setup.sh installs them)")
        shot = os.path.join(self.dir, "shot.png")
        r = subprocess.run(["node", os.path.join(BROWSER, "report_page.mjs"), self.page, shot],
                           capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stderr)
        seen = json.loads(r.stdout.strip().splitlines()[-1])
        self.assertEqual(seen["console_errors"], [])
        res = read_json(os.path.join(self.run_dir, "results.json"))
        first = next(i for i, e in enumerate(res["episodes"]) if e["outcome"] == "collision")
        self.assertEqual(seen["replays"], 1)  # the first collision; cs has no inertia here
        self.assertEqual(seen["before"]["frame"], 0)
        self.assertEqual(seen["after_step"]["frame"], 1)
        self.assertGreater(seen["after_step"]["cursor"], seen["before"]["cursor"])
        self.assertTrue(seen["before"]["src_is_frame"] and seen["after_step"]["src_is_frame"])
        self.assertNotEqual(seen["after_mark"]["src"], seen["before"]["src"])
        # The failure control goes to the collision: the recording's last step.
        with h5py.File(os.path.join(self.run_dir, "episodes", "episode_%06d.h5" % first), "r") as f:
            steps = len(f["speed"])
        stride = -(-steps // 300)
        self.assertEqual(seen["after_mark"]["frame"], (steps - 1) // stride)
        self.assertIn(">> collision", seen["after_mark"]["values"])
        self.assertGreater(seen["charts"], 0)
        self.assertGreater(seen["screenshot"]["distinct_colours"], 50)
        self.assertTrue(os.path.getsize(shot) > 10000)


class Errors(TempDirCase):
    def test_episodes_without_html_is_one_line(self):
        run = os.path.join(self.dir, "cs")
        cli("eval", "--agent", "cs", "--suite", "quickstart", "--out", run, "--quiet")
        r = subprocess.run([BIN, "report", run, "--episodes", "1"], capture_output=True, text=True)
        self.assertEqual(r.returncode, 1)
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
        self.assertIn("--episodes chooses the replays of --html", r.stderr)

    def test_an_episode_without_its_recording_is_said_on_the_page(self):
        run = os.path.join(self.dir, "cs")
        cli("eval", "--agent", "cs", "--suite", "quickstart", "--out", run, "--quiet")
        page = os.path.join(self.dir, "p.html")
        cli("report", run, "--html", page, "--episodes", "0")
        with open(page) as f:
            text = f.read()
        self.assertIn("not recorded (run eval with --record", text)
        self.assertNotIn("<section class=\"replay\"", text)


def png_pixels(data_uri):
    """The RGB bytes of an 8-bit RGB PNG data URI (zlib and the five PNG filters)."""
    import base64
    import struct
    import zlib
    raw = base64.b64decode(data_uri.split(",", 1)[1])
    pos, idat, width, height = 8, b"", 0, 0
    while pos < len(raw):
        length, kind = struct.unpack(">I4s", raw[pos:pos + 8])
        chunk = raw[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            width, height = struct.unpack(">II", chunk[:8])
            assert chunk[8] == 8 and chunk[9] == 2, "8-bit RGB"
        elif kind == b"IDAT":
            idat += chunk
        pos += 12 + length
    data, stride, out = zlib.decompress(idat), width * 3, bytearray()
    prev = bytearray(stride)
    for y in range(height):
        f, line = data[y * (stride + 1)], bytearray(data[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - 3] if i >= 3 else 0
            b, c = prev[i], prev[i - 3] if i >= 3 else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        out += line
        prev = line
    return np.frombuffer(bytes(out), np.uint8).reshape(height, width, 3)


class MujocoReplay(TempDirCase):
    def test_a_mujoco_replay_shows_the_recorded_frames_and_the_return_over_time(self):
        run = os.path.join(self.dir, "reacher")
        cli("eval", "--env", "reacher", "--agent", "random", "--episodes", 3, "--max-steps", 20,
            "--record", "--out", run, "--quiet")
        page = os.path.join(self.dir, "p.html")
        cli("report", run, "--html", page)
        with open(page, encoding="utf-8") as f:
            text = f.read()
        blocks = re.findall(r'<script type="application/json" class="replay-data">(.*?)</script>',
                            text, re.S)
        self.assertEqual(len(blocks), 1)
        replay = json.loads(blocks[0].replace("<\\/", "</"))
        res = read_json(os.path.join(run, "results.json"))
        returns = [e["return"] for e in res["episodes"]]
        worst = returns.index(min(returns))
        self.assertIn("episode %d: lowest return" % worst, replay["title"])
        self.assertEqual(len(replay["frames"]), 20)
        ret = next(s for s in replay["series"] if s["name"] == "return")
        self.assertAlmostEqual(ret["values"][-1], min(returns), delta=2e-3)
        self.assertEqual([s["name"] for s in replay["series"]], ["return", "a0", "a1"])
        with h5py.File(os.path.join(run, "episodes", "episode_%06d.h5" % worst), "r") as f:
            obs = f["obs"][()]
            np.testing.assert_allclose(np.cumsum(f["reward"][()])[-1], min(returns), atol=1e-3)
        for t in (0, 7, 19):
            np.testing.assert_array_equal(png_pixels(replay["frames"][t]),
                                          obs[t].transpose(1, 2, 0))


if __name__ == "__main__":
    unittest.main()
