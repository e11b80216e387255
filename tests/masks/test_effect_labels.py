"""The per-Gaussian effect labels the masks stage writes for the update's per-effect settings."""
import numpy as np
import pytest

from anigs.effects.labels import effect_label_ids as label_of
from anigs.effects.labels import effect_labels


def test_labels_follow_the_chosen_regions_and_fill_from_the_nearest():
    means = np.array([[0, 0, 0], [0.1, 0, 0], [5, 0, 0], [5.1, 0, 0], [9, 9, 9], [5.05, 0, 0]], float)
    dynamic = np.array([True, True, True, True, False, True])
    regions = np.array([0, -1, 1, 3, 1, -1])  # foliage, none, grass, water (not chosen), grass (static), none
    labels, counts = effect_labels(dynamic, regions, [0, 1], means)
    assert labels.dtype == np.int8
    # foliage 1, its unlabelled neighbour 1, grass 2, the unchosen water region -> nearest (grass) 2,
    # the static Gaussian 0, the last one next to the grass 2
    assert labels.tolist() == [1, 1, 2, 2, 0, 2]
    assert counts == {"from_regions": 2, "nearest": 3, "default": 0}
    assert ((labels != 0) == dynamic).all()
    assert label_of()["foliage_sway"] == 1 and label_of()["grass_wave"] == 2 and label_of()["flower_bob"] == 3


def test_no_labelled_region_falls_back_to_foliage_and_shapes_are_checked():
    labels, counts = effect_labels(np.array([True, False]), np.array([-1, -1]), [1], np.zeros((2, 3)))
    assert labels.tolist() == [1, 0] and counts["default"] == 1
    with pytest.raises(ValueError, match="must agree"):
        effect_labels(np.array([True]), np.array([0, 1]), [0], np.zeros((1, 3)))
