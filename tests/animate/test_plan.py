"""Round arithmetic of the unrolled dataset-model loop."""
from __future__ import annotations

import pytest

from anigs.animate.plan import RoundPlan


def test_full_model_adds_views_round_by_round():
    p = RoundPlan(num_views=12, views_per_round=3)
    assert p.num_rounds == 4
    assert p.dataset(1) == ["v00", "v01", "v02"]
    assert p.dataset(4) == p.view_ids() and len(p.dataset(4)) == 12
    assert p.render_model_round(1) == 0 and p.render_model_round(3) == 2
    assert p.target_round(3, "v01") == 3


def test_uneven_queue_and_refresh_rounds():
    p = RoundPlan(num_views=5, views_per_round=2, extra_rounds=2)
    assert p.num_rounds == 5
    assert p.dataset(3) == p.dataset(5) == p.view_ids()
    assert p.first_round("v04") == 3


def test_ablations():
    no_exp = RoundPlan(num_views=6, views_per_round=3, view_expansion=False)
    assert no_exp.dataset(1) == no_exp.view_ids() and no_exp.num_rounds == 2
    no_upd = RoundPlan(num_views=6, views_per_round=3, dataset_update=False)
    assert no_upd.render_model_round(2) == 0
    assert no_upd.target_round(2, "v01") == 1 and no_upd.target_round(2, "v04") == 2


def test_bad_plans():
    with pytest.raises(ValueError, match="at least one view"):
        RoundPlan(num_views=0)
    with pytest.raises(ValueError, match="round 3"):
        RoundPlan(num_views=2, views_per_round=1).dataset(3)
    with pytest.raises(KeyError, match="v09"):
        RoundPlan(num_views=2).first_round("v09")
