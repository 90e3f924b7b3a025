#!/usr/bin/env python3
"""Steps/s of a Python loop driving the world through causaldrive.make (step with the expert's
action from info, as a DAgger or imitation loop in Python does) against the C++ closed loop of
the expert (the benchmark runner's loop, as `causaldrive bench eval` times it), in one process,
interleaved episode by episode on the same tasks.

    PYTHONPATH=build/python python3 scripts/bench_python.py [--suite town-a-regular] [--episodes 6] [--json]
"""
import argparse
import json
import statistics
import time

import causaldrive


def python_episode(env, episode):
    obs, info = env.reset(options={"episode": episode})
    steps = 0
    t0 = time.perf_counter()
    while True:
        obs, reward, terminated, truncated, info = env.step(info["expert_action"])
        steps += 1
        if terminated or truncated:
            break
    return steps, time.perf_counter() - t0, info["outcome"]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--suite", default="town-a-regular")
    ap.add_argument("--episodes", type=int, default=6)
    ap.add_argument("--config", default=None)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    with causaldrive.make(a.suite, config=a.config) as env:
        n = min(a.episodes, env.episodes)
        py_steps = py_s = cpp_steps = cpp_s = 0
        ratios = []
        for i in range(n):
            c = env._env.cpp_episode(i, "expert")
            s, t, _ = python_episode(env, i)
            cpp_steps += c["steps"]
            cpp_s += c["seconds"]
            py_steps += s
            py_s += t
            ratios.append((s / t) / (c["steps"] / c["seconds"]))
    out = {"suite": a.suite, "episodes": n, "python_steps": py_steps,
           "python_steps_per_s": py_steps / py_s, "cpp_steps": cpp_steps,
           "cpp_steps_per_s": cpp_steps / cpp_s, "ratio": (py_steps / py_s) / (cpp_steps / cpp_s),
           "ratio_median_over_episodes": statistics.median(ratios)}
    if a.json:
        print(json.dumps(out))
    else:
        print("closed loop of the expert on %s, %d episodes, interleaved (one process)" % (a.suite, n))
        print("  python loop (env.step)  %8.0f steps/s  (%d steps)" % (out["python_steps_per_s"], py_steps))
        print("  C++ loop (run_episode)  %8.0f steps/s  (%d steps)" % (out["cpp_steps_per_s"], cpp_steps))
        print("  ratio %.2f (median over episodes %.2f)" % (out["ratio"], out["ratio_median_over_episodes"]))


if __name__ == "__main__":
    main()
