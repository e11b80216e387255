"""LTX-Video prior (diffusers) with weights from a local folder: refinement, generation, SDS.

Expected folder layout (what ``LTXConditionPipeline.save_pretrained`` writes, e.g. a local
copy of ``Lightricks/LTX-Video``)::

    model_path/model_index.json
    model_path/transformer/   (LTXVideoTransformer3DModel)
    model_path/vae/           (AutoencoderKLLTXVideo)
    model_path/scheduler/     (FlowMatchEulerDiscreteScheduler)
    model_path/text_encoder/  (T5EncoderModel)   } or, without them, ``prompt_embeds``: a .pt file
    model_path/tokenizer/     (T5 tokenizer)     }   {"embeds": [L,D], "mask": [L]} used for every prompt

Nothing is ever downloaded (``local_files_only=True``).

The denoising loop is written here with the pipeline's components (transformer, VAE and
its latent statistics, the pipeline's packing / video-coordinate helpers) rather than by
calling the pipeline, because SDEdit-style refinement needs an explicit noise level:
``denoise_strength`` picks a number of schedule steps, not a sigma (NOTES.md).

Rectified flow (paper Eq. rf_forward / rf_euler): ``z_s = (1 - s) z_0 + s eps``; the
transformer predicts ``v = eps - z_0``; Euler: ``z_{s'} = z_s + (s' - s) v``.

Refinement: encode the (composed) clip, noise it to ``sigma = strength``, run Euler steps
over explicit sigmas from ``strength`` to 0 (``steps`` linear steps, or the part of the
configured ``sigmas`` below ``strength``), decode. With ``condition_first_frame`` the first
latent frame (= pixel frame 0, the VAE is causal) is kept clean with per-token timestep 0,
as LTXConditionPipeline does for a frame-0 condition, so the canonical frame stays put.
Frame counts are padded to ``8k+1`` (last frame repeated) and sizes to multiples of 32
(edge pixels replicated); the output is cropped back to the input shape.
"""
from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import torch

from anigs.typed_config import Section
from anigs.device import get_device
from anigs.refine.prior.base import MaskLike, VideoPrior, check_strength
from anigs.video import check_clip

log = logging.getLogger(__name__)

LAYOUT = ("transformer", "vae", "scheduler", "text_encoder", "tokenizer")
LAYOUT_HELP = ("expected a local diffusers LTX-Video folder: model_index.json plus subfolders "
               "transformer/, vae/, scheduler/, text_encoder/, tokenizer/ (e.g. a local copy of "
               "Lightricks/LTX-Video downloaded beforehand with `huggingface-cli download "
               "Lightricks/LTX-Video --local-dir PATH`); text_encoder/ and tokenizer/ may be left out "
               "when ltx.prompt_embeds names a .pt file with precomputed T5 embeddings")


@dataclass
class LTXConfig(Section):
    """Config of the LTX-Video prior (section ``ltx`` of the refine stage)."""

    HANDED = ('device',)  # set once for the whole run (anigs.config.HANDED), not in this section

    WHERE = "ltx prior config"

    model_path: str = ""                  # local diffusers folder (see LAYOUT_HELP)
    steps: int = 8                        # Euler steps from sigma=strength to 0 (linear in sigma)
    sigmas: list[float] | None = None     # explicit schedule (e.g. the distilled one); the part < strength is used
    guidance_scale: float = 1.0           # classifier-free guidance (> 1 doubles the batch)
    negative_prompt: str = ""  # negative text prompt (with guidance_scale > 1)
    max_sequence_length: int = 128        # T5 tokens
    frame_rate: float = 24.0              # frame rate given to the transformer's video coordinates
    device: str = "auto"                  # auto | cpu | cuda[:N]
    dtype: str = "auto"                   # auto (bf16 on GPU, fp32 on CPU) | bfloat16 | float32
    condition_first_frame: bool = True    # keep latent frame 0 clean (frame 0 = canonical frame)
    decode_timestep: float = 0.0          # for timestep-conditioned VAEs (LTX 0.9.1+)
    decode_noise_scale: float | None = None  # noise scale added before VAE decoding (null = model default)
    vae_tiling: bool = False              # decode in tiles (large resolutions)
    prompt_embeds: str | None = None      # .pt with {"embeds": [L,D], "mask": [L]} when no text encoder
    sds_tau_min: float = 0.02             # SDS: tau ~ U(tau_min, tau_max)
    sds_tau_max: float = 0.98  # largest diffusion time sampled by the SDS loss
    sds_weighting: str = "uniform"        # uniform: w=1 | x0: w=tau^2 (loss on the predicted clean latent)

    def validate(self) -> None:
        cfg = self
        if cfg.steps < 1:
            raise ValueError(f"ltx.steps must be >= 1, got {cfg.steps}")
        if not (0.0 <= cfg.sds_tau_min <= cfg.sds_tau_max <= 1.0):
            raise ValueError(f"need 0 <= sds_tau_min <= sds_tau_max <= 1, got {cfg.sds_tau_min}, {cfg.sds_tau_max}")
        if cfg.sds_weighting not in ("uniform", "x0"):
            raise ValueError(f"sds_weighting {cfg.sds_weighting!r} is not 'uniform' or 'x0'")
        if cfg.dtype not in ("auto", "bfloat16", "float32"):
            raise ValueError(f"ltx.dtype {cfg.dtype!r} is not auto | bfloat16 | float32 (float16 gives NaN with LTX)")
        if cfg.sigmas is not None and any(not (0.0 <= s <= 1.0) for s in cfg.sigmas):
            raise ValueError(f"ltx.sigmas must lie in [0, 1], got {cfg.sigmas}")


def sigma_schedule(strength: float, steps: int, sigmas: list[float] | None = None) -> list[float]:
    """Explicit sigmas from ``strength`` down to 0 (inclusive): ``steps`` linear steps, or the
    values of ``sigmas`` strictly below ``strength`` with ``strength`` prepended."""
    s = check_strength(strength)
    if s == 0.0:
        return [0.0]
    if sigmas:
        tail = sorted({float(x) for x in sigmas if x < s - 1e-6}, reverse=True)
        out = [s] + tail
    else:
        out = [s * (1.0 - i / steps) for i in range(steps)]
    return out + [0.0] if out[-1] > 0.0 else out


def padded_shape(frames: int, height: int, width: int, t_ratio: int = 8, s_ratio: int = 32) -> tuple[int, int, int]:
    """(T', H', W'): frames -> t_ratio*k + 1 >= frames, sizes -> multiples of s_ratio."""
    tp = (max(frames, 1) - 1 + t_ratio - 1) // t_ratio * t_ratio + 1
    return tp, -(-height // s_ratio) * s_ratio, -(-width // s_ratio) * s_ratio


def pad_video(video: torch.Tensor, shape: tuple[int, int, int]) -> torch.Tensor:
    """Pad [B,C,T,H,W] at the end of T, H, W by replication to ``shape`` (T', H', W')."""
    T, H, W = video.shape[2:]
    tp, hp, wp = shape
    if (hp, wp) != (H, W):
        b, c = video.shape[:2]
        flat = video.permute(0, 2, 1, 3, 4).reshape(b * T, c, H, W)
        flat = torch.nn.functional.pad(flat, (0, wp - W, 0, hp - H), mode="replicate")
        video = flat.reshape(b, T, c, hp, wp).permute(0, 2, 1, 3, 4)
    if tp != T:
        video = torch.cat([video, video[:, :, -1:].expand(-1, -1, tp - T, -1, -1)], dim=2)
    return video


def check_model_folder(path: str | Path, need_text_encoder: bool = True) -> Path:
    """Raise FileNotFoundError naming the expected layout when ``path`` is not a usable folder."""
    if not path:
        raise FileNotFoundError(f"ltx.model_path is not set; {LAYOUT_HELP}")
    p = Path(path).expanduser()
    if not p.is_dir():
        raise FileNotFoundError(f"LTX-Video model folder not found: {p}; {LAYOUT_HELP}")
    need = ["transformer", "vae", "scheduler"] + (["text_encoder", "tokenizer"] if need_text_encoder else [])
    missing = [n + "/" for n in need if not (p / n).is_dir()]
    if not (p / "model_index.json").is_file():
        missing.insert(0, "model_index.json")
    if missing:
        raise FileNotFoundError(f"LTX-Video model folder {p} lacks {missing}; {LAYOUT_HELP}")
    return p


def import_diffusers():
    try:
        from diffusers import LTXConditionPipeline  # noqa: F401
        from diffusers.pipelines.ltx import pipeline_ltx_condition  # noqa: F401
    except Exception as exc:  # ImportError, or a broken optional dependency underneath
        raise RuntimeError(f"the ltx prior needs diffusers and transformers ({type(exc).__name__}: {exc}); "
                           "install the extra: pip install -c envs/constraints.txt 'anigs[ltx]'") from exc
    return LTXConditionPipeline, pipeline_ltx_condition


class LTXPrior(VideoPrior):
    """LTX-Video refinement / generation / SDS (see module docstring). Loads lazily on first use."""

    name = "ltx"
    has_score = True

    def __init__(self, cfg: LTXConfig | Mapping[str, Any] | None = None):
        self.cfg = cfg if isinstance(cfg, LTXConfig) else LTXConfig.from_dict(cfg)
        self.device = get_device(self.cfg.device)
        if self.cfg.dtype == "auto":
            self.dtype = torch.bfloat16 if self.device.type == "cuda" else torch.float32
        else:
            self.dtype = getattr(torch, self.cfg.dtype)
        self.pipe = None
        self._embeds: dict[tuple[str, bool], tuple[torch.Tensor, torch.Tensor]] = {}
        self.last_info: dict[str, Any] = {}

    # -- loading -----------------------------------------------------------------------
    def load(self):
        """Load the pipeline components from ``model_path`` (local files only)."""
        if self.pipe is not None:
            return self.pipe
        use_embeds = bool(self.cfg.prompt_embeds)
        path = check_model_folder(self.cfg.model_path, need_text_encoder=not use_embeds)
        if use_embeds and not Path(self.cfg.prompt_embeds).is_file():
            raise FileNotFoundError(f"ltx.prompt_embeds file not found: {self.cfg.prompt_embeds} "
                                    "(a torch .pt with {'embeds': [L,D], 'mask': [L]})")
        Pipe, _ = import_diffusers()
        extra = {"text_encoder": None, "tokenizer": None} if use_embeds else {}
        with warnings.catch_warnings():  # newer diffusers renamed torch_dtype to dtype; keep the old spelling working
            warnings.simplefilter("ignore", FutureWarning)
            pipe = Pipe.from_pretrained(str(path), local_files_only=True, torch_dtype=self.dtype, **extra)
        pipe.to(self.device)
        for module in (pipe.transformer, pipe.vae, getattr(pipe, "text_encoder", None)):
            if module is not None:
                module.requires_grad_(False)
                module.eval()
        if self.cfg.vae_tiling:
            pipe.vae.enable_tiling()
        pipe.set_progress_bar_config(disable=True)
        self.pipe = pipe
        log.info("LTX-Video loaded from %s on %s (%s): VAE %dx spatial / %dx temporal", path, self.device,
                 self.dtype, pipe.vae_spatial_compression_ratio, pipe.vae_temporal_compression_ratio)
        return pipe

    # -- helpers -------------------------------------------------------------------------
    def _prompt(self, prompt: str, negative: bool = False) -> tuple[torch.Tensor, torch.Tensor]:
        key = (prompt if not negative else self.cfg.negative_prompt, negative)
        if key in self._embeds:
            return self._embeds[key]
        pipe = self.load()
        if self.cfg.prompt_embeds:
            d = torch.load(self.cfg.prompt_embeds, map_location="cpu", weights_only=True)
            emb, mask = d["embeds"], d["mask"]
            emb = (emb[None] if emb.ndim == 2 else emb).to(self.device, self.dtype)
            mask = (mask[None] if mask.ndim == 1 else mask).to(self.device)
        else:
            emb, mask, _, _ = pipe.encode_prompt(prompt=key[0], do_classifier_free_guidance=False,
                                                 max_sequence_length=self.cfg.max_sequence_length, device=self.device)
            emb = emb.to(self.dtype)
        self._embeds[key] = (emb, mask)
        return emb, mask

    def _encode(self, video: torch.Tensor, grad: bool = False) -> torch.Tensor:
        """[1,3,T,H,W] in [0,1] (padded) -> normalised latents [1,C,F,h,w] float32."""
        pipe = self.load()
        _, mod = import_diffusers()
        with torch.set_grad_enabled(grad):
            out = pipe.vae.encode((video * 2.0 - 1.0).to(self.device, pipe.vae.dtype))
            z = mod.retrieve_latents(out, sample_mode="argmax").float()
        return pipe._normalize_latents(z, pipe.vae.latents_mean, pipe.vae.latents_std,
                                       pipe.vae.config.scaling_factor).float()

    @torch.no_grad()
    def _decode(self, z: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        """Normalised latents -> video [1,3,T,H,W] in [0,1] float32."""
        pipe = self.load()
        z = pipe._denormalize_latents(z, pipe.vae.latents_mean, pipe.vae.latents_std, pipe.vae.config.scaling_factor)
        ts = None
        if pipe.vae.config.timestep_conditioning:
            noise = torch.randn(z.shape, generator=generator, dtype=z.dtype).to(z.device)
            scale = self.cfg.decode_noise_scale if self.cfg.decode_noise_scale is not None else self.cfg.decode_timestep
            z = (1 - scale) * z + scale * noise
            ts = torch.tensor([self.cfg.decode_timestep], device=z.device, dtype=pipe.vae.dtype)
        video = pipe.vae.decode(z.to(pipe.vae.dtype), ts, return_dict=False)[0]
        return ((video.float() + 1.0) / 2.0).clamp(0.0, 1.0)

    def _coords(self, frames: int, h: int, w: int) -> torch.Tensor:
        pipe = self.pipe
        ids = pipe._prepare_video_ids(1, frames, h, w, patch_size=pipe.transformer_spatial_patch_size,
                                      patch_size_t=pipe.transformer_temporal_patch_size, device=self.device)
        ids = pipe._scale_video_ids(ids, scale_factor=pipe.vae_spatial_compression_ratio,
                                    scale_factor_t=pipe.vae_temporal_compression_ratio, frame_index=0,
                                    device=self.device).float()
        ids[:, 0] = ids[:, 0] * (1.0 / self.cfg.frame_rate)
        return ids

    def velocity(self, z: torch.Tensor, sigma: float | torch.Tensor, prompt: str,
                 clean_tokens: torch.Tensor | None = None) -> torch.Tensor:
        """Velocity prediction for latents z [1,C,F,h,w] at noise level ``sigma`` -> [1,C,F,h,w] float32.

        ``clean_tokens`` [N] bool: tokens given timestep 0 (conditioning frames).
        """
        pipe = self.load()
        F, h, w = z.shape[2:]
        pst, ps = pipe.transformer_temporal_patch_size, pipe.transformer_spatial_patch_size
        x = pipe._pack_latents(z, ps, pst)
        N = x.shape[1]
        t = torch.full((1, N), float(sigma) * 1000.0, device=self.device)
        if clean_tokens is not None:
            t = torch.where(clean_tokens[None], torch.zeros_like(t), t)
        emb, mask = self._prompt(prompt)
        coords = self._coords(F, h, w)
        cfg_on = self.cfg.guidance_scale > 1.0
        if cfg_on:
            nemb, nmask = self._prompt(prompt, negative=True)
            x_in, t_in = torch.cat([x, x]), torch.cat([t, t])
            emb_in, mask_in, coords_in = torch.cat([nemb, emb]), torch.cat([nmask, mask]), torch.cat([coords, coords])
        else:
            x_in, t_in, emb_in, mask_in, coords_in = x, t, emb, mask, coords
        v = pipe.transformer(hidden_states=x_in.to(self.dtype), encoder_hidden_states=emb_in, timestep=t_in,
                             encoder_attention_mask=mask_in, video_coords=coords_in, return_dict=False)[0].float()
        if cfg_on:
            vu, vc = v.chunk(2)
            v = vu + self.cfg.guidance_scale * (vc - vu)
        return pipe._unpack_latents(v, F // pst, h // ps, w // ps, ps, pst)

    def _to_video(self, clip: np.ndarray) -> tuple[torch.Tensor, tuple[int, int, int]]:
        pipe = self.load()
        T, H, W, _ = clip.shape
        shape = padded_shape(T, H, W, pipe.vae_temporal_compression_ratio, pipe.vae_spatial_compression_ratio)
        video = torch.from_numpy(np.ascontiguousarray(clip)).permute(3, 0, 1, 2)[None].float()
        return pad_video(video, shape), shape

    # -- interface -------------------------------------------------------------------------
    @torch.no_grad()
    def refine(self, clip: np.ndarray, mask: MaskLike | None = None, prompt: str = "", seed: int = 0,
               strength: float = 0.5) -> np.ndarray:
        """SDEdit-style rectified-flow refinement of clip [T,H,W,3] -> [T,H,W,3] float32.

        ``mask`` is not used by the model (ComposedV2V handles it around the call).
        """
        clip = check_clip(clip).astype(np.float32, copy=False)
        s = check_strength(strength)
        sigmas = sigma_schedule(s, self.cfg.steps, self.cfg.sigmas)
        self.last_info = {"sigmas": sigmas, "strength": s}
        if s == 0.0:
            log.info("LTX refine: strength 0: clip returned unchanged")
            return clip.copy()
        return self._run(clip, prompt, seed, sigmas)

    @torch.no_grad()
    def generate(self, first_frame: np.ndarray, mask: MaskLike | None = None, prompt: str = "", seed: int = 0,
                 num_frames: int = 49) -> np.ndarray:
        """Image-to-video from pure noise with frame 0 as the clean condition -> [num_frames,H,W,3]."""
        if num_frames < 1:
            raise ValueError(f"num_frames must be >= 1, got {num_frames}")
        clip = np.repeat(np.asarray(first_frame, np.float32)[None], num_frames, axis=0)
        sigmas = sigma_schedule(1.0, self.cfg.steps, self.cfg.sigmas)
        self.last_info = {"sigmas": sigmas, "strength": 1.0}
        return self._run(check_clip(clip), prompt, seed, sigmas)

    def _run(self, clip: np.ndarray, prompt: str, seed: int, sigmas: list[float]) -> np.ndarray:
        T, H, W, _ = clip.shape
        video, shape = self._to_video(clip)
        gen = torch.Generator().manual_seed(int(seed))
        z0 = self._encode(video)
        noise = torch.randn(z0.shape, generator=gen, dtype=torch.float32).to(self.device)
        x = (1.0 - sigmas[0]) * z0 + sigmas[0] * noise
        F, h, w = z0.shape[2:]
        clean = None
        pst, ps = self.pipe.transformer_temporal_patch_size, self.pipe.transformer_spatial_patch_size
        if self.cfg.condition_first_frame and pst == 1:
            per_frame = (h // ps) * (w // ps)               # packed token order: frame, row, column
            clean = torch.zeros(F * per_frame, dtype=torch.bool, device=self.device)
            clean[:per_frame] = True
            x[:, :, :1] = z0[:, :, :1]
        elif self.cfg.condition_first_frame:
            log.warning("condition_first_frame needs a temporal patch size of 1 (got %d): not applied", pst)
        log.info("LTX refine: %d frames %dx%d padded to %s, latents %s, sigmas %s, seed %d",
                 T, W, H, shape, tuple(z0.shape), [round(v, 4) for v in sigmas], seed)
        for s_cur, s_next in zip(sigmas[:-1], sigmas[1:]):
            v = self.velocity(x, s_cur, prompt, clean)
            x = x + (s_next - s_cur) * v
            if clean is not None:
                x[:, :, :1] = z0[:, :, :1]
        if not torch.isfinite(x).all():
            raise RuntimeError(f"LTX refine produced non-finite latents (dtype {self.dtype}, sigmas {sigmas})")
        out = self._decode(x, gen)[0, :, :T, :H, :W].permute(1, 2, 3, 0).cpu().numpy()
        return np.ascontiguousarray(out, dtype=np.float32)

    def sds_loss(self, rendered_subclip: torch.Tensor, prompt: str = "", generator: torch.Generator | None = None,
                 grad_frame: int | None = None) -> torch.Tensor:
        """Paper's SDS term for a rendered clip [T,H,W,3] in [0,1] with T = 4m+1 -> scalar.

        ``L = w(tau) * mean((v_theta(z_tau, tau, l) - (eps - z_0))^2)`` with ``z_0 = E(clip)``,
        ``tau ~ U(tau_min, tau_max)``, ``eps ~ N(0, I)``; the velocity is a stop-gradient (the
        DiT Jacobian is dropped, as in SDS), so the gradient ``2 w (v - eps + z_0) / n`` flows
        through the VAE encoder into one frame only (``grad_frame`` or a random one; memory);
        the other frames are detached. Finite for every tau in [0, 1].
        """
        if not isinstance(rendered_subclip, torch.Tensor) or rendered_subclip.ndim != 4 \
                or rendered_subclip.shape[-1] != 3:
            raise ValueError(f"sds_loss expects a torch tensor [T,H,W,3], got "
                             f"{getattr(rendered_subclip, 'shape', type(rendered_subclip))}")
        T = rendered_subclip.shape[0]
        if T % 4 != 1:
            raise ValueError(f"sds_loss expects 4m+1 frames, got {T}")
        gen = generator if generator is not None else torch.Generator().manual_seed(0)
        pipe = self.load()
        j = int(torch.randint(T, (1,), generator=gen)) if grad_frame is None else int(grad_frame)
        if not 0 <= j < T:
            raise ValueError(f"grad_frame {j} outside [0, {T})")
        sel = torch.zeros(T, 1, 1, 1, dtype=torch.bool, device=rendered_subclip.device)
        sel[j] = True
        clip = torch.where(sel, rendered_subclip, rendered_subclip.detach()).float()
        shape = padded_shape(T, clip.shape[1], clip.shape[2], pipe.vae_temporal_compression_ratio,
                             pipe.vae_spatial_compression_ratio)
        video = pad_video(clip.permute(3, 0, 1, 2)[None], shape)
        z0 = self._encode(video, grad=True)
        lo, hi = self.cfg.sds_tau_min, self.cfg.sds_tau_max
        tau = lo + (hi - lo) * float(torch.rand((), generator=gen))
        eps = torch.randn(z0.shape, generator=gen, dtype=torch.float32).to(z0.device)
        with torch.no_grad():
            z_tau = (1.0 - tau) * z0.detach() + tau * eps
            v = self.velocity(z_tau, tau, prompt)
        w = 1.0 if self.cfg.sds_weighting == "uniform" else tau ** 2
        loss = w * ((v - (eps - z0)) ** 2).mean()
        self.last_info = {"tau": tau, "grad_frame": j, "weight": w}
        if not math.isfinite(float(loss.detach())):
            raise RuntimeError(f"SDS loss is not finite at tau={tau:.4f}")
        return loss
