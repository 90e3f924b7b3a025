#!/usr/bin/env python3
"""The PyTorch-Python peer of `causaldrive bench train`: causaldrive's policy network (the small
CNN or ResNet-34 backbone, CILRS head: speed-input MLP, fusion layer, four command branches, and
the speed-prediction head), re-created layer by layer with PyTorch, trained with Adam 2e-4 on
random inputs already on the device, with the loss of bc-oh (L1 of the commanded branch's action +
0.05 x L1 of the predicted speed). Prints one JSON object per case; the parameter count must equal
the C++ network's (scripts/gpu_check.sh compares them).

  python3 scripts/gpu_peer.py --backbone small --device cuda --batch 128 --precision fp32
"""
import argparse
import json
import sys
import time

import torch
import torch.nn as nn

BRANCHES, MEASUREMENT = 4, 128


def conv(cin, cout, k, s, p):
    return nn.Conv2d(cin, cout, k, s, p, bias=False)


class Small(nn.Module):  # src/nn/policy_net.cpp SmallBackbone
    def __init__(self, cin, size, feat):
        super().__init__()
        self.convs = nn.Sequential(
            conv(cin, 32, 4, 4, 0), nn.BatchNorm2d(32), nn.ReLU(),
            conv(32, 64, 2, 2, 0), nn.BatchNorm2d(64), nn.ReLU(),
            conv(64, 128, 2, 2, 0), nn.BatchNorm2d(128), nn.ReLU(),
            conv(128, 32, 1, 1, 0), nn.BatchNorm2d(32), nn.ReLU())
        side = size // 16
        self.fc = nn.Linear(32 * side * side, feat)

    def forward(self, x):
        return torch.relu(self.fc(self.convs(x).flatten(1)))


class Block(nn.Module):  # BasicBlock
    def __init__(self, cin, cout, stride):
        super().__init__()
        self.conv1, self.bn1 = conv(cin, cout, 3, stride, 1), nn.BatchNorm2d(cout)
        self.conv2, self.bn2 = conv(cout, cout, 3, 1, 1), nn.BatchNorm2d(cout)
        self.down = (nn.Sequential(conv(cin, cout, 1, stride, 0), nn.BatchNorm2d(cout))
                     if stride != 1 or cin != cout else None)

    def forward(self, x):
        y = self.bn2(self.conv2(torch.relu(self.bn1(self.conv1(x)))))
        return torch.relu(y + (self.down(x) if self.down is not None else x))


class ResNet34(nn.Module):  # ResNet34Backbone
    def __init__(self, cin, feat):
        super().__init__()
        self.stem = nn.Sequential(conv(cin, 64, 7, 2, 3), nn.BatchNorm2d(64), nn.ReLU(),
                                  nn.MaxPool2d(3, 2, 1))
        layers, c = [], 64
        for stage, (n, w) in enumerate(zip((3, 4, 6, 3), (64, 128, 256, 512))):
            for b in range(n):
                layers.append(Block(c, w, 2 if b == 0 and stage > 0 else 1))
                c = w
        self.layers = nn.Sequential(*layers)
        self.proj = nn.Linear(512, feat) if feat != 512 else None

    def forward(self, x):
        f = self.layers(self.stem(x)).mean((2, 3))
        return torch.relu(self.proj(f)) if self.proj is not None else f


def mlp(widths, out, dropout):
    layers = []
    for a, b in zip(widths, widths[1:]):
        layers += [nn.Linear(a, b), nn.ReLU()] + ([nn.Dropout(dropout)] if dropout > 0 else [])
    return nn.Sequential(*layers, nn.Linear(widths[-1], out))


class Policy(nn.Module):  # PolicyNet, head "cilrs", throttle_brake, signed pedals (tanh): the default
    def __init__(self, backbone, cin, size, feat=256, actions=1, dropout=0.2):
        super().__init__()
        self.backbone = Small(cin, size, feat) if backbone == "small" else ResNet34(cin, feat)
        self.speed_head = mlp([feat, feat, feat], 1, 0.0)
        self.measurement = nn.Sequential(nn.Linear(1, MEASUREMENT), nn.ReLU(),
                                         nn.Linear(MEASUREMENT, MEASUREMENT), nn.ReLU())
        self.fusion = nn.Sequential(nn.Linear(feat + MEASUREMENT, feat), nn.ReLU())
        self.branches = nn.ModuleList(mlp([feat, feat, feat], actions, dropout)
                                      for _ in range(BRANCHES))

    def forward(self, image, speed, command):
        f = self.backbone(image)
        j = self.fusion(torch.cat([f, self.measurement(speed)], 1))
        stacked = torch.stack([b(j) for b in self.branches], 1)
        index = command.clamp(0, BRANCHES - 1).view(-1, 1, 1).expand(-1, 1, stacked.size(2))
        return torch.tanh(stacked.gather(1, index).squeeze(1)), self.speed_head(f)


def profile(dev, step, sync, steps):
    """PyTorch's profiler over a few plain steps: its table, by the device's own time, on stderr
    (a profiler that fails says so there and leaves the benchmark's figures alone)."""
    try:
        acts = [torch.profiler.ProfilerActivity.CPU] + (
            [torch.profiler.ProfilerActivity.CUDA] if dev.type == "cuda" else [])
        with torch.profiler.profile(activities=acts) as prof:
            for _ in range(steps):
                step()
            sync()
        table = None
        for key in (("self_device_time_total", "self_cuda_time_total") if dev.type == "cuda"
                    else ("self_cpu_time_total",)):
            try:
                table = prof.key_averages().table(sort_by=key, row_limit=25)
                break
            except Exception:  # the key's name differs between PyTorch versions
                continue
        print(table, file=sys.stderr, flush=True)
    except Exception as e:
        print(f"profiler failed: {e}", file=sys.stderr, flush=True)


def bench(a):
    if a.threads > 0:
        torch.set_num_threads(a.threads)
    dev = torch.device(a.device)
    torch.manual_seed(0)
    net = Policy(a.backbone, a.channels, a.size).to(dev)
    if a.channels_last:
        net = net.to(memory_format=torch.channels_last)
    opt = torch.optim.Adam(net.parameters(), 2e-4)
    B = a.batch
    image = torch.rand(B, a.channels, a.size, a.size, device=dev)
    if a.channels_last:
        image = image.contiguous(memory_format=torch.channels_last)
    speed = torch.zeros(B, 1, device=dev)
    command = torch.randint(0, 4, (B,), device=dev)
    target, speed_label = torch.rand(B, 1, device=dev), torch.rand(B, 1, device=dev) * 10

    def forward_loss():
        with torch.autocast(device_type=dev.type, dtype=torch.bfloat16,
                            enabled=a.precision == "bf16"):
            action, s = net(image, speed, command)
            return (action.float() - target).abs().mean() + 0.05 * (s.float() - speed_label).abs().mean()

    def step():
        loss = forward_loss()
        opt.zero_grad()
        loss.backward()
        opt.step()
        return loss

    sync = torch.cuda.synchronize if dev.type == "cuda" else (lambda: None)
    for _ in range(a.warmup):
        step()
    sync()
    t = time.perf_counter()
    for _ in range(a.steps):
        step()
    sync()
    dt = time.perf_counter() - t

    # Where a step's time goes, as bench train measures it: up to 10 more steps with the device
    # synchronised between the phases.
    def clock():
        sync()
        return time.perf_counter()

    phase_steps, fwd, bwd, optim = min(a.steps, 10), 0.0, 0.0, 0.0
    for _ in range(phase_steps):
        t0 = clock()
        loss = forward_loss()
        t1 = clock()
        opt.zero_grad()
        loss.backward()
        t2 = clock()
        opt.step()
        t3 = clock()
        fwd, bwd, optim = fwd + t1 - t0, bwd + t2 - t1, optim + t3 - t2
    phases = {"steps": phase_steps, "forward_ms": 1e3 * fwd / phase_steps,
              "backward_ms": 1e3 * bwd / phase_steps, "optimizer_ms": 1e3 * optim / phase_steps}
    if a.profile:
        profile(dev, step, sync, min(a.steps, 5))
    return {"phases": phases, "peer": "pytorch-python", "torch": torch.__version__,
            "backbone": a.backbone, "device": dev.type, "precision": a.precision, "batch": B, "steps": a.steps,
            "channels_last": a.channels_last, "threads": torch.get_num_threads(),
            "parameters": sum(p.numel() for p in net.parameters()),
            "samples_per_s": B * a.steps / dt if dt > 0 else 0.0}


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--backbone", choices=("small", "resnet34"), default="small")
    p.add_argument("--device", default="cuda" if torch.cuda.is_available() else "cpu")
    p.add_argument("--precision", choices=("fp32", "bf16"), default="fp32")
    p.add_argument("--batch", type=int, default=128)
    p.add_argument("--steps", type=int, default=50)
    p.add_argument("--warmup", type=int, default=5)
    p.add_argument("--threads", type=int, default=0)
    p.add_argument("--channels", type=int, default=32)
    p.add_argument("--size", type=int, default=64)
    p.add_argument("--channels-last", action="store_true")
    p.add_argument("--profile", action="store_true",
                   help="print PyTorch's profiler table of a few steps on stderr")
    print(json.dumps(bench(p.parse_args())), flush=True)


if __name__ == "__main__":
    main()
