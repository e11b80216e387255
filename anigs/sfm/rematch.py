"""More matches for a database the first matching left short: loops and look-alike pairs, every pair.

The escalation (:mod:`anigs.sfm.escalate`) adds pairs to the database the first matching wrote;
COLMAP skips the pairs already there, so each step pays only for the new ones.

- :func:`match_loops`: COLMAP's sequential matcher with loop detection, on a vocabulary tree
  built here from the capture's own SIFT descriptors (:func:`build_vocab_tree`: COLMAP's
  default tree is a download, and nothing downloads at run time), plus each photo's
  ``LOOK_ALIKE`` most similar photos by grey thumbnail (:func:`anigs.sfm.plan.similar_pairs`).
- :func:`match_every_pair`: exhaustive matching.
"""
from __future__ import annotations

import logging
import time
from pathlib import Path

import numpy as np

from anigs.sfm.config import SfmConfig
from anigs.sfm.plan import similar_pairs

log = logging.getLogger(__name__)

LOOK_ALIKE = 10  # look-alike (thumbnail) pairs per photo in the loop step
LOOP_IMAGES = 10  # photos the vocabulary tree retrieves per photo
VOCAB_WORDS = 1024  # visual words of the tree built from the capture
VOCAB_MAX_DESCRIPTORS = 50_000  # descriptors the tree is trained on (an even subsample)
VOCAB_ITERATIONS = 20  # k-means iterations, one round (COLMAP's 100 x 3 took 150 s on 20 photos)


def matching_kwargs(cfg: SfmConfig, device) -> dict:
    """Matching and seeded verification options shared by every matcher call."""
    import pycolmap

    match = pycolmap.FeatureMatchingOptions()
    match.num_threads = cfg.matching_num_threads
    match.use_gpu = device == pycolmap.Device.cuda
    verify = pycolmap.TwoViewGeometryOptions()
    verify.ransac.random_seed = cfg.seed
    return {"matching_options": match, "verification_options": verify, "device": device}


def database_stats(database: Path) -> dict:
    """Keypoints per image, verified pairs and inlier matches of ``database``."""
    import pycolmap

    db = pycolmap.Database.open(str(database))
    try:
        return {"keypoints_per_image": db.num_keypoints() / max(db.num_images(), 1),
                "verified_pairs": int(db.num_verified_image_pairs()), "inlier_matches": int(db.num_inlier_matches())}
    finally:
        db.close()


def build_vocab_tree(database: Path, path: Path, num_threads: int) -> Path:
    """A COLMAP visual index (vocabulary tree) trained on the descriptors in ``database``, written to ``path``."""
    import pycolmap

    db = pycolmap.Database.open(str(database))
    try:
        desc = [np.asarray(db.read_descriptors(im.image_id).data) for im in db.read_all_images()]
    finally:
        db.close()
    d = np.concatenate([x for x in desc if len(x)])
    step = max(1, len(d) // VOCAB_MAX_DESCRIPTORS)
    index = pycolmap.VisualIndex.create(128, 64)
    opts = pycolmap.VisualIndex.BuildOptions()
    opts.num_visual_words = min(VOCAB_WORDS, max(16, len(d[::step]) // 40))
    opts.num_iterations = VOCAB_ITERATIONS
    opts.num_rounds = 1
    opts.num_threads = num_threads
    index.build(opts, pycolmap.FeatureDescriptors(pycolmap.FeatureExtractorType.SIFT, d[::step]).to_float())
    index.write(str(path))
    return path


def match_loops(database: Path, image_dir: Path, names: list[str], cfg: SfmConfig, device, work: Path) -> dict:
    """Sequential matching with loop detection (own vocabulary tree) and look-alike pairs."""
    import pycolmap

    t0 = time.perf_counter()
    kw = matching_kwargs(cfg, device)
    tree = build_vocab_tree(database, work / "vocab_tree.bin", cfg.num_threads)
    pairing = pycolmap.SequentialPairingOptions()
    pairing.overlap = cfg.sequential_overlap
    pairing.quadratic_overlap = True
    pairing.loop_detection = True
    pairing.loop_detection_period = 1
    pairing.loop_detection_num_images = min(LOOP_IMAGES, len(names) - 1)
    pairing.vocab_tree_path = str(tree)
    pairing.num_threads = cfg.num_threads
    pycolmap.match_sequential(database, pairing_options=pairing, **kw)
    extra = similar_pairs([Path(image_dir) / n for n in names], LOOK_ALIKE, cfg.sequential_overlap)
    if extra:
        pairs_file = work / "look_alike_pairs.txt"
        pairs_file.write_text("".join(f"{names[i]} {names[j]}\n" for i, j in extra))
        imported = pycolmap.ImportedPairingOptions()
        imported.match_list_path = str(pairs_file)
        pycolmap.match_image_pairs(database, pairing_options=imported, **kw)
    return {"look_alike_pairs": len(extra), "loop_images": pairing.loop_detection_num_images,
            "match_s": time.perf_counter() - t0}


def match_every_pair(database: Path, cfg: SfmConfig, device) -> dict:
    """Exhaustive matching (pairs already in ``database`` are skipped)."""
    import pycolmap

    t0 = time.perf_counter()
    pycolmap.match_exhaustive(database, **matching_kwargs(cfg, device))
    return {"match_s": time.perf_counter() - t0}
