"""DiffusionNet (Sharp et al. 2022) rerun on this project's PSB data, split and metric.

What it measures: for each PSB category, DiffusionNet is trained on the
split's training meshes and scored on its test meshes with the project's own
Eq. 5 (``anseg.metrics.pooled_accuracy``: unit area, the primary figure; raw
area; plain faces). Data and metric come from ``anseg``; the network, its
operators and its settings come from the authors' public code, which this
repository does not copy. The settings are those of their segmentation
experiment (``experiments/human_segmentation_original``): 16 heat kernel
signature features (``compute_hks_autoscale``) or xyz positions with random
rotations, 128 eigenpairs, 4 blocks of width 128 with dropout, outputs
averaged to the faces, Adam at lr 1e-3 halved every 50 epochs, 200 epochs,
one mesh per step, the last model scored.

One run each, one seed: a rerun with another seed or device is not expected
to match to the last digit. On one CPU thread a PSB category takes 20 to 90
minutes (20 meshes, 200 epochs); the human set (381 training meshes of about
1,500 faces) has not been timed here.

Usage::

    git clone https://github.com/nmwsharp/diffusion-net
    pip install robust_laplacian potpourri3d   # what diffusion_net imports beyond torch, scipy, scikit-learn
    ANSEG_DATA=/path/to/datasets python benchmarks/diffusionnet.py --diffusion-net diffusion-net \\
        [--dataset psb|human_seg] [--category Hand Teddy] [--split 0] [--epochs 200] [--input hks|xyz] \\
        [--device auto] [--seed 0] [--op-cache DIR] [--json FILE] [--checkpoint DIR]

``--json FILE`` keeps the figures with the settings, the machine's record
(CPU model, kernels, releases, revision) and the clone's commit. The tables
show a peer's number only where such a file is stored under
``results/peers/`` (``anseg.study.peers`` reads every file there); name it
``diffusionnet_<input>_<category or human_seg>_split<split>_<device>.json``.

``--checkpoint DIR`` writes the training's state there after every epoch
(weights, optimiser, schedule, random generators, seconds spent), and a run
that finds the state of the same settings goes on from it: a stopped run
resumes where it stopped and ends with the weights the uninterrupted run
would have; its ``train_s`` counts the seconds of every session.
"""

from __future__ import annotations

import anseg  # noqa: F401  first: importing anseg pins the float kernels before NumPy and torch load

# isort: split
import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from anseg import datasets
from anseg.metrics import pooled_accuracy

# The authors' settings for segmentation (human_segmentation_original.py).
K_EIG = 128
N_HKS = 16
WIDTH, BLOCKS = 128, 4
LR, DECAY_EVERY, DECAY_RATE = 1e-3, 50, 0.5
EPOCHS = 200


def import_diffusion_net(path: Path):
    """``diffusion_net`` from a clone of the authors' repository, or a one-line reason why not."""
    src = path / "src"
    if not (src / "diffusion_net" / "__init__.py").is_file():
        sys.exit(f"error: no src/diffusion_net under {path}; clone https://github.com/nmwsharp/diffusion-net and pass its folder")
    sys.path.insert(0, str(src))
    try:
        import diffusion_net
    except ImportError as error:
        sys.exit(f"error: cannot import diffusion_net from {src} ({error}); pip install robust_laplacian potpourri3d")
    return diffusion_net


class Prepared:
    """One mesh as DiffusionNet takes it: its operators, input features and face labels, on the device."""

    def __init__(self, dn, item, args, device):
        import torch

        verts = dn.geometry.normalize_positions(torch.tensor(item.mesh.vertices, dtype=torch.float32))
        faces = torch.tensor(item.mesh.faces, dtype=torch.int64)
        _frames, mass, L, evals, evecs, grad_x, grad_y = dn.geometry.get_operators(
            verts, faces, k_eig=K_EIG, op_cache_dir=args.op_cache)
        self.verts, self.faces, self.mass, self.L = verts.to(device), faces.to(device), mass.to(device), L.to(device)
        self.evals, self.evecs, self.grad_x, self.grad_y = (evals.to(device), evecs.to(device),
                                                            grad_x.to(device), grad_y.to(device))
        # the HKS depends on the mesh alone: computed once, not at every step as the authors' loop does
        self.hks = dn.geometry.compute_hks_autoscale(self.evals, self.evecs, N_HKS) if args.input == "hks" else None
        self.labels = torch.tensor(item.labels, device=device)

    def forward(self, dn, model, rotation=None):
        """Per-face log-probabilities; ``rotation`` (a numpy RandomState) turns xyz inputs at random."""
        features = self.hks
        if features is None:
            features = self.verts if rotation is None else dn.utils.random_rotate_points(self.verts, rotation)
        return model(features, self.mass, L=self.L, evals=self.evals, evecs=self.evecs,
                     gradX=self.grad_x, gradY=self.grad_y, faces=self.faces)


class Checkpoint:
    """A training's state after each epoch in ``--checkpoint``'s folder, one file per data set, category and settings.

    Holds what the next epoch depends on: the weights, the optimiser and its
    schedule, torch's random generator (the epoch's order and the dropout)
    and the xyz rotations' generator. Written to a temporary file, then
    renamed, so a run stopped while writing leaves the last whole state.
    """

    def __init__(self, args, category, model, optimizer, scheduler, rotation):
        self.settings = {"dataset": args.dataset, "category": category, "split": args.split, "epochs": args.epochs,
                         "input": args.input, "seed": args.seed}
        name = f"diffusionnet_{args.input}_{category or args.dataset}_split{args.split}_seed{args.seed}.ckpt"
        self.path = Path(args.checkpoint) / name if args.checkpoint else None
        self.parts = {"model": model, "optimizer": optimizer, "scheduler": scheduler}
        self.rotation = rotation

    def resume(self) -> tuple[int, float]:
        """The epoch to start from and the seconds spent before it: (0, 0.0) without a state of these settings."""
        import torch

        if self.path is None or not self.path.is_file():
            return 0, 0.0
        state = torch.load(self.path, weights_only=False)
        if state["settings"] != self.settings:
            return 0, 0.0
        for key, part in self.parts.items():
            part.load_state_dict(state[key])
        torch.set_rng_state(state["torch_rng"])
        self.rotation.set_state(state["rotation"])
        print(f"resumed at epoch {state['epoch']} from {self.path}", flush=True)
        return state["epoch"], state["train_s"]

    def save(self, epoch: int, train_s: float) -> None:
        import torch

        if self.path is None:
            return
        self.path.parent.mkdir(parents=True, exist_ok=True)
        partial = self.path.with_suffix(".partial")
        torch.save({"settings": self.settings, "epoch": epoch, "train_s": train_s, "torch_rng": torch.get_rng_state(),
                    "rotation": self.rotation.get_state(), **{k: p.state_dict() for k, p in self.parts.items()}}, partial)
        partial.replace(self.path)


def run_category(dn, category: str | None, args, device) -> dict:
    """Train on the split's training meshes, score the test meshes; the figures of one PSB category, or of the
    human set (``category`` None, ``--dataset human_seg``: its one split, the paper's)."""
    import torch
    from tqdm.auto import tqdm

    # reseeded per category, so a category's result does not depend on which ran before it
    torch.manual_seed(args.seed)
    rotation = np.random.RandomState(args.seed)
    start = time.perf_counter()
    train = [Prepared(dn, item, args, device)
             for item in datasets.load(args.dataset, category=category, split="train", split_index=args.split,
                                       progress=False)]
    test_items = datasets.load(args.dataset, category=category, split="test", split_index=args.split, progress=False)
    test = [Prepared(dn, item, args, device) for item in test_items]
    operator_s = time.perf_counter() - start

    model = dn.layers.DiffusionNet(C_in=N_HKS if args.input == "hks" else 3, C_out=len(test_items[0].label_names),
                                   C_width=WIDTH, N_block=BLOCKS, outputs_at="faces", dropout=True,
                                   last_activation=lambda x: torch.nn.functional.log_softmax(x, dim=-1)).to(device)
    optimizer = torch.optim.Adam(model.parameters(), lr=LR)
    scheduler = torch.optim.lr_scheduler.StepLR(optimizer, step_size=DECAY_EVERY, gamma=DECAY_RATE)
    state = Checkpoint(args, category, model, optimizer, scheduler, rotation)
    first, spent = state.resume()
    start = time.perf_counter()
    model.train()
    for epoch in tqdm(range(first, args.epochs), desc=f"DiffusionNet {category or args.dataset}", unit="epoch",
                      initial=first, total=args.epochs):
        for i in torch.randperm(len(train)).tolist():
            loss = torch.nn.functional.nll_loss(train[i].forward(dn, model, rotation if args.input == "xyz" else None),
                                                train[i].labels)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
        scheduler.step()
        state.save(epoch + 1, spent + time.perf_counter() - start)
    train_s = spent + time.perf_counter() - start

    model.eval()
    with torch.no_grad():
        predicted = [mesh.forward(dn, model).argmax(dim=1).cpu().numpy() for mesh in test]
    scores = pooled_accuracy(predicted, [item.labels for item in test_items], [item.mesh.face_areas for item in test_items])
    return {"category": category or args.dataset, **{key: 100 * value for key, value in scores.items()},
            "train_s": train_s, "operator_s": operator_s, **({"resumed_at_epoch": first} if first else {})}


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--diffusion-net", type=Path, required=True, metavar="PATH",
                        help="a clone of https://github.com/nmwsharp/diffusion-net")
    parser.add_argument("--dataset", default="psb", choices=["psb", "human_seg"],
                        help="PSB (by category) or the human set as MeshCNN distributes it (default: psb)")
    parser.add_argument("--category", nargs="+", action="extend", choices=datasets.PSB_CATEGORIES,
                        help="PSB categories (default: all 16)")
    parser.add_argument("--split", type=int, default=0, choices=range(datasets.PSB_SPLIT_COUNT),
                        help="PSB's fixed split (default: 0); the human set has one split")
    parser.add_argument("--epochs", type=int, default=EPOCHS, help=f"default: {EPOCHS}, the authors' setting")
    parser.add_argument("--input", default="hks", choices=["hks", "xyz"])
    parser.add_argument("--device", default="auto", choices=["auto", "cpu", "cuda"])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--op-cache", help="folder where diffusion_net keeps each mesh's operators between runs (default: none)")
    parser.add_argument("--json", type=Path, metavar="FILE", help="also write the figures to FILE")
    parser.add_argument("--checkpoint", type=Path, metavar="DIR",
                        help="keep each training's state here after every epoch, and resume from it (default: none)")
    args = parser.parse_args(argv)
    if args.dataset == "human_seg" and (args.category or args.split):
        parser.error("the human set has no categories and one split: --category and --split are for PSB")

    dn = import_diffusion_net(args.diffusion_net)
    import torch

    device = torch.device("cuda" if args.device == "auto" and torch.cuda.is_available() else
                          "cpu" if args.device == "auto" else args.device)
    rows = []
    data = f"PSB split {args.split}" if args.dataset == "psb" else "the human set"
    print(f"DiffusionNet ({args.input}), {data}, {args.epochs} epochs, {device}; Eq. 5 accuracy in %")
    for category in (args.category or datasets.PSB_CATEGORIES) if args.dataset == "psb" else [None]:
        try:
            row = run_category(dn, category, args, device)
        except datasets.DatasetError as error:
            sys.exit(f"error: {error}")
        rows.append(row)
        print(f"{row['category']:10s} unit area {row['unit_area']:6.2f}  raw area {row['raw_area']:6.2f}  "
              f"faces {row['faces']:6.2f}  train {row['train_s']:7.1f} s  (operators {row['operator_s']:.1f} s)",
              flush=True)

    mean = float(np.mean([row["unit_area"] for row in rows]))
    print(f"{'mean':10s} unit area {mean:6.2f}")
    if args.json:
        from anseg.study.store import code_revision, environment

        authors = code_revision(args.diffusion_net)["code_revision"]  # the clone's commit: which DiffusionNet ran
        args.json.write_text(json.dumps({"settings": vars(args), "categories": rows, "mean": mean,
                                         "diffusion_net_revision": authors,
                                         "environment": environment()}, indent=1, default=str))


if __name__ == "__main__":
    main()
