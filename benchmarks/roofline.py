"""How close training's gradient steps run to this core's arithmetic peak: GFLOP per step, GFLOP/s, share of peak.

    python benchmarks/roofline.py [--category Teddy] [--split 0] [--set OVERRIDES ...] [--epochs 3] [--threads 1]

Builds the hierarchies of one category's training meshes as training does
(after one epoch of training, so the attention is a trained one), then times
epochs of gradient steps, once for the default settings or for each
``--set`` (the syntax of ``anseg.configs``), and counts their floating-point
work: the matrix products through torch's FLOP counter, and the flash
attention kernel, which that counter does not see on the CPU, as 7 products
of heads x tokens x tokens x head-dim per block and level (2 forward, 5
backward). Element-wise work (exponentials, GELU, normalisation, Adam) is not
counted, so the share of peak is a lower bound on how busy the core is. The
peak is one large float32 matrix product measured in the same run. A step
that runs at a share s of it cannot be made more than 1/s times faster
without changing its arithmetic.
"""

from __future__ import annotations

# first: importing stages pins the float kernels (anseg/kernels.py) before NumPy and torch load
from stages import peak_gflops

# isort: split
import argparse
import time
from dataclasses import replace

import numpy as np
import torch
from torch.utils.flop_counter import FlopCounterMode

import anseg.train as train
from anseg import datasets
from anseg.configs import configuration


def flash_flops(model, example) -> float:
    """FLOPs of the flash attention of one step (forward and backward), which the FLOP counter misses on the CPU."""
    config = model.network.config
    head_dim = config.width // config.heads
    tokens = [level["layout"].n_patches for level in example.inputs]
    return sum(7 * 2 * config.heads * t * t * head_dim * config.depth for t in tokens)


def measure(train_set, overrides: str, epochs: int) -> tuple[float, float]:
    """Seconds of one epoch of gradient steps (the median of ``epochs``) and its GFLOP."""
    config, settings = configuration("default", overrides)
    groups = train.level_zero_features(train_set, config, progress=False)
    model = train.fit(train_set, train_set[0].label_names, config, replace(settings, epochs=1, average_last=0), progress=False)
    model.network.train()
    examples = [train._examples(model, model.config, m.mesh, m.labels, g, settings, torch.device("cpu"))
                for m, g in zip(train_set, groups)]
    optimizer = torch.optim.Adam(model.network.parameters(), lr=settings.lr)

    def epoch() -> None:
        for example in examples:
            loss, _ = train._loss(model, example, settings)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()

    with FlopCounterMode(display=False) as counter:
        epoch()  # also the warm-up
    flops = counter.get_total_flops() + sum(flash_flops(model, e) for e in examples)
    seconds = []
    for _ in range(epochs):
        start = time.perf_counter()
        epoch()
        seconds.append(time.perf_counter() - start)
    return float(np.median(seconds)), flops / 1e9


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dataset", default="psb")
    parser.add_argument("--category", default="Teddy")
    parser.add_argument("--split", type=int, default=0)
    parser.add_argument("--set", action="append", default=None, help="overrides of the default settings (repeatable)")
    parser.add_argument("--epochs", type=int, default=3, help="timed epochs of each setting (default: 3)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default: 1, as the parallel runs)")
    args = parser.parse_args(argv)
    torch.set_num_threads(args.threads)
    train_set = datasets.load(args.dataset, category=args.category, split="train", split_index=args.split, progress=False)
    peak = peak_gflops(repeat=5)
    print(f"{args.dataset} {args.category} split {args.split}: {len(train_set)} training meshes; torch threads "
          f"{torch.get_num_threads()}; float32 matrix product peak {peak:.1f} GFLOP/s")
    print(f"{'settings':<40}{'s/epoch':>9}{'GFLOP/step':>12}{'GFLOP/s':>9}{'of peak':>9}")
    for overrides in args.set or [""]:
        seconds, gflop = measure(train_set, overrides, args.epochs)
        rate = gflop / seconds
        print(f"{overrides or 'default':<40}{seconds:>9.3f}{gflop / len(train_set):>12.2f}{rate:>9.1f}{rate / peak:>9.0%}")


if __name__ == "__main__":
    np.seterr(all="ignore")
    main()
