# needs: sumo
"""causaldrive.load_episode against h5py (the independent reader), and its errors."""
import glob
import os
import unittest

import h5py
import numpy as np

import causaldrive
from support import TempDirCase, cli, write_config


class LoadEpisodeTest(TempDirCase):
    def test_driving_episode_equals_h5py(self):
        config = write_config(self.dir, "regular")
        out = os.path.join(self.dir, "data")
        cli("collect", "--config", config, "--episodes", 1, "--seed", 4, "--noise", "--out", out)
        path = glob.glob(os.path.join(out, "*.h5"))[0]
        ep = causaldrive.load_episode(path)
        with h5py.File(path, "r") as f:
            for key in ("bev", "speed", "action", "command", "pose", "noise"):
                self.assertEqual(ep[key].dtype, f[key].dtype, key)
                np.testing.assert_array_equal(ep[key], f[key][()], err_msg=key)
            self.assertEqual(set(ep["causes"]), set(f["causes"]))
            for name in f["causes"]:
                np.testing.assert_array_equal(ep["causes"][name], f["causes"][name][()])
            self.assertEqual(ep["attrs"]["seed"], int(f.attrs["seed"]))
            self.assertEqual(ep["attrs"]["town"], f.attrs["town"].decode())
            self.assertEqual(ep["attrs"]["action_names"],
                             [a.decode() for a in f.attrs["action_names"]])
        # Handed over, not copied: the arrays are views on the reader's buffers.
        for key in ("bev", "speed", "action"):
            self.assertFalse(ep[key].flags.owndata, key)
            self.assertIsNotNone(ep[key].base, key)
        self.assertEqual(ep["attrs"]["domain"], "driving")

    def test_steering_data_with_lateral_augmentation(self):
        """A free-steering ego's files: steer in the action, the lane errors, and the
        augmentation's shifts (about the configured fraction of frames, within the ranges)."""
        config = write_config(self.dir, "empty")
        with open(config, "a") as f:
            f.write("[ego]\nlateral = \"free\"\n")
            f.write("[collect.augment]\nfraction = 0.5\nshift_m = 0.8\nrotate_rad = 0.1\n")
        out = os.path.join(self.dir, "steer")
        cli("collect", "--config", config, "--episodes", 1, "--out", out)
        path = glob.glob(os.path.join(out, "*.h5"))[0]
        ep = causaldrive.load_episode(path)
        self.assertEqual(ep["attrs"]["action_names"], ["throttle", "brake", "steer"])
        with h5py.File(path, "r") as f:
            for key in ("lateral_error", "heading_error", "augment"):
                np.testing.assert_array_equal(ep[key], f[key][()], err_msg=key)
        aug = ep["augment"]
        shifted = np.any(aug != 0, axis=1)
        self.assertTrue(0.35 < shifted.mean() < 0.65, shifted.mean())
        self.assertLessEqual(np.abs(aug[:, 0]).max(), 0.8)
        self.assertLessEqual(np.abs(aug[:, 1]).max(), 0.1)
        # The expert keeps its lane; the labels of frames seen from the left (shift > 0.4 m,
        # turned less than 0.02 rad) steer right of the true frames' labels on average.
        self.assertLess(np.abs(ep["lateral_error"]).max(), 1.6)
        steer = ep["action"][:, 2]
        left = shifted & (aug[:, 0] > 0.4) & (np.abs(aug[:, 1]) < 0.02)
        right = shifted & (aug[:, 0] < -0.4) & (np.abs(aug[:, 1]) < 0.02)
        self.assertTrue(left.any() and right.any())
        self.assertLess(steer[left].mean(), steer[right].mean())

    def test_side_cameras_of_the_camera_view(self):
        """collect.augment.cameras = "sides" with the front camera: augmented frames come from
        CILRS's left or right camera exactly ((+shift, +turn) or (-shift, -turn)), rendered
        from that pose (they differ from the true view's frames), and the left camera's labels
        steer right of the right camera's."""
        config = write_config(self.dir, "empty")
        with open(config, "a") as f:
            f.write("[ego]\nlateral = \"free\"\n")
            f.write("[collect.augment]\nfraction = 0.5\nshift_m = 0.6\nrotate_rad = 0.2\n"
                    "cameras = \"sides\"\n")
            f.write("[sense]\nview = \"camera\"\n[sense.camera]\nwidth = 64\nheight = 24\n")
        out = os.path.join(self.dir, "sides")
        cli("collect", "--config", config, "--episodes", 1, "--out", out)
        path = glob.glob(os.path.join(out, "*.h5"))[0]
        ep = causaldrive.load_episode(path)
        aug, frames = ep["augment"], ep["frames"]
        self.assertEqual(frames.shape[1:], (3, 24, 64))
        shifted = np.any(aug != 0, axis=1)
        self.assertTrue(0.35 < shifted.mean() < 0.65, shifted.mean())
        left = shifted & (aug[:, 0] > 0)
        right = shifted & (aug[:, 0] < 0)
        np.testing.assert_allclose(aug[left], np.tile([0.6, 0.2], (left.sum(), 1)), atol=1e-6)
        np.testing.assert_allclose(aug[right], np.tile([-0.6, -0.2], (right.sum(), 1)), atol=1e-6)
        self.assertTrue(left.any() and right.any())
        steer = ep["action"][:, 2]
        self.assertLess(steer[left].mean(), steer[right].mean())
        # A side camera's frame is not its neighbour true frame's: the view moved.
        t = int(np.flatnonzero(left[1:] & ~shifted[:-1])[0]) + 1
        self.assertFalse(np.array_equal(frames[t], frames[t - 1]))

    def test_errors(self):
        with self.assertRaises(causaldrive.IoError) as e:
            causaldrive.load_episode(os.path.join(self.dir, "missing.h5"))
        self.assertIn("missing.h5", str(e.exception))
        bad = os.path.join(self.dir, "bad.h5")
        with open(bad, "wb") as f:
            f.write(b"not an hdf5 file" * 10)
        with self.assertRaises(causaldrive.DataError) as e:
            causaldrive.load_episode(bad)
        self.assertIsInstance(e.exception, ValueError)
        # A file whose datasets disagree in length is refused, not half-read.
        broken = os.path.join(self.dir, "broken.h5")
        config = write_config(self.dir, "empty")
        out = os.path.join(self.dir, "one")
        cli("collect", "--config", config, "--episodes", 1, "--out", out)
        src = glob.glob(os.path.join(out, "*.h5"))[0]
        with h5py.File(src, "r") as f, h5py.File(broken, "w") as g:
            for key in f:
                f.copy(key, g)
            for k, v in f.attrs.items():
                g.attrs[k] = v
            del g["speed"]
            g["speed"] = f["speed"][:-1]
        with self.assertRaises(causaldrive.DataError) as e:
            causaldrive.load_episode(broken)
        self.assertIn("speed", str(e.exception))


if __name__ == "__main__":
    unittest.main()
