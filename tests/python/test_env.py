# needs: sumo
"""causaldrive.make for driving: the Gymnasium loop, spaces, the collect oracle, errors."""
import glob
import os
import types
import unittest

import h5py
import numpy as np

import causaldrive
from support import FAST, TempDirCase, cli, write_config


class DrivingEnvTest(TempDirCase):
    def test_spaces_and_step_loop(self):
        """Route mode (ego.lateral = "route"): the action is (throttle, brake)."""
        route = dict(FAST, **{"world.traffic": "empty", "ego.lateral": "route"})
        with causaldrive.make("town-a", settings=route) as env:
            self.assertFalse(env.steers)
            bev = causaldrive._core.settings_json()["bev"]
            self.assertEqual(env.observation_space["bev"].shape,
                             (len(env.channel_names), bev["height"], bev["width"]))
            self.assertEqual(env.observation_space["bev"].dtype, np.uint8)
            self.assertEqual(env.action_space.shape, (2,))
            self.assertEqual(env.action_space.dtype, np.float32)
            self.assertEqual(list(env.action_space.low), [0, 0])
            self.assertEqual(list(env.action_space.high), [1, 1])
            obs, info = env.reset(seed=3)
            self.assertIn(obs, env.observation_space)
            self.assertEqual(obs["bev"].dtype, np.uint8)
            self.assertTrue(set(np.unique(obs["bev"])) <= {0, 255})
            self.assertEqual(obs["speed"].dtype, np.float32)
            self.assertEqual(set(info["causes"]), set(env.cause_names))
            self.assertEqual(info["expert_action"].shape, (2,))
            total, steps = 0.0, 0
            while True:
                obs, reward, terminated, truncated, info = env.step(info["expert_action"])
                self.assertIsInstance(terminated, bool)
                self.assertIsInstance(truncated, bool)
                total += reward
                steps += 1
                if terminated or truncated:
                    break
                self.assertNotIn("outcome", info)
            # The expert finishes an empty-town route; the reward is the route progress.
            self.assertEqual(info["outcome"], "success")
            self.assertTrue(terminated and not truncated)
            self.assertAlmostEqual(total, info["progress_m"], places=6)
            self.assertGreater(total, 90.0)
            record = info["episode_record"]
            self.assertEqual(record["outcome"], "success")
            self.assertAlmostEqual(record["duration_s"], steps * env.dt, places=6)
            self.assertNotIn("expert_action", info)
            with self.assertRaises(causaldrive.Error) as e:
                env.step([0.0, 1.0])
            self.assertIn("after the episode ended", str(e.exception))
            self.assertIsInstance(e.exception, RuntimeError)

    def test_collect_oracle_same_observations_and_expert_labels(self):
        """Same seed, same observations as `causaldrive collect`; info's expert_action is the
        recorded label (files read with h5py). collect.hold_s (1 s by default) holds the ego
        braked at the start, marked by the noise mask: the env is driven the same way."""
        config = write_config(self.dir, "regular")
        out = os.path.join(self.dir, "data")
        cli("collect", "--config", config, "--episodes", 1, "--seed", 11, "--out", out)
        path = sorted(glob.glob(os.path.join(out, "*.h5")))[0]
        with h5py.File(path, "r") as f:
            bev, action = f["bev"][()], f["action"][()]
            speed, command = f["speed"][()], f["command"][()]
            held = f["noise"][()]
            seed = int(f.attrs["seed"])
            outcome = f.attrs["outcome"].decode()
        env = causaldrive.make("town-a", config=config)
        try:
            obs, info = env.reset(seed=seed)
            t = 0
            while True:
                np.testing.assert_array_equal(obs["bev"], bev[t], err_msg="frame %d" % t)
                self.assertEqual(obs["speed"][0], speed[t])
                self.assertEqual(obs["command"], command[t])
                self.assertEqual(info["expert_action"].dtype, np.float64)
                np.testing.assert_array_equal(info["expert_action"].astype(np.float32), action[t])
                act = info["expert_action"].copy()
                if held[t]:
                    act[0], act[1] = 0.0, 1.0  # the hold: braked, whatever the label says
                obs, _, terminated, truncated, info = env.step(act)
                t += 1
                if terminated or truncated:
                    break
            self.assertEqual(t, len(bev))
            self.assertEqual(int(held[:10].sum()), 10)  # the first second, at dt 0.1
            self.assertEqual(int(held.sum()), 10)
            # collect names every episode that ran out of time "timeout"; eval names its class.
            ended = info["outcome"] if info["outcome"] in ("success", "collision", "offroad") \
                else "timeout"
            self.assertEqual(ended, outcome)
            # Without a seed, the n-th reset is collect's episode n of collect.seed.
            env.close()
            env = causaldrive.make("town-a", config=config, settings={"collect.seed": 11})
            obs, info = env.reset()
            np.testing.assert_array_equal(obs["bev"], bev[0])
            self.assertEqual(info["seed"], seed)
        finally:
            env.close()

    def test_camera_view_is_what_collect_records(self):
        """sense.view = "camera": the observation's frame is obs["camera"], uint8 (3, H, W) RGB,
        and it is, step by step, the "frames" dataset `collect` records for the same seed."""
        config = write_config(self.dir, "regular")
        with open(config, "a") as f:
            f.write("[sense]\nview = \"camera\"\n[sense.camera]\nwidth = 64\nheight = 24\n")
        out = os.path.join(self.dir, "data")
        cli("collect", "--config", config, "--episodes", 1, "--seed", 11, "--out", out)
        path = sorted(glob.glob(os.path.join(out, "*.h5")))[0]
        with h5py.File(path, "r") as f:
            self.assertNotIn("bev", f)
            frames, held, seed = f["frames"][()], f["noise"][()], int(f.attrs["seed"])
        self.assertEqual(frames.shape[1:], (3, 24, 64))
        with causaldrive.make("town-a", config=config) as env:
            self.assertEqual(env.view, "camera")
            self.assertEqual(env.channel_names, ["red", "green", "blue"])
            self.assertNotIn("bev", env.observation_space.spaces)
            self.assertEqual(env.observation_space["camera"].shape, (3, 24, 64))
            obs, info = env.reset(seed=seed)
            self.assertIn(obs, env.observation_space)
            self.assertGreater(len(np.unique(obs["camera"])), 16)  # shaded RGB, not 0/255
            for t in range(min(40, len(frames))):
                np.testing.assert_array_equal(obs["camera"], frames[t], err_msg="frame %d" % t)
                act = info["expert_action"].copy()
                if held[t]:
                    act[0], act[1] = 0.0, 1.0
                obs, _, terminated, truncated, info = env.step(act)
                if terminated or truncated:
                    break

    def test_free_steering(self):
        """ego.lateral = "free" (the default): the action gains steer, the expert's steer keeps
        the lane, and a hard right turn leaves the road (the episode ends as offroad)."""
        free = dict(FAST, **{"world.traffic": "empty"})
        with causaldrive.make("town-a", settings=free) as env:
            self.assertTrue(env.steers)
            self.assertEqual(env.action_space.shape, (3,))
            np.testing.assert_array_equal(env.action_space.low, [0, 0, -1])
            obs, info = env.reset(seed=3)
            self.assertEqual(info["expert_action"].shape, (3,))
            worst = 0.0
            while True:
                obs, _, terminated, truncated, info = env.step(info["expert_action"])
                worst = max(worst, abs(info["lateral_error_m"]))
                if terminated or truncated:
                    break
            self.assertEqual(info["outcome"], "success")
            self.assertLess(worst, 1.6)
            self.assertGreaterEqual(info["episode_record"]["lateral_error_m"], 0.0)
            obs, info = env.reset(seed=3)
            for _ in range(400):
                obs, _, terminated, truncated, info = env.step([0.6, 0.0, -1.0])
                if terminated or truncated:
                    break
            self.assertEqual(info["outcome"], "offroad")
            with self.assertRaises(ValueError):
                env.reset(seed=3)
                env.step([0.5, 0.0])  # two values where three are needed

    def test_suite_walk_and_seeds(self):
        with causaldrive.make("quickstart", settings={"eval.trials": 2, "world.warmup_s": 5.0}) as env:
            self.assertEqual(env.episodes, 8)
            seen = [env.reset()[1]["episode"] for _ in range(3)]
            self.assertEqual(seen, [0, 1, 2])
            obs_a, info_a = env.reset(seed=13)
            self.assertEqual(info_a["episode"], 13 % 8)
            for _ in range(5):
                obs_a, *_ = env.step([0.5, 0.0, 0.0])
            obs_b, info_b = env.reset(options={"episode": 5})
            for _ in range(5):
                obs_b, *_ = env.step([0.5, 0.0, 0.0])
            np.testing.assert_array_equal(obs_a["bev"], obs_b["bev"])
            self.assertEqual(obs_a["speed"][0], obs_b["speed"][0])
            with self.assertRaises(causaldrive.ConfigError):
                env.reset(options={"episode": 8})
            with self.assertRaises(ValueError):
                env.reset(options={"episod": 1})

    def test_errors(self):
        with self.assertRaises(causaldrive.ConfigError) as e:
            causaldrive.make("town-q")
        self.assertIn("unknown environment 'town-q'", str(e.exception))
        with self.assertRaises(ValueError) as e:
            causaldrive.make("town-a", settings={"world.trafic": "dense"})
        self.assertIn("world.trafic", str(e.exception))
        with self.assertRaises(ValueError) as e:
            causaldrive.make("town-a", settings={"world.traffic": "jammed"})
        self.assertIn("world.traffic", str(e.exception))
        with self.assertRaises(causaldrive.ConfigError):
            causaldrive.make("town-a", config=os.path.join(self.dir, "missing.toml"))
        env = causaldrive.make("town-a", settings=FAST)
        try:
            with self.assertRaises(causaldrive.Error) as e:
                env.step([0.0, 0.0, 0.0])
            self.assertIn("before reset", str(e.exception))
            env.reset(seed=1)
            for bad in ([0.5], [0.5, 0.0], [[0.5, 0.0, 0.0]], [0.1, 0.2, 0.3, 0.4], "go"):
                with self.assertRaises(ValueError) as e:
                    env.step(bad)
                self.assertIn("action", str(e.exception))
            with self.assertRaises(ValueError):
                env.step([float("nan"), 0.0, 0.0])
            # One libsumo simulation per process: a second world is refused while one is open.
            with self.assertRaises(causaldrive.Error) as e:
                causaldrive.make("town-b")
            self.assertIn("close()", str(e.exception))
            env.step(np.array([0.0, 1.0, 0.0], dtype=np.float32))  # still usable
        finally:
            env.close()
        with self.assertRaises(causaldrive.Error):
            env.reset()
        causaldrive.make("town-b", settings={"world.warmup_s": 1.0}).close()  # free again

    def test_gymnasium_registration(self):
        """register_gymnasium against a stand-in with gymnasium's registration surface
        (gymnasium itself is not a Debian package): every environment is registered, and the
        wrapper is a gymnasium.Env with gymnasium's spaces that runs the same episode."""
        registry = {}

        class Env:
            def reset(self, *, seed=None, options=None):
                self.seeded = seed

        class Space:
            def __init__(self, *args, **kwargs):
                self.args, self.kwargs = args, kwargs

        gym = types.SimpleNamespace(
            Env=Env, register=lambda id, entry_point, kwargs: registry.update({id: (entry_point, kwargs)}),
            spaces=types.SimpleNamespace(Box=type("Box", (Space,), {}),
                                         Dict=type("Dict", (Space,), {}),
                                         Discrete=type("Discrete", (Space,), {})))
        ids = causaldrive.register_gymnasium(gym)
        self.assertEqual(set(ids), set(registry))
        self.assertIn("causaldrive/town-a-regular", registry)
        self.assertIn("causaldrive/hopper", registry)
        self.assertIn("causaldrive/town-b", registry)
        entry, kwargs = registry["causaldrive/town-a"]
        env = entry(settings=FAST, **kwargs)
        try:
            self.assertIsInstance(env, Env)
            self.assertEqual(env.action_space.kwargs["shape"], (3,))  # the default ego steers
            self.assertEqual(set(env.observation_space.args[0]), {"bev", "speed", "command"})
            obs, info = env.reset(seed=3)
            self.assertEqual(env.seeded, 3)
            out = env.step(info["expert_action"])
            self.assertEqual(len(out), 5)
        finally:
            env.close()


if __name__ == "__main__":
    unittest.main()
