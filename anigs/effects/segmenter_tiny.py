"""Random-weight SegFormer folders for offline tests and checks of the segmenter's real code path
(:mod:`anigs.effects.segmenter`): the same classes and files as a real checkpoint, meaningless output."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import torch


def save_random_segformer(path: str | Path, labels: Sequence[str], size: tuple[int, int] = (64, 64),
                          tiny: bool = True, seed: int = 0) -> Path:
    """Write a random-weight ``SegformerForSemanticSegmentation`` with ``id2label`` = ``labels`` and its
    ``SegformerImageProcessor`` (input ``size`` (height, width)) to ``path`` (config.json,
    model.safetensors, preprocessor_config.json), the layout ``effects.segmenter.weights`` names.

    ``tiny``: 2 encoder blocks of width 8 and 16 (a few thousand weights); else SegFormer-B0's
    architecture (3.7M weights, as ``nvidia/segformer-b0-finetuned-ade-512-512``)."""
    from transformers import SegformerConfig, SegformerForSemanticSegmentation, SegformerImageProcessor

    path = Path(path)
    path.mkdir(parents=True, exist_ok=True)
    id2label = {i: str(name) for i, name in enumerate(labels)}
    kw = dict(num_encoder_blocks=2, depths=[1, 1], sr_ratios=[2, 1], hidden_sizes=[8, 16], patch_sizes=[7, 3],
              strides=[4, 2], num_attention_heads=[1, 1], mlp_ratios=[2, 2], decoder_hidden_size=16) if tiny else {}
    cfg = SegformerConfig(id2label=id2label, label2id={v: k for k, v in id2label.items()}, **kw)
    torch.manual_seed(seed)
    SegformerForSemanticSegmentation(cfg).save_pretrained(path)
    SegformerImageProcessor(size={"height": int(size[0]), "width": int(size[1])}).save_pretrained(path)
    return path
