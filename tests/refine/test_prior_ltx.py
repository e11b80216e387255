"""LTX-Video prior on a tiny random-weight stack saved to disk and loaded back (real code path)."""
from __future__ import annotations

import logging
import shutil

import numpy as np
import pytest
import torch

from anigs.refine.prior.ltx import LTXConfig, LTXPrior, check_model_folder, padded_shape, sigma_schedule

DISTILLED = [1.0, 0.994, 0.988, 0.981, 0.975, 0.909, 0.725, 0.422]


def test_missing_folder_names_the_layout(tmp_path):
    with pytest.raises(FileNotFoundError, match="transformer/.*vae/.*scheduler/.*text_encoder/.*tokenizer/"):
        check_model_folder(tmp_path / "nope")
    (tmp_path / "m" / "transformer").mkdir(parents=True)
    with pytest.raises(FileNotFoundError, match=r"lacks \['model_index.json', 'vae/'"):
        check_model_folder(tmp_path / "m")
    with pytest.raises(FileNotFoundError, match="model_path is not set"):
        LTXPrior({"device": "cpu"}).load()


def test_sigma_schedule_and_padding():
    s = sigma_schedule(0.6, 8)
    assert s[0] == 0.6 and s[-1] == 0.0 and len(s) == 9 and all(a > b for a, b in zip(s, s[1:]))
    assert sigma_schedule(0.5, 8, DISTILLED) == [0.5, 0.422, 0.0]
    assert sigma_schedule(1.0, 8, DISTILLED)[:2] == [1.0, 0.994]
    assert sigma_schedule(0.0, 8) == [0.0]
    assert padded_shape(1, 32, 32) == (1, 32, 32)
    assert padded_shape(9, 33, 64) == (9, 64, 64)
    assert padded_shape(10, 40, 50) == (17, 64, 64)
    with pytest.raises(ValueError, match="unknown key"):
        LTXConfig.from_dict({"num_steps": 3})
    with pytest.raises(ValueError, match="float16"):
        LTXConfig.from_dict({"dtype": "float16"})


@pytest.fixture(scope="module")
def tiny_ltx(tmp_path_factory):
    """A tiny LTXConditionPipeline (random weights, tiny T5, sentencepiece tokenizer) saved to disk."""
    for mod in ("diffusers", "transformers", "sentencepiece"):
        pytest.importorskip(mod, reason=f"{mod} not installed (extra: anigs[ltx])")
    from anigs.refine.prior.ltx_tiny import save_tiny_random_stack

    return save_tiny_random_stack(tmp_path_factory.mktemp("ltx"))


def prior_for(path, **kw):
    return LTXPrior({"model_path": str(path), "device": "cpu", "max_sequence_length": 16, **kw})


def small_clip(T=10, H=40, W=50, seed=0):
    return np.random.default_rng(seed).random((T, H, W, 3)).astype(np.float32)


def test_refine_shapes_sigmas_timesteps(tiny_ltx, caplog):
    prior = prior_for(tiny_ltx, steps=4)
    seen = []
    prior.load().transformer.register_forward_pre_hook(
        lambda mod, args, kwargs: seen.append(kwargs["timestep"].detach().clone()), with_kwargs=True)
    clip = small_clip()
    with caplog.at_level(logging.INFO, logger="anigs.refine.prior.ltx"):
        out = prior.refine(clip, None, "trees sway", seed=3, strength=0.6)
    assert out.shape == clip.shape and out.dtype == np.float32
    assert np.isfinite(out).all() and out.min() >= 0 and out.max() <= 1
    sig = prior.last_info["sigmas"]
    assert sig[0] == pytest.approx(0.6) and sig[-1] == 0.0 and len(sig) == 5
    assert "sigmas [0.6, 0.45, 0.3, 0.15, 0.0]" in caplog.text and "padded to (17, 64, 64)" in caplog.text
    assert len(seen) == 4
    per_frame = 2 * 2  # latent tokens of one frame: 64/32 x 64/32
    for t_used, s in zip(seen, sig[:-1]):
        assert torch.all(t_used[:, :per_frame] == 0)                       # frame 0: clean condition
        assert torch.allclose(t_used[:, per_frame:], torch.tensor(s * 1000.0))
    again = prior_for(tiny_ltx, steps=4).refine(clip, None, "trees sway", seed=3, strength=0.6)
    assert np.array_equal(out, again)
    other = prior.refine(clip, None, "trees sway", seed=4, strength=0.6)
    assert not np.array_equal(out, other)
    assert np.array_equal(prior.refine(clip, None, "", 0, 0.0), clip)


def test_generate_and_distilled_schedule(tiny_ltx):
    prior = prior_for(tiny_ltx, sigmas=DISTILLED, condition_first_frame=False)
    out = prior.generate(small_clip(1, 32, 48)[0], None, "grass waves", seed=1, num_frames=9)
    assert out.shape == (9, 32, 48, 3) and np.isfinite(out).all()
    assert prior.last_info["sigmas"] == DISTILLED + [0.0]
    one = prior.refine(small_clip(1, 20, 30), None, "", seed=0, strength=0.5)   # 1 frame, odd size
    assert one.shape == (1, 20, 30, 3) and np.isfinite(one).all()


def test_prompt_embeds_without_text_encoder(tiny_ltx, tmp_path):
    model = tmp_path / "model"
    shutil.copytree(tiny_ltx, model)
    shutil.rmtree(model / "text_encoder")
    shutil.rmtree(model / "tokenizer")
    with pytest.raises(FileNotFoundError, match="text_encoder/"):
        check_model_folder(model)
    torch.save({"embeds": torch.randn(7, 16), "mask": torch.ones(7, dtype=torch.long)}, tmp_path / "emb.pt")
    prior = prior_for(model, steps=2, prompt_embeds=str(tmp_path / "emb.pt"))
    out = prior.refine(small_clip(9, 32, 32), None, "ignored", seed=0, strength=0.5)
    assert out.shape == (9, 32, 32, 3) and np.isfinite(out).all()


@pytest.mark.parametrize("tau", [0.0, 0.5, 1.0])
def test_sds_gradient_reaches_only_the_sampled_frame(tiny_ltx, tau):
    prior = prior_for(tiny_ltx, sds_tau_min=tau, sds_tau_max=tau)
    base = torch.from_numpy(small_clip(5, 32, 40))
    coeffs = torch.zeros(5, requires_grad=True)          # stand-in for the deformation coefficients
    clip = (base * (1 + coeffs[:, None, None, None])).clamp(0, 1)
    loss = prior.sds_loss(clip, "trees sway", torch.Generator().manual_seed(0))
    assert loss.ndim == 0 and torch.isfinite(loss)
    loss.backward()
    j = prior.last_info["grad_frame"]
    assert prior.last_info["tau"] == pytest.approx(tau)
    assert torch.isfinite(coeffs.grad).all() and coeffs.grad[j] != 0
    assert torch.count_nonzero(coeffs.grad) == 1
    pipe = prior.load()
    for module in (pipe.transformer, pipe.vae, pipe.text_encoder):
        assert all(p.grad is None for p in module.parameters())
    with pytest.raises(ValueError, match="4m\\+1"):
        prior.sds_loss(torch.zeros(4, 32, 32, 3), "x")


@pytest.mark.gpu
def test_refine_bf16_on_gpu(tiny_ltx):
    prior = LTXPrior({"model_path": str(tiny_ltx), "device": "auto", "max_sequence_length": 16, "steps": 3})
    assert prior.device.type == "cuda" and prior.dtype == torch.bfloat16  # auto picks the GPU, bf16 there
    clip = small_clip(17, 64, 96)
    out = prior.refine(clip, None, "trees sway", seed=0, strength=0.7)
    assert out.shape == clip.shape and np.isfinite(out).all()
    coeffs = torch.zeros(5, device=prior.device, requires_grad=True)
    sub = (torch.from_numpy(clip[:5]).to(prior.device) * (1 + coeffs[:, None, None, None])).clamp(0, 1)
    loss = prior.sds_loss(sub, "trees sway", torch.Generator().manual_seed(0))
    loss.backward()
    assert torch.isfinite(loss) and torch.isfinite(coeffs.grad).all()
