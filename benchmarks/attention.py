"""Time of the supervised attention mass, forward and backward: chunked (anseg) against autograd over the dense matrix.

    python benchmarks/attention.py [--tokens 500 1000 2000 4000] [--heads 4] [--dim 16] [--threads 1] [--repeat 5]

Training supervises each face's attention through the mass every token
receives, the column mean of softmax(q k^T / sqrt(d)) over heads and queries.
``anseg.model.received_attention`` forms it a chunk of queries at a time, in
its backward pass too; the reference below lets autograd go through the whole
(heads x T x T) matrix, as training did before. Level 0 of a 25K-face PSB mesh
is about 1,700 tokens.

Beside the times, how close each pass runs to this core's arithmetic peak:
the GFLOP/s of its matrix products (multiply-adds counted twice; the
exponentials and other element-wise work not counted) against those of one
large float32 matrix product measured in the same run. The chunked mass does
4 products of H x T x T x d forward and backward (scores twice, then the
gradients of q and k); one block's attention through
``scaled_dot_product_attention`` (flash, as the model calls it) does 7 (2
forward; the scores again and 4 gradient products backward).
"""

from __future__ import annotations

# first: importing stages pins the float kernels (anseg/kernels.py) before NumPy and torch load
from stages import peak_gflops

# isort: split
import argparse
import math
import time

import torch

from anseg.model import received_attention


def dense_received_attention(q: torch.Tensor, k: torch.Tensor) -> torch.Tensor:
    return torch.softmax(q @ k.transpose(1, 2) / math.sqrt(q.shape[-1]), dim=-1).mean(dim=(0, 1))


def seconds_per_call(mass_of, q, k, upstream, repeat: int) -> float:
    """Median seconds of one forward and backward pass."""
    times = []
    for _ in range(repeat + 1):  # the first call warms up and is dropped
        start = time.perf_counter()
        torch.autograd.grad(mass_of(q, k), (q, k), upstream)
        times.append(time.perf_counter() - start)
    return sorted(times[1:])[repeat // 2]


def sdpa_block(q: torch.Tensor, k: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """One block's attention as the model calls it: a leading batch axis of 1 keeps the CPU flash kernel."""
    return torch.nn.functional.scaled_dot_product_attention(q.unsqueeze(0), k.unsqueeze(0), v.unsqueeze(0))[0]


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tokens", type=int, nargs="+", default=[500, 1000, 2000, 4000])
    parser.add_argument("--heads", type=int, default=4)
    parser.add_argument("--dim", type=int, default=16, help="per-head dimension (width 64 / 4 heads)")
    parser.add_argument("--threads", type=int, default=1, help="torch threads (default: 1, as the parallel runs)")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args(argv)
    torch.set_num_threads(args.threads)
    generator = torch.Generator().manual_seed(0)
    peak = peak_gflops(args.repeat)
    print(f"heads {args.heads}, dim {args.dim}, torch threads {torch.get_num_threads()}; "
          f"milliseconds per forward + backward (median); float32 matrix product peak {peak:.1f} GFLOP/s")
    print(f"{'tokens':>8}{'dense autograd':>16}{'chunked':>10}{'speed-up':>10}{'GFLOP/s':>9}{'of peak':>9}"
          f"{'sdpa block':>12}{'GFLOP/s':>9}{'of peak':>9}")
    for n in args.tokens:
        q, k, v = (torch.randn(args.heads, n, args.dim, generator=generator, requires_grad=True) for _ in range(3))
        upstream = torch.randn(n, generator=generator)
        dense = seconds_per_call(dense_received_attention, q, k, upstream, args.repeat)
        chunked = seconds_per_call(received_attention, q, k, upstream, args.repeat)
        block = seconds_per_call(lambda q, k: sdpa_block(q, k, v), q, k, torch.randn(args.heads, n, args.dim), args.repeat)
        product = 2 * args.heads * n * n * args.dim / 1e9  # GFLOP of one H x T x T x d product
        print(f"{n:>8}{1000 * dense:>16.1f}{1000 * chunked:>10.1f}{dense / chunked:>9.1f}x"
              f"{4 * product / chunked:>9.1f}{4 * product / chunked / peak:>9.0%}"
              f"{1000 * block:>12.1f}{7 * product / block:>9.1f}{7 * product / block / peak:>9.0%}")


if __name__ == "__main__":
    main()
