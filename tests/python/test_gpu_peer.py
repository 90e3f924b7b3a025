"""`causaldrive bench train` against its PyTorch-Python peer (scripts/gpu_peer.py), on the CPU:
the peer re-creates bc-oh's network layer by layer, so the two must count the same parameters for
the small CNN and for ResNet-34 (the GPU check's C++-vs-Python ratio compares the same network);
both report a positive rate, and the C++ JSON names the device and libtorch it ran with."""
import json
import os
import subprocess
import sys
import unittest

SOURCE = os.environ.get("CAUSALDRIVE_SOURCE_DIR",
                        os.path.join(os.path.dirname(__file__), "..", ".."))
BIN = os.environ.get("CAUSALDRIVE_BIN", os.path.join(SOURCE, "build", "causaldrive"))

try:
    import torch  # noqa: F401  (Debian's python3-torch: the peer needs PyTorch)
    HAVE_TORCH = True
except ImportError:
    HAVE_TORCH = False


def last_json(out):
    return json.loads(out.strip().splitlines()[-1])


@unittest.skipUnless(HAVE_TORCH, "PyTorch is not installed for this python3")
class PeerTest(unittest.TestCase):
    def run_both(self, backbone):
        args = ["--backbone", backbone, "--batch", "4", "--steps", "1", "--warmup", "0",
                "--threads", "1"]
        cpp = subprocess.run([BIN, "bench", "train", "--device", "cpu", "--json", *args],
                             capture_output=True, text=True, timeout=300)
        self.assertEqual(cpp.returncode, 0, cpp.stderr)
        peer = subprocess.run([sys.executable, os.path.join(SOURCE, "scripts", "gpu_peer.py"),
                               "--device", "cpu", *args], capture_output=True, text=True,
                              timeout=300)
        self.assertEqual(peer.returncode, 0, peer.stderr)
        return last_json(cpp.stdout), last_json(peer.stdout)

    def test_same_network_in_both(self):
        for backbone, params in (("small", 967813), ("resnet34", 22281477)):
            cpp, peer = self.run_both(backbone)
            # The count by hand for the small CNN: convs 32*32*16 + 32*64*4 + 64*128*4 + 128*32,
            # BatchNorms 2*(32+64+128+32), fc 512*256+256, the CILRS head (one signed-pedals
            # output per branch, the default) and speed head.
            self.assertEqual(cpp["parameters"], params, backbone)
            self.assertEqual(peer["parameters"], cpp["parameters"], backbone)
            self.assertGreater(cpp["samples_per_s"], 0)
            self.assertGreater(peer["samples_per_s"], 0)
            self.assertEqual(cpp["device"], "cpu")
            self.assertEqual(cpp["runtime"]["libtorch"], torch.__version__.split("a")[0].split("+")[0])
            self.assertEqual(cpp["batch"], 4)

    def test_bf16_on_the_cpu_is_one_line(self):
        r = subprocess.run([BIN, "bench", "train", "--device", "cpu", "--precision", "bf16"],
                           capture_output=True, text=True, timeout=60)
        self.assertEqual(r.returncode, 1)
        self.assertEqual(r.stderr.strip().count("\n"), 0, r.stderr)
        self.assertIn("bf16", r.stderr)


class GpuCheckAgreementTest(unittest.TestCase):
    """gpu_check.py's CPU-CUDA loss agreement: a difference over 1% is an error of the check
    (its exit code), one within it is not."""

    def load(self):
        import importlib.util
        import tempfile
        out = tempfile.mkdtemp(prefix="cdtest-gpu-check.")
        self.addCleanup(__import__("shutil").rmtree, out, True)
        os.environ["OUT"] = out
        try:
            spec = importlib.util.spec_from_file_location(
                "gpu_check", os.path.join(SOURCE, "scripts", "gpu_check.py"))
            module = importlib.util.module_from_spec(spec)
            spec.loader.exec_module(module)
        finally:
            del os.environ["OUT"]
        return module

    def test_a_disagreement_fails_the_check(self):
        check = self.load()
        far = check.agreement("small", 4096, 0.200, 0.210)  # 5% apart
        self.assertFalse(far["within"])
        self.assertAlmostEqual(far["relative_difference"], 0.05)
        self.assertEqual(len(check.report["errors"]), 1)
        self.assertIn("small", check.report["errors"][0])
        self.assertIn("5.00%", check.report["errors"][0])
        with self.assertRaises(SystemExit) as exit_:
            check.finish(0 if not check.report["errors"] else 1)
        self.assertEqual(exit_.exception.code, 1)

    def test_an_agreement_within_one_percent_passes(self):
        check = self.load()
        near = check.agreement("resnet34", 512, 0.200, 0.2009)  # 0.45% apart
        self.assertTrue(near["within"])
        self.assertEqual(check.report["errors"], [])


if __name__ == "__main__":
    unittest.main()
