"""Attention checks (catch trials): ours against a visibly blurred copy of itself.

The blurred copy has the same motion, so only the visual-quality answer is scored: a participant
who prefers the blurred copy was not looking. The tally excludes participants who fail more
catch trials than allowed, and never counts catch answers in Table 4.
"""
from __future__ import annotations

from pathlib import Path

from anigs.video import read_mp4, write_mp4

CATCH = "catch"  # the variant name of the blurred copy in trials and answers
CATCH_QUESTION = "quality"


def blur_sigma(width: int, height: int) -> float:
    """Gaussian blur in pixels: 1.5% of the diagonal (obvious at any size), at least 1.5 px."""
    return max(1.5, 0.015 * (width * width + height * height) ** 0.5)


def make_catch_video(src: str | Path, dst: str | Path, fps: float) -> float:
    """Write a blurred copy of ``src`` to ``dst``; return the blur sigma used."""
    from scipy.ndimage import gaussian_filter


    clip = read_mp4(src)
    sigma = blur_sigma(clip.shape[2], clip.shape[1])
    write_mp4(dst, gaussian_filter(clip, sigma=(0, sigma, sigma, 0), mode="nearest"), fps=max(1, round(fps)))
    return sigma


def is_catch(answer_or_trial: dict) -> bool:
    return answer_or_trial.get("other") == CATCH


def catch_failed(answer: dict) -> bool:
    """A scored catch answer that prefers the blurred copy."""
    return is_catch(answer) and answer["question"] == CATCH_QUESTION and answer["chosen"] == CATCH
