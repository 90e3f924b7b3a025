#!/usr/bin/python3
"""How much of an expert's labels a state-based policy can learn: a MuJoCo-Image data folder's
(state, action) rows, an MLP (2 x 256, ReLU) fitted on all episodes but the last two and scored
on those (R^2 over every action component), and the lag-1 linear R^2 of the labels in time.

    scripts/label_predictability.py runs/mujoco_paper/data/halfcheetah [--epochs 60] [--seed 0]

A validation R^2 near or below 0 means the labels are not a function of the state: no image
policy can learn them either (the frames show less than the state). Needs python3-h5py and
python3-torch (installed by the setup step). The root's x position is left out (it only grows).
"""
import argparse
import glob
import os

import h5py
import numpy as np
import torch


def r2(pred, target):
    return 1.0 - float(((pred - target) ** 2).sum()) / float(((target - target.mean(0)) ** 2).sum())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("folder")
    ap.add_argument("--epochs", type=int, default=60)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    files = sorted(glob.glob(os.path.join(args.folder, "episode_*.h5")))
    if len(files) < 3:
        raise SystemExit(f"error: {args.folder} holds {len(files)} episode files; need at least 3")
    states, actions = [], []
    for f in files:
        with h5py.File(f, "r") as h:
            states.append(h["state"][:, 1:].astype(np.float32))
            actions.append(h["action"][:].astype(np.float32))
    torch.set_num_threads(1)
    torch.manual_seed(args.seed)
    xs, ys = np.concatenate(states[:-2]), np.concatenate(actions[:-2])
    mu, sd = xs.mean(0), xs.std(0) + 1e-6
    x = torch.tensor((xs - mu) / sd)
    y = torch.tensor(ys)
    xv = torch.tensor((np.concatenate(states[-2:]) - mu) / sd)
    yv = torch.tensor(np.concatenate(actions[-2:]))
    net = torch.nn.Sequential(torch.nn.Linear(x.shape[1], 256), torch.nn.ReLU(),
                              torch.nn.Linear(256, 256), torch.nn.ReLU(),
                              torch.nn.Linear(256, y.shape[1]))
    opt = torch.optim.Adam(net.parameters(), 1e-3)
    for _ in range(args.epochs):
        perm = torch.randperm(len(x))
        for i in range(0, len(x), 128):
            b = perm[i:i + 128]
            loss = ((net(x[b]) - y[b]) ** 2).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
    prev = np.concatenate([a[:-1] for a in actions])
    nxt = np.concatenate([a[1:] for a in actions])
    design = np.hstack([prev, np.ones((len(prev), 1), np.float32)])
    w = np.linalg.lstsq(design, nxt, rcond=None)[0]
    with torch.no_grad():
        print(f"{args.folder}: {len(files)} episodes, {len(x) + len(xv)} rows; state -> action "
              f"MLP R2 train {r2(net(x), y):.3f}, held-out episodes {r2(net(xv), yv):.3f}; "
              f"labels' lag-1 R2 {r2(design @ w, nxt):.3f}")


if __name__ == "__main__":
    main()
