"""The kept weights (results/WEIGHTS.md): scripts/keep_weights.sh commits them alone and lists
them in results/weights.tsv; scripts/restore_weights.sh brings back what that manifest lists and
nothing else, checks every byte, fetches what a shallow clone lacks and fails in one line where
it cannot; paper_lib.sh's restore_run stops a step rather than reuse a run without weights.
Fixture repositories built here, so the tests do not depend on this checkout's history depth;
one test runs a shallow clone of this repository itself."""
import hashlib
import os
import shutil
import subprocess
import unittest

from support import TempDirCase

SOURCE = os.path.abspath(os.environ.get("CAUSALDRIVE_SOURCE_DIR",
                                        os.path.join(os.path.dirname(__file__), "..", "..")))
SCRIPTS = ["restore_weights.sh", "keep_weights.sh", "paper_lib.sh", "weights_lib.sh"]
MANIFEST = "results/weights.tsv"
RUN = "results/keep/train/seed0/%s"  # the fixture's kept runs: a (two files) and b
ENV = dict(os.environ, GIT_AUTHOR_NAME="t", GIT_AUTHOR_EMAIL="t@t", GIT_COMMITTER_NAME="t",
           GIT_COMMITTER_EMAIL="t@t", GIT_TERMINAL_PROMPT="0")


def git(cwd, *args):
    return subprocess.run(["git", *args], cwd=cwd, env=ENV, check=True, capture_output=True,
                          text=True).stdout


def fake_weights(seed, size=3000):
    """A few KB of bytes that differ from seed to seed."""
    out, block = b"", str(seed).encode()
    while len(out) < size:
        block = hashlib.sha256(block).digest()
        out += block
    return out[:size]


class WeightsCase(TempDirCase):
    def setUp(self):
        super().setUp()
        self.origin = os.path.join(self.dir, "origin")
        self.make_origin()

    def make_origin(self):
        """A repository with the scripts and two kept runs, each kept by its own keep_weights
        call (so its bytes are in its own commit), then one more commit on top."""
        os.makedirs(os.path.join(self.origin, "scripts"))
        git(self.origin, "init", "-q", "-b", "main")
        for name in SCRIPTS:
            shutil.copy2(os.path.join(SOURCE, "scripts", name), os.path.join(self.origin, "scripts"))
        self.write(self.origin, ".gitignore", b"*.tmp\nresults/**/*.pt\n")
        self.weights = {RUN % "a" + "/best.pt": fake_weights(1),
                        RUN % "a" + "/vae.pt": fake_weights(2, 5000),
                        RUN % "b" + "/best.pt": fake_weights(3)}
        for run in "ab":
            self.write(self.origin, RUN % run + "/checkpoint.json", b'{"run": "%s"}' % run.encode())
        git(self.origin, "add", "-A")
        git(self.origin, "commit", "-q", "-m", "init")
        self.commits = {}
        for run in "ab":
            for path, data in self.weights.items():
                if path.startswith(RUN % run + "/"):
                    self.write(self.origin, path, data)
            r = self.script(self.origin, "keep_weights.sh", RUN % run)
            self.assertEqual(r.returncode, 0, r.stderr)
            self.commits[run] = git(self.origin, "rev-parse", "HEAD~1").strip()
        self.write(self.origin, "notes.md", b"later work\n")
        git(self.origin, "add", "notes.md")
        git(self.origin, "commit", "-q", "-m", "later")

    @staticmethod
    def write(root, relative, data):
        path = os.path.join(root, relative)
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(path, "wb") as f:
            f.write(data)

    @staticmethod
    def script(cwd, name, *args):
        return subprocess.run([os.path.join(cwd, "scripts", name), *args], cwd=cwd, env=ENV,
                              capture_output=True, text=True, timeout=60)

    def clone(self, name, *options, reachable=True):
        dest = os.path.join(self.dir, name)
        git(self.dir, "clone", "-q", *options, "file://" + self.origin, dest)
        if not reachable:
            git(dest, "remote", "set-url", "origin", "/nonexistent")
        return dest

    @staticmethod
    def found(root, suffix):
        return sorted(os.path.relpath(os.path.join(d, f), root)
                      for d, _, names in os.walk(root) if ".git" not in d
                      for f in names if f.endswith(suffix))

    def assert_restored(self, root, paths):
        self.assertEqual(self.found(os.path.join(root, "results"), ".pt"),
                         sorted(os.path.relpath(p, "results") for p in paths))
        for path in paths:
            with open(os.path.join(root, path), "rb") as f:
                self.assertEqual(f.read(), self.weights[path], path)
        self.assertEqual(self.found(root, ".tmp"), [])

    def assert_one_line(self, r, *parts):
        self.assertNotEqual(r.returncode, 0, r.stdout)
        self.assertEqual(len(r.stderr.splitlines()), 1, r.stderr)
        for part in parts:
            self.assertIn(part, r.stderr)


class ManifestAndRestoreTest(WeightsCase):
    def test_the_manifest_lists_each_kept_file_with_its_hash_size_blob_and_commit(self):
        with open(os.path.join(self.origin, MANIFEST)) as f:
            lines = f.read().splitlines()
        self.assertEqual(lines[0], "# path\tsha256\tsize\tblob\tcommit")
        expected = []
        for path in sorted(self.weights):
            data = self.weights[path]
            blob = subprocess.run(["git", "hash-object", "--stdin"], input=data,
                                  capture_output=True, check=True).stdout.decode().strip()
            commit = self.commits[path.split("/")[4]]
            expected.append("\t".join([path, hashlib.sha256(data).hexdigest(), str(len(data)),
                                       blob, commit]))
        self.assertEqual(lines[1:], expected)
        # The weights are in their commit's tree and no longer in HEAD's.
        self.assertEqual(git(self.origin, "ls-tree", "-r", "--name-only", "HEAD", "results")
                         .split(), [RUN % "a" + "/checkpoint.json", RUN % "b" + "/checkpoint.json",
                                    MANIFEST])

    def test_a_fresh_clone_restores_the_kept_bytes_once(self):
        clone = self.clone("clone")
        self.assertEqual(self.found(clone, ".pt"), [])
        r = self.script(clone, "restore_weights.sh")
        self.assertEqual((r.returncode, r.stderr), (0, ""))
        self.assertEqual(r.stdout, "restore_weights: 3 file(s) restored, 0 already present "
                                   "under results\n")
        self.assert_restored(clone, self.weights)
        r = self.script(clone, "restore_weights.sh", RUN % "b")
        self.assertEqual(r.stdout, "restore_weights: 0 file(s) restored, 1 already present "
                                   "under %s\n" % RUN % "b")

    def test_only_the_paths_asked_for_and_none_for_an_unlisted_path(self):
        clone = self.clone("clone")
        # A path relative to the caller's folder, not the repository root.
        r = subprocess.run([os.path.join(clone, "scripts", "restore_weights.sh"), "seed0/a"],
                           cwd=os.path.join(clone, "results", "keep", "train"), env=ENV,
                           capture_output=True, text=True, timeout=60)
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assert_restored(clone, [RUN % "a" + "/best.pt", RUN % "a" + "/vae.pt"])
        r = self.script(clone, "restore_weights.sh", "results/nothing")
        self.assertEqual((r.returncode, r.stdout), (0, "restore_weights: 0 file(s) restored, "
                                                       "0 already present under results/nothing\n"))

    def test_a_deleted_run_is_not_restored(self):
        git(self.origin, "rm", "-q", "-r", RUN % "b")
        with open(os.path.join(self.origin, MANIFEST)) as f:
            kept = [line for line in f if not line.startswith(RUN % "b" + "/")]
        self.write(self.origin, MANIFEST, "".join(kept).encode())
        git(self.origin, "commit", "-q", "-am", "b deleted")
        clone = self.clone("clone")
        r = self.script(clone, "restore_weights.sh")
        self.assertEqual(r.stdout, "restore_weights: 2 file(s) restored, 0 already present "
                                   "under results\n")
        self.assert_restored(clone, [RUN % "a" + "/best.pt", RUN % "a" + "/vae.pt"])
        self.assertFalse(os.path.exists(os.path.join(clone, RUN % "b")))

    def test_a_run_deleted_with_its_line_left_in_the_manifest_is_not_restored(self):
        git(self.origin, "rm", "-q", "-r", RUN % "b")
        git(self.origin, "commit", "-q", "-m", "b deleted")
        clone = self.clone("clone")
        r = self.script(clone, "restore_weights.sh")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assert_restored(clone, [RUN % "a" + "/best.pt", RUN % "a" + "/vae.pt"])
        self.assertFalse(os.path.exists(os.path.join(clone, RUN % "b")))

    def test_a_shallow_clone_without_origin_fails_in_one_line_and_writes_nothing(self):
        clone = self.clone("shallow", "--depth", "1", reachable=False)
        r = self.script(clone, "restore_weights.sh", RUN % "a")
        self.assert_one_line(r, "git fetch --unshallow", "(commit %s)" % self.commits["a"][:7])
        self.assertTrue(r.stderr.startswith("restore_weights: %s/best.pt: " % RUN % "a"), r.stderr)
        self.assertEqual(r.stdout, "")
        self.assertEqual(self.found(clone, ".pt"), [])
        self.assertEqual(self.found(clone, ".tmp"), [])

    def test_a_shallow_clone_with_origin_fetches_what_it_lacks(self):
        clone = self.clone("shallow", "--depth", "1")
        r = self.script(clone, "restore_weights.sh")
        self.assertEqual((r.returncode, r.stderr), (0, ""))
        self.assertEqual(r.stdout, "restore_weights: 3 file(s) restored, 0 already present "
                                   "under results\n")
        self.assert_restored(clone, self.weights)
        self.assertEqual(git(clone, "rev-parse", "--is-shallow-repository").strip(), "true")

    def test_a_present_file_with_other_bytes_is_refused_and_left_alone(self):
        clone = self.clone("clone")
        self.write(clone, RUN % "a" + "/best.pt", b"retrained")
        r = self.script(clone, "restore_weights.sh", RUN % "a")
        self.assert_one_line(r, "restore_weights: %s/best.pt: not the kept bytes" % RUN % "a",
                             "scripts/keep_weights.sh %s" % RUN % "a")
        with open(os.path.join(clone, RUN % "a" + "/best.pt"), "rb") as f:
            self.assertEqual(f.read(), b"retrained")
        self.assertEqual(self.found(clone, ".tmp"), [])

    def test_bytes_that_do_not_match_the_manifest_are_not_written(self):
        clone = self.clone("clone")
        with open(os.path.join(clone, MANIFEST)) as f:
            text = f.read()
        sha = hashlib.sha256(self.weights[RUN % "b" + "/best.pt"]).hexdigest()
        self.write(clone, MANIFEST, text.replace(sha, "0" * 64).encode())
        r = self.script(clone, "restore_weights.sh", RUN % "b")
        self.assert_one_line(r, "restore_weights: %s/best.pt: blob " % RUN % "b", "not restored")
        self.assertEqual(self.found(clone, ".pt"), [])
        self.assertEqual(self.found(clone, ".tmp"), [])

    def test_a_tarball_fails_in_one_line(self):
        tarball = os.path.join(self.dir, "tarball")
        os.makedirs(tarball)
        archive = subprocess.run(["git", "archive", "HEAD"], cwd=self.origin, env=ENV,
                                 capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", tarball], input=archive, check=True)
        r = self.script(tarball, "restore_weights.sh")
        self.assert_one_line(r, "not a git checkout", "clone the repository")
        self.assertEqual(self.found(tarball, ".pt"), [])


class KeepWeightsTest(WeightsCase):
    def test_an_unrelated_staged_file_stays_staged_and_out_of_both_commits(self):
        repo = self.origin
        self.write(repo, RUN % "c" + "/checkpoint.json", b"{}")
        git(repo, "add", RUN % "c" + "/checkpoint.json")
        git(repo, "commit", "-q", "-m", "c's records")
        self.write(repo, "staged.txt", b"not ready\n")
        git(repo, "add", "staged.txt")
        self.write(repo, RUN % "c" + "/best.pt", fake_weights(4))
        before = git(repo, "rev-parse", "HEAD").strip()
        r = self.script(repo, "keep_weights.sh", RUN % "c")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertEqual(git(repo, "rev-parse", "HEAD~2").strip(), before)
        changed = lambda c: git(repo, "diff-tree", "--no-commit-id", "--name-status", "-r", c)
        self.assertEqual(changed("HEAD~1"), "A\t%s/best.pt\n" % RUN % "c")
        self.assertEqual(changed("HEAD"), "D\t%s/best.pt\nM\t%s\n" % (RUN % "c", MANIFEST))
        self.assertEqual(git(repo, "status", "--porcelain"), "A  staged.txt\n")
        with open(os.path.join(repo, MANIFEST)) as f:
            self.assertEqual([line.split("\t")[0] for line in f][1:],
                             sorted(list(self.weights) + [RUN % "c" + "/best.pt"]))

    def test_a_file_over_5_mb_is_refused_and_nothing_committed(self):
        before = git(self.origin, "rev-parse", "HEAD")
        self.write(self.origin, RUN % "a" + "/member_0.pt", b"x" * 5_000_001)
        r = self.script(self.origin, "keep_weights.sh", RUN % "a")
        self.assert_one_line(r, "keep_weights: %s/member_0.pt is 5000001 bytes" % RUN % "a")
        self.assertEqual(git(self.origin, "rev-parse", "HEAD"), before)

    def test_the_manifest_regenerated_from_history_leaves_deleted_runs_out(self):
        git(self.origin, "rm", "-q", "-r", RUN % "b")
        git(self.origin, "commit", "-q", "-m", "b deleted")
        with open(os.path.join(self.origin, MANIFEST)) as f:
            before = f.read()
        r = self.script(self.origin, "keep_weights.sh", "--manifest-only")
        self.assertEqual(r.returncode, 0, r.stderr)
        with open(os.path.join(self.origin, MANIFEST)) as f:
            self.assertEqual(f.read(), "".join(line for line in before.splitlines(True)
                                               if not line.startswith(RUN % "b" + "/")))


class RestoreRunTest(WeightsCase):
    """paper_lib.sh's kept_train on a kept run, as the paper scripts call it (set -e)."""

    def kept_train(self, clone, run):
        calls = os.path.join(self.dir, "calls")
        fake = os.path.join(self.dir, "fake_cd")
        with open(fake, "w") as f:
            f.write('#!/bin/sh\necho "$*" >> "%s"\n' % calls)
        os.chmod(fake, 0o755)
        out = os.path.join(self.dir, "runs", "keep")
        script = ('set -euo pipefail\nsource scripts/paper_lib.sh\n'
                  'kept_train "$OUT/train/seed0/%s" --method bc-so --seed 0\necho reused\n' % run)
        r = subprocess.run(["bash", "-c", script], cwd=clone, capture_output=True, text=True,
                           env=dict(ENV, CD=fake, OUT=out, KEEP="results/keep"), timeout=60)
        self.assertFalse(os.path.exists(calls))  # a kept run is never trained again
        return r, os.path.join(out, "train", "seed0")

    def test_without_its_weights_the_step_stops_in_one_line(self):
        clone = self.clone("shallow", "--depth", "1", reachable=False)
        r, seed0 = self.kept_train(clone, "a")
        self.assert_one_line(r, "restore_weights: %s/best.pt: " % RUN % "a",
                             "git fetch --unshallow")
        self.assertEqual(r.stdout, "")
        self.assertFalse(os.path.exists(seed0))  # nothing copied, not even an empty folder
        self.assertEqual(self.found(clone, ".pt") + self.found(clone, ".tmp"), [])

    def test_with_its_weights_the_run_is_copied_back(self):
        clone = self.clone("shallow", "--depth", "1")
        r, seed0 = self.kept_train(clone, "a")
        self.assertEqual((r.returncode, r.stdout, r.stderr), (0, "reused\n", ""))
        self.assertEqual(os.listdir(seed0), ["a"])
        self.assertEqual(sorted(os.listdir(os.path.join(seed0, "a"))),
                         ["best.pt", "checkpoint.json", "vae.pt"])
        with open(os.path.join(seed0, "a", "vae.pt"), "rb") as f:
            self.assertEqual(f.read(), self.weights[RUN % "a" + "/vae.pt"])


class ThisRepositoryTest(TempDirCase):
    """A shallow clone of this repository, origin unreachable, running a paper script step that
    reuses a kept run: the step stops in one line instead of reusing the run without weights.
    The working tree's scripts and manifest are copied in (they may not be committed yet)."""

    def test_a_shallow_clone_stops_a_step_that_reuses_a_kept_run(self):
        top = subprocess.run(["git", "rev-parse", "--show-toplevel"], cwd=SOURCE,
                             capture_output=True, text=True)
        if top.returncode != 0 or os.path.realpath(top.stdout.strip()) != os.path.realpath(SOURCE):
            self.skipTest("%s is not a git checkout" % SOURCE)
        if not os.path.exists(os.path.join(SOURCE, MANIFEST)):
            self.skipTest("no %s" % MANIFEST)
        clone = os.path.join(self.dir, "clone")
        git(self.dir, "clone", "-q", "--depth", "1", "--no-checkout", "file://" + SOURCE, clone)
        git(clone, "remote", "set-url", "origin", "/nonexistent")
        for relative in [os.path.join("scripts", name) for name in SCRIPTS] + [MANIFEST]:
            os.makedirs(os.path.dirname(os.path.join(clone, relative)), exist_ok=True)
            shutil.copy2(os.path.join(SOURCE, relative), os.path.join(clone, relative))
        # The first listed run whose records this clone holds and whose bytes it lacks.
        with open(os.path.join(SOURCE, MANIFEST)) as f:
            rows = [line.rstrip("\n").split("\t") for line in f if not line.startswith("#")]
        for path, _, _, blob, commit in rows:
            run = os.path.dirname(path)
            records = git(clone, "ls-tree", "--name-only", "HEAD", run + "/").split()
            lacks = subprocess.run(["git", "cat-file", "-e", blob], cwd=clone).returncode != 0
            if records and lacks:
                break
        else:
            self.skipTest("no kept run whose weights a shallow clone lacks")
        git(clone, "checkout", "-q", "HEAD", "--", run)
        keep, relative = "/".join(run.split("/")[:2]), "/".join(run.split("/")[2:])
        out = os.path.join(self.dir, "runs", os.path.basename(keep))
        script = ('set -euo pipefail\nsource scripts/paper_lib.sh\n'
                  'kept_train "$OUT/%s" --method x\necho reused\n' % relative)
        r = subprocess.run(["bash", "-c", script], cwd=clone, capture_output=True, text=True,
                           env=dict(ENV, CD="/bin/true", OUT=out, KEEP=keep), timeout=120)
        self.assertNotEqual(r.returncode, 0, r.stdout)
        self.assertEqual(r.stdout, "")
        lines = r.stderr.splitlines()
        self.assertEqual(len(lines), 1, r.stderr)
        self.assertRegex(lines[0], r"^restore_weights: %s/[^/]+\.pt: its bytes \(commit [0-9a-f]{7}\)"
                         r" are not in this clone \(shallow\); run 'git fetch --unshallow' and "
                         r"retry$" % run)
        self.assertFalse(os.path.exists(os.path.join(out, relative)))
        self.assertEqual([f for f in os.listdir(os.path.join(clone, run)) if
                          f.endswith((".pt", ".tmp"))], [])


if __name__ == "__main__":
    unittest.main()
