"""The attention network: per-face embedding, patch tokens, a transformer, face attention and class logits.

One mesh per call. Faces come grouped into patches (the tokens) by a :class:`~anseg.cluster.PatchLayout`
computed elsewhere, a ``(n_patches, patch_size)`` grid whose unused slots (padding) only the share's
softmax sees (as -inf). Data flow (W = ``width``, T tokens, P slots per token, F faces, C classes)::

    x (F, in) --embed MLP--> e (F, W)  [--diffusion blocks--> e (F, W), optional]
    per-face score s = w.e; share = softmax of s over the patch's faces
    token = sum of share * e over its faces                       (T, W)
    depth x pre-norm block: h += Attn(LN h); h += MLP(LN h)       (T, W)
    logits = head([e, LN(h)[patch]])                              (F, C)
    attention = received mass of the token (last block) x share x F  (F,)
    context = LN(h), per token (the face's token is patch), what a finer level may read  (T, W)

Attention is Eq. 1-4 of the paper, through ``scaled_dot_product_attention``, so A is never stored
whole (memory O(T)). A face's attention is the mass its token *receives* in the last block (mean
over queries and heads, in chunks: :func:`received_attention`), spread over the token's faces by the
learned share that pools them, which gives the share a gradient from the class loss (the collapse
is not differentiable); times F, so its mean over a mesh's faces is exactly 1 and compares across
meshes. It has no gradient unless ``attention_grad=True``, so that training may supervise it.
**Depth 0** is the paper's "without downsampling" control (Table IV): a per-face classifier (logits =
head(e)), flat attention. Weights start from the paper's "N(0, 0.001)", read as variance. Switches: :class:`ModelConfig`.
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import NamedTuple

import torch
import torch.nn.functional as F
from torch import nn

from anseg.cache import atomic_write
from anseg.cluster import PatchLayout

# Scores in one chunk of received_attention: 4 MiB of float32, small enough to stay near the core
# between the passes over it; larger chunks were slower and smaller ones no faster (docs/decisions.md).
_CHUNK_ELEMENTS = 1 << 20
# Switches retired after validation (docs/decisions.md), each with the value that meant "off": a model file or a
# stored setting that holds a retired switch at that value reads as today's model; any other value is refused.
RETIRED = {"position_frequencies": 0, "position_pairs": 0, "heat_bias_pairs": 0,
           "coarse_levels": 0, "coarse_context": False}


@dataclass
class ModelConfig:
    """Hyper-parameters of :class:`AttentionSegmenter`; every switch below is off by default.

    ``detach_share`` cuts the attention supervision's direct path through the
    share (the factor that spreads a token's mass over its faces), so that the
    boundary signal goes to the queries and keys; the share still shapes the
    tokens they are made from.

    ``diffusion_blocks``: learned heat diffusion on the faces after the
    embedding, e += MLP([e, D_t e]) with D_t e = Phi exp(-Lambda t) Phi^T M e
    through the mesh's Laplacian eigenbasis (:class:`SpectralInput`, carried
    to coarse levels by the pipeline), one learned time per channel
    (DiffusionNet's spectral diffusion, Sharp et al. 2022), unchanged by the
    eigenvectors' signs and by rotations inside an eigenspace of equal
    eigenvalues. ``diffusion_gradients`` adds DiffusionNet's gradient
    features to every such block: the diffused channels' gradients along
    the surface (:func:`anseg.geometry.gradient.face_gradient`, in each
    face's frame), each dotted with a learned rotation-and-scaling of all of
    them (complex-linear, as DiffusionNet has it), through tanh; unchanged
    by the choice of each face's frame. Switches that validation rejected are retired
    (:data:`RETIRED`); their runs replay at their own revision.
    """

    in_features: int
    n_classes: int
    width: int = 64
    depth: int = 2
    heads: int = 4
    patch_size: int = 16
    dropout: float = 0.0
    init_std: float = math.sqrt(0.001)  # the paper's N(0, 0.001), read as variance
    detach_share: bool = False  # the attention loss reaches the share only through the tokens (class docstring)
    embed_norm: bool = False  # LayerNorm on each face's embedding: bounds what a far-off input can do downstream
    spectral_pairs: int = 0  # eigenpairs of the SpectralInput the model reads (0: none)
    diffusion_blocks: int = 0  # learned diffusion blocks on the faces (class docstring)
    diffusion_gradients: bool = False  # their gradient features (class docstring)

    def __post_init__(self) -> None:
        for name in ("in_features", "n_classes", "width", "heads", "patch_size"):
            if getattr(self, name) < 1:
                raise ValueError(f"ModelConfig.{name} must be >= 1, got {getattr(self, name)}")
        if self.depth < 0:
            raise ValueError(f"ModelConfig.depth must be >= 0, got {self.depth}")
        if self.width % self.heads:
            raise ValueError(f"ModelConfig.width ({self.width}) must be divisible by heads ({self.heads})")
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"ModelConfig.dropout must be in [0, 1), got {self.dropout}")
        if self.init_std <= 0:
            raise ValueError(f"ModelConfig.init_std must be > 0, got {self.init_std}")
        if self.diffusion_blocks < 0:
            raise ValueError(f"ModelConfig.diffusion_blocks must be >= 0, got {self.diffusion_blocks}")
        if self.diffusion_blocks and not self.spectral_pairs:
            raise ValueError("ModelConfig.diffusion_blocks need a spectrum to read (spectral_pairs > 0)")
        if self.diffusion_gradients and not self.diffusion_blocks:
            raise ValueError("ModelConfig.diffusion_gradients need diffusion blocks to add them to")


class SpectralInput(NamedTuple):
    """One level's eigenbasis: ``basis`` (F, k) per face, ``values`` (k,) eigenvalues, ``mass`` (F,) face areas summing to 1,
    and, for a model with ``diffusion_gradients``, ``gradient`` (2F, F) sparse (:func:`anseg.geometry.gradient.face_gradient`).

    On a coarse level the basis is the area-weighted mean of the input faces'
    (:func:`anseg.pipeline.build_levels`), still orthonormal under the
    coarse faces' areas up to the collapse's error.
    """

    basis: torch.Tensor
    values: torch.Tensor
    mass: torch.Tensor
    gradient: torch.Tensor | None = None


class Output(NamedTuple):
    """Per-face class logits (F, C) and attention values (F,) with mean 1 (None when not asked for)."""

    logits: torch.Tensor
    attention: torch.Tensor | None


def received_attention(q: torch.Tensor, k: torch.Tensor, chunk: int | None = None, scale: float | None = None) -> torch.Tensor:
    """Attention mass each key receives: softmax(scale q k^T) averaged over queries and heads (scale 1/sqrt(d) by default).

    ``q``, ``k``: (H, T, d). Returns (T,), summing to 1, differentiable in ``q`` and
    ``k``. Scores are formed ``chunk`` queries at a time (default: as many as fit in
    2^20 scores), forward and backward, so memory is O(H x chunk x T) and the
    (T x T) matrix never exists whole.
    """
    if q.dim() != 3 or q.shape != k.shape:
        raise ValueError(f"q and k must both be (heads, tokens, dim), got {tuple(q.shape)} and {tuple(k.shape)}")
    heads, n_tokens, _ = q.shape
    if chunk is None:
        chunk = max(1, _CHUNK_ELEMENTS // (heads * n_tokens))
    if chunk < 1:
        raise ValueError(f"chunk must be >= 1, got {chunk}")
    return _ReceivedAttention.apply(q, k, chunk, 1.0 / math.sqrt(q.shape[-1]) if scale is None else scale)


class _ReceivedAttention(torch.autograd.Function):
    """received_attention with a hand-written backward over the same chunks.

    Autograd through the dense matrix made ~10 passes over H x T x T floats per
    step and dominated training time; here each chunk is recomputed from the
    saved log-sum-exp of its rows and stays in cache. With A = softmax(S) and
    g the incoming gradient of the mass, dL/dS_hij = A_hij (g_j - sum_k A_hik g_k) / (H T).
    """

    @staticmethod
    def forward(ctx, q, k, chunk, scale):
        heads, n_tokens, _ = q.shape
        queries, keys = q * scale, k.transpose(1, 2)
        mass = q.new_zeros(1, n_tokens)
        log_sum_exp = q.new_empty(heads, n_tokens, 1)
        for start in range(0, n_tokens, chunk):
            # Softmax in place, its row normalisation folded into the column sum as one
            # (1 x chunk) @ (chunk x T) product per head: no second copy of the chunk.
            weights = torch.matmul(queries[:, start : start + chunk], keys)
            row_max = weights.amax(dim=-1, keepdim=True)
            row_sums = weights.sub_(row_max).exp_().sum(dim=-1, keepdim=True)
            log_sum_exp[:, start : start + chunk] = row_max + row_sums.log()
            mass += torch.matmul(row_sums.reciprocal_().transpose(1, 2), weights).sum(dim=0)
        ctx.save_for_backward(q, k, log_sum_exp)
        ctx.chunk, ctx.scale = chunk, scale
        return mass[0] / (heads * n_tokens)

    @staticmethod
    def backward(ctx, grad_mass):
        q, k, log_sum_exp = ctx.saved_tensors
        heads, n_tokens, _ = q.shape
        scale = ctx.scale
        queries, keys = q * scale, k.transpose(1, 2)
        g = grad_mass / (heads * n_tokens)
        grad_q, grad_k = torch.empty_like(q), torch.zeros_like(k)
        for start in range(0, n_tokens, ctx.chunk):
            stop = min(start + ctx.chunk, n_tokens)
            weights = torch.matmul(queries[:, start:stop], keys).sub_(log_sum_exp[:, start:stop]).exp_()
            row_dot = torch.matmul(weights, g.unsqueeze(1))  # sum_k A_ik g_k, (H, chunk, 1)
            grad_scores = (weights * g).sub_(weights.mul_(row_dot))
            grad_q[:, start:stop] = torch.matmul(grad_scores, k) * scale
            grad_k += torch.matmul(grad_scores.transpose(1, 2), q[:, start:stop]) * scale
        return grad_q, grad_k, None, None


class SelfAttention(nn.Module):
    """Multi-head self-attention of Eq. 1-4, through scaled_dot_product_attention."""

    def __init__(self, config: ModelConfig):
        super().__init__()
        self.heads = config.heads
        self.qkv = nn.Linear(config.width, 3 * config.width)
        self.proj = nn.Linear(config.width, config.width)
        # Dropout on the output, not on A: sdpa's dropout_p sends CPU to the path that stores all of A.
        self.dropout = nn.Dropout(config.dropout)

    def forward(self, h: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(T, W) -> output (T, W), and the per-head queries and keys (H, T, d), scores at scale 1/sqrt(d)."""
        n_tokens, width = h.shape
        dim = width // self.heads
        # (3, 1, H, T, d): the leading batch axis of 1 matters, the CPU flash kernel
        # wants 4-d input; 3-d input falls back to a path that stores all of A (docs/decisions.md).
        q, k, v = self.qkv(h).view(n_tokens, 3, self.heads, dim).permute(1, 2, 0, 3).unsqueeze(1)
        out = F.scaled_dot_product_attention(q, k, v, scale=1.0 / math.sqrt(dim))
        return self.dropout(self.proj(out[0].transpose(0, 1).reshape(n_tokens, width))), q[0], k[0]


class SpectralDiffusion(nn.Module):
    """e + MLP([e, D_t e]), D_t the heat diffusion through the eigenbasis, one learned time per channel (:class:`ModelConfig`)."""

    def __init__(self, width: int, gradients: bool = False):
        super().__init__()
        # times from 1e-3 to 1e-1 on the unit-area mesh: from a few faces' width to a limb's length at the start
        self.log_time = nn.Parameter(torch.linspace(math.log(1e-3), math.log(1e-1), width))
        # the real and imaginary parts of a complex W x W matrix, for the gradient features
        self.rotate = nn.Linear(width, 2 * width, bias=False) if gradients else None
        self.mlp = nn.Sequential(nn.Linear((3 if gradients else 2) * width, width), nn.GELU(), nn.Linear(width, width))

    def forward(self, e: torch.Tensor, spectrum: SpectralInput) -> torch.Tensor:
        coefficients = spectrum.basis.T @ (spectrum.mass.unsqueeze(1) * e)  # (k, W)
        decay = torch.exp(-spectrum.values.unsqueeze(1) * self.log_time.exp().unsqueeze(0))  # (k, W)
        diffused = spectrum.basis @ (coefficients * decay)
        parts = [e, diffused]
        if self.rotate is not None:
            if spectrum.gradient is None:
                raise ValueError("a block with gradient features needs the level's gradient operator (SpectralInput.gradient)")
            g = torch.sparse.mm(spectrum.gradient, diffused)  # (2F, W): x and y along each face's frame
            x, y = g[0::2], g[1::2]
            real, imaginary = self.rotate.weight.chunk(2, dim=0)
            turned_x, turned_y = x @ real.T - y @ imaginary.T, y @ real.T + x @ imaginary.T
            parts.append(torch.tanh(x * turned_x + y * turned_y))
        return e + self.mlp(torch.cat(parts, dim=1))


class Block(nn.Module):
    """Pre-norm transformer block: h + Attn(LN h), then + MLP(LN h)."""

    def __init__(self, config: ModelConfig):
        super().__init__()
        self.norm_attention = nn.LayerNorm(config.width)
        self.attention = SelfAttention(config)
        self.norm_mlp = nn.LayerNorm(config.width)
        self.mlp = nn.Sequential(
            nn.Linear(config.width, 4 * config.width),
            nn.GELU(),
            nn.Linear(4 * config.width, config.width),
            nn.Dropout(config.dropout),
        )

    def forward(self, h: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(T, W) -> (T, W), plus this block's queries and keys (H, T, d)."""
        update, q, k = self.attention(self.norm_attention(h))
        h = h + update
        return h + self.mlp(self.norm_mlp(h)), q, k


class AttentionSegmenter(nn.Module):
    """Per-face class logits and attention values from per-face features and a patch layout (module docstring)."""

    def __init__(self, config: ModelConfig):
        super().__init__()
        self.config = config
        width = config.width
        layers = [nn.Linear(config.in_features, width), nn.GELU(), nn.Linear(width, width)]
        self.embed = nn.Sequential(*layers, *([nn.LayerNorm(width)] if config.embed_norm else []))
        self.share_score = nn.Linear(width, 1)
        self.diffusion = nn.ModuleList(SpectralDiffusion(width, config.diffusion_gradients)
                                       for _ in range(config.diffusion_blocks))
        self.blocks = nn.ModuleList(Block(config) for _ in range(config.depth))
        self.norm_out = nn.LayerNorm(width)
        context = width if config.depth else 0  # depth 0: the face's own embedding only
        self.head = self._head(width + context)
        for module in self.modules():
            if isinstance(module, nn.Linear):
                nn.init.normal_(module.weight, mean=0.0, std=config.init_std)
                if module.bias is not None:
                    nn.init.zeros_(module.bias)

    def _head(self, inputs: int) -> nn.Sequential:
        width = self.config.width
        return nn.Sequential(nn.Linear(inputs, width), nn.GELU(), nn.Dropout(self.config.dropout),
                             nn.Linear(width, self.config.n_classes))

    def forward(
        self, x: torch.Tensor, layout: PatchLayout, need_attention: bool = True, attention_grad: bool = False,
        spectrum: SpectralInput | None = None,
    ) -> Output:
        """Logits (F, C), attention (F,), and context (T, W) with each face's token (F,) of one mesh.

        ``x``: (F, in_features) features; ``layout``: where every face sits in the
        (n_patches, patch_size) token grid (:func:`anseg.cluster.layout`, which
        checks it once when it is made). ``need_attention=False`` skips the
        received-attention pass (as costly as one attention layer) when only the
        logits are wanted, e.g. in most training steps; ``attention_grad=True``
        returns attention with its gradient (see the module docstring).
        ``spectrum``: the level's eigenbasis, for a model with ``spectral_pairs``.

        The per-face layers run on the F faces, not on the padded grid, and
        the head's columns that read the token's context act once per token
        (its first layer is linear, so adding them per face is the same sum):
        the per-face layers are most of a step's arithmetic at patches of 32.
        """
        if x.dim() != 2 or x.shape[1] != self.config.in_features:
            raise ValueError(f"x must be (faces, {self.config.in_features}), got {tuple(x.shape)}")
        if layout.n_faces != x.shape[0] or layout.patch_size != self.config.patch_size:
            raise ValueError(f"the layout places {layout.n_faces} faces in patches of {layout.patch_size}; "
                             f"x has {x.shape[0]} faces and the model takes patches of {self.config.patch_size}")
        if self.config.spectral_pairs and (spectrum is None or spectrum.basis.shape != (x.shape[0], self.config.spectral_pairs)):
            raise ValueError(f"this model reads a spectrum of {self.config.spectral_pairs} eigenpairs per face, got "
                             f"{None if spectrum is None else tuple(spectrum.basis.shape)}")
        if not layout.mask.any(axis=1).all():
            raise ValueError("every patch needs at least one real face")
        if x.dtype != self.norm_out.weight.dtype:
            raise ValueError(f"features must be {self.norm_out.weight.dtype} like the model, got {x.dtype}")
        # a finite sum rules out NaN and inf in one cheap pass; the exact test runs only when it is not
        if not bool(torch.isfinite(x.sum())) and not bool(torch.isfinite(x).all()):
            raise ValueError("features hold NaN or inf at real faces")
        embedded = self.embed(x)
        for block in self.diffusion:
            embedded = block(embedded, spectrum)
        if not self.blocks:  # the per-face classifier (module docstring)
            if attention_grad:
                raise ValueError("a depth-0 model has no attention to train")
            return Output(self.head(embedded), x.new_ones(len(x)) if need_attention else None)
        patch = torch.as_tensor(layout.patch_of_face, device=x.device)
        # softmax of the scores over each patch's faces, on the grid where padding holds -inf
        scores = layout.to_tokens(self.share_score(embedded).squeeze(-1), fill=-math.inf)
        share = layout.to_faces(torch.softmax(scores, dim=1))
        h = embedded.new_zeros(layout.n_patches, embedded.shape[1]).index_add(0, patch, share.unsqueeze(1) * embedded)
        for block in self.blocks:
            h, q, k = block(h)
        context = self.norm_out(h)
        logits = self._head_on_faces(self.head, embedded, context, patch)
        attention = None
        if attention_grad:
            pooling = share.detach() if self.config.detach_share else share
            attention = received_attention(q, k, scale=self._scale)[patch] * pooling * len(x)
        elif need_attention:
            with torch.no_grad():
                attention = received_attention(q.detach(), k.detach(), scale=self._scale)[patch] * share.detach() * len(x)
        return Output(logits, attention)

    @staticmethod
    def _head_on_faces(head: nn.Sequential, embedded: torch.Tensor, context: torch.Tensor, patch: torch.Tensor) -> torch.Tensor:
        """``head(cat([embedded, context[patch]]))`` with the context's columns applied per token (T rows, not F)."""
        first, width = head[0], embedded.shape[1]
        hidden = (F.linear(embedded, first.weight[:, :width])
                  + F.linear(context, first.weight[:, width : 2 * width], first.bias)[patch])
        return head[1:](hidden)

    @property
    def _scale(self) -> float:
        """The attention's score scale, 1/sqrt(head dim)."""
        return 1.0 / math.sqrt(self.config.width // self.config.heads)


def model_config(recorded: dict) -> ModelConfig:
    """The :class:`ModelConfig` a model file records: a retired switch (:data:`RETIRED`) is dropped where it was off
    and refused where it was on, since this code no longer has what it switched on."""
    on = {name: value for name, value in recorded.items() if name in RETIRED and value != RETIRED[name]}
    if on:
        raise ValueError(f"the model uses switches retired since it was trained ({on}); "
                         "replay it at the revision that trained it")
    return ModelConfig(**{name: value for name, value in recorded.items() if name not in RETIRED})


def save(model: AttentionSegmenter, path: str | os.PathLike) -> Path:
    """Write the model's config and weights to ``path`` atomically."""
    payload = {"config": asdict(model.config), "state_dict": model.state_dict()}
    return atomic_write(path, lambda tmp: torch.save(payload, tmp))


def load(path: str | os.PathLike, map_location: str | torch.device = "cpu") -> AttentionSegmenter:
    """Rebuild a model written by :func:`save`, in eval mode."""
    payload = torch.load(path, map_location=map_location, weights_only=True)
    if not isinstance(payload, dict) or not {"config", "state_dict"} <= payload.keys():
        raise ValueError(f"{path} is not a model written by anseg.model.save")
    model = AttentionSegmenter(model_config(payload["config"]))
    model.load_state_dict(payload["state_dict"])
    return model.eval()
