"""causaldrive from Python: the driving world and the MuJoCo-Image environments with the
Gymnasium interface, the benchmark runner for Python policies, and the HDF5 episode reader.

    import causaldrive
    env = causaldrive.make("town-a-regular")          # a built-in suite: its episodes in turn
    obs, info = env.reset(seed=0)
    while True:
        obs, reward, terminated, truncated, info = env.step(info["expert_action"])
        if terminated or truncated:
            break
    print(info["outcome"])
    env.close()

Everything runs in the C++ library (libsumo, MuJoCo, libtorch) behind `causaldrive._core`.
Errors are `causaldrive.Error` (a RuntimeError); bad arguments and configs are
`causaldrive.ConfigError`, malformed files `causaldrive.DataError` (both also ValueError).
The gymnasium package is not required; where it is installed, `register_gymnasium()` registers
the environments as "causaldrive/NAME".
"""

from . import _core
from ._core import (ConfigError, DataError, Error, IoError, SimError, Agent, evaluate,
                    load_episode)
from .spaces import Box, Dict, Discrete

__all__ = ["make", "evaluate", "load_episode", "Agent", "DrivingEnv", "MujocoEnv", "Box",
           "Dict", "Discrete", "Error", "ConfigError", "DataError", "IoError", "SimError",
           "suite_names", "town_names", "mujoco_env_names", "register_gymnasium"]

suite_names = _core.suite_names
town_names = _core.town_names
mujoco_env_names = _core.mujoco_env_names
agent_names = _core.agent_names


class _Env:
    """What both kinds of environment share: the Gymnasium calls over the C++ environment."""

    metadata = {"render_modes": []}
    render_mode = None

    def step(self, action):
        return self._env.step(action)

    def expert_action(self):
        """The privileged expert's action at the current state."""
        return self._env.expert_action()

    def render(self):
        return None

    def close(self):
        self._env.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class DrivingEnv(_Env):
    """The driving world as a Gymnasium-style environment (use make()).

    NAME is a built-in suite or a suite .json file (reset() runs its episodes in eval's order;
    reset(seed=s) runs episode s % episodes; reset(options={"episode": i}) runs episode i), or a
    town (a built-in town or a .net.xml network: reset(seed=s) draws the task `collect` draws
    for an episode of seed s, so the seed attribute of a collected file replays its task).

    Observation: {"bev": uint8 (C, H, W) with values 0 or 255, "speed": float32 (1,) in m/s,
    "command": int (0 follow, 1 left, 2 right, 3 straight)}; with sense.view = "camera" the
    frame is "camera": uint8 (3, H, W), the front camera's RGB (self.view names the key).
    Action: float32 (2,): throttle and brake in [0, 1]; with ego.lateral = "free" (3,): steer
    in [-1, 1] (positive to the left) follows, and info adds "lateral_error_m",
    "heading_error" (to the lane centre) and "steer_angle" (rad of road wheel).
    Reward: metres of route progress in the step, minus collision_penalty (100) on a collision.
    Secondary: this is an imitation benchmark.
    terminated: success or collision; truncated: the task's timeout.
    info: "causes" (the ground truth, by name), "expert_action" (the privileged expert's action
    at the current state, what collect records as the label; while the episode runs),
    "time_s", "progress_m", "route_length_m", "seed", "episode" (suites), and at the end
    "outcome" (success, collision, offroad, or the class of a timeout: stuck, restart_stall,
    stopped_free, blocked, slow) and "episode_record" (as in eval's
    results.json).
    """

    def __init__(self, name, config=None, settings=None):
        self._env = _core.DrivingEnv(name, config, settings)
        self.name = name
        c, h, w = self._env.channels, self._env.height, self._env.width
        self.view = self._env.view  # sense.view: the frames' key, "bev" or "camera"
        self.observation_space = Dict({
            self.view: Box(0, 255, (c, h, w), "uint8"),
            "speed": Box(0.0, float("inf"), (1,), "float32"),
            "command": Discrete(4),
        })
        self.steers = self._env.steers  # ego.lateral = "free": the action gains steer
        if self.steers:
            self.action_space = Box([0.0, 0.0, -1.0], [1.0, 1.0, 1.0], (3,), "float32")
        else:
            self.action_space = Box(0.0, 1.0, (2,), "float32")
        self.channel_names = self._env.channel_names
        self.cause_names = self._env.cause_names
        self.dt = self._env.dt
        self.episodes = self._env.episodes
        self.town = self._env.town
        self.traffic = self._env.traffic
        self.collision_penalty = self._env.collision_penalty

    def reset(self, *, seed=None, options=None):
        episode = None
        if options:
            unknown = set(options) - {"episode"}
            if unknown:
                raise ConfigError("reset: unknown option(s) %s (known: episode)" % sorted(unknown))
            episode = options.get("episode")
        return self._env.reset(seed, episode)


class MujocoEnv(_Env):
    """A MuJoCo-Image environment (halfcheetah, hopper, ant, reacher, humanoid) with Gym's
    reward, termination and episode limit (use make()).

    Observation: uint8 (3, H, W), the rendered frame (mujoco.size, default 64). Action: float32,
    one value per actuator within action_space's bounds. info: "state" (qpos then qvel, the
    privileged state: for analysis and experts, never an image policy's input), "step", "seed",
    and at the end "outcome" and "episode_return". expert_action() asks the planner expert
    (costly: it simulates its rollouts). reset(seed=s) gives collect's initial state of seed s.
    """

    def __init__(self, name, config=None, settings=None):
        self._env = _core.MujocoEnv(name, config, settings)
        self.name = name
        e = self._env
        self.observation_space = Box(0, 255, (e.channels, e.height, e.width), "uint8")
        self.action_space = Box(e.action_low, e.action_high, (len(e.action_low),), "float32")
        self.dt = e.dt
        self.max_steps = e.max_steps
        self.state_dim = e.state_dim

    def reset(self, *, seed=None, options=None):
        if options:
            raise ConfigError("reset: a MuJoCo-Image environment takes no options")
        return self._env.reset(seed)


def make(name, config=None, settings=None):
    """An environment: a built-in suite name ("town-a-regular"), a suite .json file, a town
    (built-in name or .net.xml) or a MuJoCo-Image environment ("hopper"). `config` is a TOML file
    (default: the built-in settings), `settings` a dict of config keys set over it
    ({"world.traffic": "dense"})."""
    if not isinstance(name, str):
        raise ConfigError("make: the environment name must be a string")
    if name in _core.mujoco_env_names():
        return MujocoEnv(name, config, settings)
    return DrivingEnv(name, config, settings)


def _gymnasium_space(space, gs):
    if isinstance(space, Dict):
        return gs.Dict({k: _gymnasium_space(s, gs) for k, s in space.spaces.items()})
    if isinstance(space, Discrete):
        return gs.Discrete(space.n)
    return gs.Box(low=space.low, high=space.high, shape=space.shape, dtype=space.dtype)


def register_gymnasium(gymnasium=None):
    """Registers every built-in suite, town and MuJoCo-Image environment with gymnasium as
    "causaldrive/NAME" (gymnasium must be installed; Debian does not ship it). The registered
    environments are thin gymnasium.Env wrappers with gymnasium's own spaces."""
    if gymnasium is None:
        import gymnasium
    gs = gymnasium.spaces

    class GymnasiumEnv(gymnasium.Env):
        metadata = {"render_modes": []}

        def __init__(self, name, config=None, settings=None, render_mode=None):
            self.env = make(name, config, settings)
            self.observation_space = _gymnasium_space(self.env.observation_space, gs)
            self.action_space = _gymnasium_space(self.env.action_space, gs)

        def reset(self, *, seed=None, options=None):
            super().reset(seed=seed)
            return self.env.reset(seed=seed, options=options)

        def step(self, action):
            return self.env.step(action)

        def close(self):
            self.env.close()

    ids = []
    for name in list(suite_names()) + list(town_names()) + list(mujoco_env_names()):
        ids.append("causaldrive/" + name)
        gymnasium.register(id=ids[-1], entry_point=GymnasiumEnv, kwargs={"name": name})
    return ids
