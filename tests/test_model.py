"""The attention network: shapes, the attention value, layout invariances, init, learning, save/load."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import torch
from torch import nn

from anseg.cluster import PatchLayout, patches
from anseg.model import (
    AttentionSegmenter,
    ModelConfig,
    SpectralInput,
    load,
    received_attention,
    save,
)


def random_layout(n_faces: int, patch_size: int, generator: torch.Generator, clusters: int = 1) -> PatchLayout:
    """Faces in random order, cut into patches cluster by cluster; the last patch of a cluster is partly padding."""
    order = torch.randperm(n_faces, generator=generator).numpy()
    labels = np.zeros(n_faces, dtype=np.int64)
    labels[order] = np.arange(n_faces) * clusters // n_faces  # contiguous runs of the sequence
    return patches(order, labels, patch_size)


@pytest.fixture
def problem():
    g = torch.Generator().manual_seed(0)
    config = ModelConfig(in_features=5, n_classes=3, width=32, depth=2, heads=4, patch_size=8)
    torch.manual_seed(0)
    model = AttentionSegmenter(config).eval()
    x = torch.randn(203, 5, generator=g)
    return model, x, random_layout(203, 8, g, clusters=3)


def test_shapes_and_attention_normalisation(problem):
    model, x, layout = problem
    out = model(x, layout)
    assert out.logits.shape == (203, 3)
    assert out.attention.shape == (203,)
    assert torch.isfinite(out.logits).all()
    assert torch.isfinite(out.attention).all() and (out.attention > 0).all()
    assert out.attention.mean().item() == pytest.approx(1.0, rel=1e-5)
    assert model(x, layout, need_attention=False).attention is None


def test_attention_with_gradient_matches_and_trains(problem):
    model, x, layout = problem
    plain = model(x, layout).attention
    graded = model(x, layout, attention_grad=True).attention
    assert torch.allclose(plain, graded, rtol=1e-4, atol=1e-6)
    graded[:10].sum().backward()
    assert model.share_score.weight.grad.abs().sum() > 0
    assert model.blocks[-1].attention.qkv.weight.grad.abs().sum() > 0


def test_token_attention_is_spread_by_the_learned_share():
    """Inside a token, face attention is proportional to exp(share score): ratios match, faces differ."""
    torch.manual_seed(1)
    model = AttentionSegmenter(ModelConfig(in_features=2, n_classes=2, width=16, heads=2, patch_size=4)).eval()
    with torch.no_grad():
        model.share_score.weight.normal_(0.0, 1.0)  # the initial scores are all near zero
    x = torch.randn(40, 2)
    attention = model(x, patches(np.arange(40), np.arange(40) // 4, 4)).attention.view(10, 4)
    with torch.no_grad():
        scores = model.share_score(model.embed(x)).view(10, 4)
    expected = torch.softmax(scores, dim=1) * attention.sum(dim=1, keepdim=True)
    torch.testing.assert_close(attention, expected)
    assert attention.std(dim=1).min() > 1e-3


def test_chunked_received_attention_equals_dense():
    g = torch.Generator().manual_seed(2)
    q, k = torch.randn(3, 37, 8, generator=g), torch.randn(3, 37, 8, generator=g)
    dense = torch.softmax(q @ k.transpose(1, 2) / math.sqrt(8), dim=-1).mean(dim=(0, 1))
    for chunk in (1, 5, 37, 100, None):
        torch.testing.assert_close(received_attention(q, k, chunk=chunk), dense, rtol=1e-5, atol=1e-7)
    assert dense.sum().item() == pytest.approx(1.0, rel=1e-5)


def test_received_attention_gradient_equals_dense_autograd():
    """The hand-written chunked backward gives the gradient autograd finds through the dense matrix."""
    g = torch.Generator().manual_seed(3)
    q, k = (torch.randn(2, 23, 4, generator=g, dtype=torch.float64, requires_grad=True) for _ in range(2))
    upstream = torch.randn(23, generator=g, dtype=torch.float64)
    dense = torch.softmax(q @ k.transpose(1, 2) / 2.0, dim=-1).mean(dim=(0, 1))
    expected = torch.autograd.grad(dense, (q, k), upstream)
    for chunk in (1, 4, 23, None):
        got = torch.autograd.grad(received_attention(q, k, chunk=chunk), (q, k), upstream)
        for a, b in zip(got, expected):
            torch.testing.assert_close(a, b)
    assert torch.autograd.gradcheck(lambda a, b: received_attention(a, b, chunk=5), (q, k))


def test_received_attention_rejects_bad_input():
    with pytest.raises(ValueError, match="heads, tokens, dim"):
        received_attention(torch.zeros(4, 8), torch.zeros(4, 8))
    with pytest.raises(ValueError, match="chunk"):
        received_attention(torch.zeros(1, 4, 2), torch.zeros(1, 4, 2), chunk=0)


def test_logits_follow_tokens_not_face_index(problem):
    model, x, layout = problem
    out = model(x, layout)
    perm = torch.randperm(x.shape[0], generator=torch.Generator().manual_seed(3))
    inverse = torch.argsort(perm).numpy()
    moved = replace(layout, order=inverse[layout.order], patch_of_face=layout.patch_of_face[perm.numpy()],
                    slot_of_face=layout.slot_of_face[perm.numpy()])
    permuted = model(x[perm], moved)
    torch.testing.assert_close(permuted.logits, out.logits[perm])
    torch.testing.assert_close(permuted.attention, out.attention[perm])


def test_context_reaches_other_tokens(problem):
    """Changing one patch's faces changes the logits of faces in other patches (attention mixes tokens)."""
    model, x, layout = problem
    out = model(x, layout)
    changed = x.clone()
    first = torch.as_tensor(layout.patch_of_face == 0)
    changed[first] += 3.0
    assert not torch.allclose(model(changed, layout).logits[~first], out.logits[~first])


def test_head_on_faces_is_the_head_on_the_concatenation(problem):
    """The context columns applied once per token give the head of [embedding, context of the face's token]."""
    model, x, layout = problem
    patch = torch.as_tensor(layout.patch_of_face)
    embedded, context = torch.randn(len(x), 16), torch.randn(layout.n_patches, 16)
    plain = nn.Sequential(nn.Linear(16 * 2, 8), nn.GELU(), nn.Linear(8, 3))
    torch.testing.assert_close(model._head_on_faces(plain, embedded, context, patch),
                               plain(torch.cat([embedded, context[patch]], dim=1)))


def test_layout_errors_are_explicit(problem):
    model, x, layout = problem
    with pytest.raises(ValueError, match="places 202 faces"):
        model(x, random_layout(202, 8, torch.Generator().manual_seed(1)))
    with pytest.raises(ValueError, match="patches of 4"):
        model(x, random_layout(203, 4, torch.Generator().manual_seed(1)))
    with pytest.raises(ValueError, match="every patch needs"):
        model(x, replace(layout, mask=np.zeros_like(layout.mask)))
    with pytest.raises(ValueError, match=r"x must be \(faces, 5\)"):
        model(x[:, :4], layout)
    for bad in (float("inf"), float("nan")):
        with pytest.raises(ValueError, match="NaN or inf"):
            model(torch.where(torch.as_tensor(layout.patch_of_face == 1)[:, None], bad, x), layout)
    model(torch.full_like(x, 3e38), layout)  # finite, though their sum overflows: no error
    with pytest.raises(ValueError, match="float32"):
        model(x.double(), layout)
    with pytest.raises(ValueError, match="divisible"):
        ModelConfig(in_features=5, n_classes=2, width=30, heads=4)


def test_init_follows_the_paper_variance():
    torch.manual_seed(4)
    model = AttentionSegmenter(ModelConfig(in_features=4, n_classes=2, width=256))
    weight = model.blocks[0].mlp[0].weight  # 1024 x 256
    assert weight.std().item() == pytest.approx(math.sqrt(0.001), rel=0.02)
    assert weight.mean().abs().item() < 1e-3
    assert all((m.bias == 0).all() for m in model.modules() if isinstance(m, torch.nn.Linear))


@pytest.fixture
def one_thread():
    """Tiny ops: a second intra-op thread only spins, and on a busy 2-core machine it costs 10x."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(threads)


def test_overfits_a_small_problem(one_thread):
    torch.manual_seed(5)
    g = torch.Generator().manual_seed(5)
    x = torch.randn(500, 4, generator=g)
    labels = (x[:, 0] > 0).long()
    layout = random_layout(500, 16, g)
    model = AttentionSegmenter(ModelConfig(in_features=4, n_classes=2, patch_size=16))
    optimiser = torch.optim.Adam(model.parameters(), lr=1e-3)
    for _ in range(200):
        optimiser.zero_grad()
        loss = torch.nn.functional.cross_entropy(model(x, layout, need_attention=False).logits, labels)
        loss.backward()
        optimiser.step()
    model.eval()
    accuracy = (model(x, layout).logits.argmax(1) == labels).float().mean().item()
    assert accuracy > 0.95


def test_save_load_round_trip(problem, tmp_path):
    model, x, layout = problem
    path = save(model, tmp_path / "sub" / "model.pt")
    restored = load(path)
    assert restored.config == model.config
    a, b = model(x, layout), restored(x, layout)
    assert torch.equal(a.logits, b.logits) and torch.equal(a.attention, b.attention)
    assert [p.name for p in path.parent.iterdir()] == ["model.pt"]  # no temporary left behind


def test_load_rejects_foreign_files(tmp_path):
    path = tmp_path / "other.pt"
    torch.save({"weights": torch.zeros(2)}, path)
    with pytest.raises(ValueError, match="not a model"):
        load(path)


def test_depth_zero_is_a_per_face_classifier():
    g = torch.Generator().manual_seed(1)
    torch.manual_seed(1)
    model = AttentionSegmenter(ModelConfig(in_features=5, n_classes=3, width=16, depth=0, patch_size=8)).eval()
    x = torch.randn(50, 5, generator=g)
    layout = random_layout(50, 8, g)
    out = model(x, layout)
    other = x.clone()
    other[1:] = torch.randn(49, 5, generator=g)  # every other face changes; face 0's logits must not
    assert torch.allclose(model(other, layout).logits[0], out.logits[0])
    assert torch.equal(out.attention, torch.ones(50))
    with pytest.raises(ValueError, match="no attention"):
        model(x, layout, attention_grad=True)
    with pytest.raises(ValueError, match="depth"):
        ModelConfig(in_features=5, n_classes=3, depth=-1)


def test_detach_share_cuts_the_attention_loss_direct_path_through_the_share():
    g = torch.Generator().manual_seed(2)
    x = torch.randn(64, 5, generator=g)
    layout = random_layout(64, 8, g, clusters=2)
    values, grads = [], []
    for detach in (False, True):
        torch.manual_seed(2)  # the same weights
        model = AttentionSegmenter(ModelConfig(in_features=5, n_classes=3, width=16, heads=2, patch_size=8, detach_share=detach))
        attention = model(x, layout, attention_grad=True).attention
        attention[:5].sum().backward()
        values.append(attention.detach())
        grads.append(model.share_score.weight.grad.clone())
        assert model.blocks[-1].attention.qkv.weight.grad.abs().sum() > 0
    torch.testing.assert_close(values[0], values[1])  # the same attention, another gradient
    assert not torch.allclose(grads[0], grads[1])


def spectral_problem(**config):
    """A model that reads a spectrum, with an orthonormal random basis (its first column constant) and its mass."""
    g = torch.Generator().manual_seed(1)
    n_faces, pairs = 150, 12
    torch.manual_seed(0)
    model = AttentionSegmenter(ModelConfig(in_features=5, n_classes=3, width=16, depth=1, heads=2, patch_size=8,
                                           spectral_pairs=pairs, **config)).eval()
    mass = torch.full((n_faces,), 1.0 / n_faces)
    basis, _ = torch.linalg.qr(torch.cat([torch.ones(n_faces, 1), torch.randn(n_faces, pairs - 1, generator=g)], 1))
    spectrum = SpectralInput(basis * math.sqrt(n_faces), torch.linspace(0, 200, pairs), mass)
    return model, torch.randn(n_faces, 5, generator=g), random_layout(n_faces, 8, g, clusters=2), spectrum


def test_learned_diffusion_ignores_the_signs_of_the_eigenvectors():
    model, x, layout, spectrum = spectral_problem(diffusion_blocks=2)
    flipped = spectrum._replace(basis=spectrum.basis * torch.tensor([1.0, -1.0] * 6))
    np.testing.assert_allclose(model(x, layout, spectrum=spectrum).logits.detach(),
                               model(x, layout, spectrum=flipped).logits.detach(), atol=1e-5)
    # and it reads the basis: another basis gives other logits
    other = spectrum._replace(basis=spectrum.basis.roll(1, dims=0))
    assert not torch.allclose(model(x, layout, spectrum=spectrum).logits, model(x, layout, spectrum=other).logits)


def test_a_model_that_reads_a_spectrum_refuses_to_run_without_one():
    model, x, layout, spectrum = spectral_problem(diffusion_blocks=1)
    with pytest.raises(ValueError, match="spectrum of 12 eigenpairs"):
        model(x, layout)
    with pytest.raises(ValueError, match="need a spectrum"):
        ModelConfig(in_features=5, n_classes=3, diffusion_blocks=1)


def test_a_model_file_with_a_retired_switch_loads_where_it_was_off_and_is_refused_where_it_was_on(tmp_path):
    model, x, layout, spectrum = spectral_problem(diffusion_blocks=1)
    save(model, tmp_path / "m.pt")
    payload = torch.load(tmp_path / "m.pt", weights_only=True)
    torch.save({**payload, "config": {**payload["config"], "position_pairs": 0}}, tmp_path / "off.pt")
    assert torch.equal(load(tmp_path / "off.pt")(x, layout, spectrum=spectrum).logits,
                       model(x, layout, spectrum=spectrum).logits)
    torch.save({**payload, "config": {**payload["config"], "heat_bias_pairs": 6}}, tmp_path / "on.pt")
    with pytest.raises(ValueError, match="retired"):
        load(tmp_path / "on.pt")


def test_a_spectral_model_saves_and_loads(tmp_path):
    model, x, layout, spectrum = spectral_problem(diffusion_blocks=1)
    save(model, tmp_path / "m.pt")
    again = load(tmp_path / "m.pt")
    assert torch.equal(model(x, layout, spectrum=spectrum).logits, again(x, layout, spectrum=spectrum).logits)

