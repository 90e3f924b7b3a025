# needs: mujoco
"""causaldrive.make for MuJoCo-Image: spaces, Gym's loop, and `collect --env` as the oracle."""
import glob
import os
import unittest

import h5py
import numpy as np

import causaldrive
from support import TempDirCase, cli


class MujocoEnvTest(TempDirCase):
    def test_spaces_loop_and_limit(self):
        with causaldrive.make("hopper", settings={"mujoco.size": 32, "mujoco.max_steps": 20}) as env:
            self.assertEqual(env.observation_space.shape, (3, 32, 32))
            self.assertEqual(env.observation_space.dtype, np.uint8)
            self.assertEqual(env.action_space.shape, (3,))
            np.testing.assert_array_equal(env.action_space.low, [-1, -1, -1])
            np.testing.assert_array_equal(env.action_space.high, [1, 1, 1])
            obs, info = env.reset(seed=2)
            self.assertEqual(obs.shape, (3, 32, 32))
            self.assertEqual(info["state"].shape, (env.state_dim,))
            steps = 0
            while True:
                obs, reward, terminated, truncated, info = env.step(np.zeros(3))
                steps += 1
                # Gym's hopper: healthy reward 1 + forward velocity - 1e-3 |a|^2.
                self.assertTrue(np.isfinite(reward))
                if terminated or truncated:
                    break
            self.assertTrue(truncated)
            self.assertEqual(steps, 20)
            self.assertEqual(info["outcome"], "truncated")
            with self.assertRaises(causaldrive.Error):
                env.step(np.zeros(3))
            env.reset(seed=2)
            with self.assertRaises(ValueError) as e:
                env.step(np.zeros(4))
            self.assertIn("shape (4,)", str(e.exception))
        with self.assertRaises(causaldrive.ConfigError):
            causaldrive.make("cheetah")

    def test_collect_oracle(self):
        """reset(seed = a collected file's seed) gives its first state and frame, and
        expert_action() its first label; stepping with its actions (no noise: executed = label)
        reproduces its states and rewards."""
        out = os.path.join(self.dir, "data")
        cli("collect", "--env", "reacher", "--episodes", 1, "--max-steps", 4, "--planner-samples",
            4, "--planner-horizon", 2, "--size", 32, "--workers", 1, "--out", out)
        path = glob.glob(os.path.join(out, "*.h5"))[0]
        with h5py.File(path, "r") as f:
            frames, actions, rewards = f["obs"][()], f["action"][()], f["reward"][()]
            states, seed = f["state"][()], int(f.attrs["seed"])
        settings = {"mujoco.size": 32, "mujoco.planner_samples": 4, "mujoco.planner_horizon": 2}
        with causaldrive.make("reacher", settings=settings) as env:
            obs, info = env.reset(seed=seed)
            np.testing.assert_array_equal(obs, frames[0])
            np.testing.assert_array_equal(info["state"], states[0])
            np.testing.assert_array_equal(env.expert_action(), actions[0])
            # The file keeps float32 labels and collect executed them in double: later states
            # agree to float32 rounding, not bit for bit.
            for t in range(len(frames)):
                if t > 0:
                    np.testing.assert_allclose(info["state"], states[t], atol=1e-4)
                    self.assertLess(np.mean(obs != frames[t]), 0.01)
                obs, reward, terminated, truncated, info = env.step(actions[t])
                self.assertAlmostEqual(reward, float(rewards[t]), places=3)

    def test_trained_expert_matches_collect(self):
        """With mujoco.expert_policies, expert_action() is the trained policy collect labels
        with: the labels of a collected episode, step by step along its states."""
        experts = os.path.join(self.dir, "experts")
        cli("train-expert", "--env", "reacher", "--out", os.path.join(experts, "reacher.pt"),
            "--steps", 200, "--start-steps", 100, "--batch", 16, "--hidden", 8, "--eval-every",
            100, "--eval-episodes", 1)
        config = os.path.join(self.dir, "mj.toml")
        with open(config, "w") as f:
            f.write('[mujoco]\nexpert_policies = "%s"\n' % experts)
        out = os.path.join(self.dir, "data")
        cli("collect", "--env", "reacher", "--config", config, "--episodes", 1, "--max-steps", 6,
            "--size", 32, "--workers", 1, "--out", out)
        path = glob.glob(os.path.join(out, "*.h5"))[0]
        with h5py.File(path, "r") as f:
            actions, seed = f["action"][()], int(f.attrs["seed"])
            self.assertIn("sac policy", f.attrs["expert"].decode() if isinstance(
                f.attrs["expert"], bytes) else f.attrs["expert"])
        with causaldrive.make("reacher", config=config, settings={"mujoco.size": 32}) as env:
            env.reset(seed=seed)
            for t in range(len(actions)):
                label = env.expert_action()
                np.testing.assert_allclose(label, actions[t], atol=1e-5)
                env.step(actions[t])
        with causaldrive.make("hopper", config=config) as env:
            env.reset(seed=1)
            with self.assertRaises(causaldrive.DataError):
                env.expert_action()


if __name__ == "__main__":
    unittest.main()
