"""A tiny random-weight LTX-Video stack for offline tests and benchmarks of the LTX prior's real
code path (:mod:`anigs.refine.prior.ltx`)."""
from __future__ import annotations

from pathlib import Path

import torch

from anigs.refine.prior.ltx import import_diffusers


def save_tiny_random_stack(path: str | Path, seed: int = 0) -> Path:
    """Write a tiny random-weight LTX-Video stack (same classes and VAE ratios as the real model:
    32x spatial, 8x temporal; 8 latent channels, 1 transformer layer, tiny T5 and a sentencepiece
    tokenizer trained on a few words) to ``path`` in the layout :meth:`LTXPrior.load` expects.

    For offline tests and benchmarks of the real code path; produces meaningless videos.
    """
    import sentencepiece as spm
    import transformers

    Pipe, _ = import_diffusers()
    import diffusers

    path = Path(path)
    path.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(seed)
    tr = diffusers.LTXVideoTransformer3DModel(in_channels=8, out_channels=8, num_attention_heads=2,
                                              attention_head_dim=8, cross_attention_dim=16, num_layers=1,
                                              caption_channels=16)
    vae = diffusers.AutoencoderKLLTXVideo(
        latent_channels=8, block_out_channels=(8, 8, 8, 8), decoder_block_out_channels=(8, 8, 8, 8),
        layers_per_block=(1, 1, 1, 1, 1), decoder_layers_per_block=(1, 1, 1, 1, 1),
        spatio_temporal_scaling=(True, True, True, False), decoder_spatio_temporal_scaling=(True, True, True, False),
        decoder_inject_noise=(False,) * 5, upsample_residual=(False,) * 4, upsample_factor=(1,) * 4,
        timestep_conditioning=False, patch_size=4, patch_size_t=1)
    te = transformers.T5EncoderModel(transformers.T5Config(vocab_size=64, d_model=16, d_kv=8, d_ff=32,
                                                           num_layers=1, num_heads=2))
    words = ["trees sway gently in the wind", "grass waves", "flowers bob in a breeze", "leaves flutter"] * 20
    spm.SentencePieceTrainer.train(sentence_iterator=iter(words), model_prefix=str(path / "_sp"), vocab_size=40,
                                   pad_id=0, eos_id=1, unk_id=2, bos_id=-1, hard_vocab_limit=False, minloglevel=2)
    tok = transformers.T5Tokenizer(vocab_file=str(path / "_sp.model"), extra_ids=0, legacy=False)
    pipe = Pipe(transformer=tr, vae=vae, scheduler=diffusers.FlowMatchEulerDiscreteScheduler(),
                text_encoder=te, tokenizer=tok)
    pipe.save_pretrained(path / "model")
    return path / "model"
