"""The static fit's budget: levels that follow the capture, explicit keys that win, a minutes budget
that fits its time, the plateau stop, and the accuracy record (what more costs, when to warn)."""
from __future__ import annotations

import pytest

from anigs.static.budget import LEVELS, CaptureSize, StepCost, next_level, parse_budget, plan
from anigs.static.fit import StaticConfig, fit_static, plan_static
from anigs.static.planning import flat_curve
from anigs.static.report import MIN_TEST_PSNR, MIN_TRAIN_PSNR, accuracy_record

from tests.static.test_fit import make_scene, sfm_points

pytestmark = pytest.mark.usefixtures("one_thread")

COST = StepCost()
DEMO = CaptureSize(42, 320, 240)
STREET = CaptureSize(23, 987, 740)


def test_levels_grow_with_the_capture():
    small, street = plan("auto", DEMO, COST, 5000), plan("auto", STREET, COST, 1500)
    assert street.max_gaussians > small.max_gaussians  # more training pixels, more Gaussians
    assert plan("auto", CaptureSize(60, 987, 740), COST, 1500).iterations > street.iterations  # more photos
    assert small.max_gaussians >= LEVELS["auto"].min_gaussians
    for name in ("fast", "auto", "quality"):
        p = plan(name, STREET, COST, 1500)
        lv = LEVELS[name]
        assert lv.min_steps <= p.iterations <= lv.max_steps and lv.min_gaussians <= p.max_gaussians <= lv.max_gaussians
        assert p.densify_stop == int(0.8 * p.iterations) and p.eval_every >= 250
    fast, auto, quality = (plan(n, STREET, COST, 1500) for n in ("fast", "auto", "quality"))
    assert fast.estimated_seconds < auto.estimated_seconds < quality.estimated_seconds
    assert (fast.iterations, fast.max_gaussians) == (1500, 30000)  # anigs 0.7's defaults, whatever the capture
    assert (fast.max_side, auto.max_side, quality.max_side) == (0, 640, 0)  # auto fits at most 640 px


def test_explicit_keys_win_and_are_named():
    p = plan("quality", STREET, COST, 1500, iterations=1000, max_gaussians=12345, densify_stop=700, eval_every=100)
    assert (p.iterations, p.max_gaussians, p.densify_stop, p.eval_every) == (1000, 12345, 700, 100)
    assert p.pinned == ("iterations", "densify.max_gaussians", "densify.stop")
    assert plan("auto", STREET, COST, 1500, max_side=400).pinned == ("max_side",)


def test_minutes_budget_fits_its_time_and_grows_with_it():
    ten, forty = plan(10, STREET, COST, 1500), plan(40.0, STREET, COST, 1500)
    assert ten.estimated_seconds <= 600 and forty.estimated_seconds <= 2400
    assert forty.iterations > ten.iterations and forty.max_gaussians > ten.max_gaussians
    assert ten.level == "10 min"
    slow = COST.calibrated(COST.step(STREET.pixels, 1500) * 3, STREET.pixels, 1500)  # a machine 3x slower
    assert plan(10, STREET, slow, 1500).iterations < ten.iterations


@pytest.mark.parametrize("bad", ["best", "", 0, -5, float("nan"), True, None])
def test_bad_budget_names_the_key(bad):
    with pytest.raises(ValueError, match="static.budget"):
        parse_budget(bad)
    with pytest.raises(ValueError, match="static.budget"):
        StaticConfig.from_dict({"budget": bad})


def test_next_level():
    assert [next_level(n) for n in ("fast", "auto", "quality", "12 min")] == ["auto", "quality", None, "quality"]


def test_flat_curve_only_after_densification():
    rows = lambda *pts: [{"iteration": s, "test_psnr": p} for s, p in pts]
    assert not flat_curve(rows((500, 20.0), (1000, 20.01)), last_densify=800, plateau_db=0.05)  # 500: densifying
    assert flat_curve(rows((1000, 20.0), (1500, 20.01)), last_densify=800, plateau_db=0.05)
    assert flat_curve(rows((1000, 20.0), (1500, 19.5)), last_densify=800, plateau_db=0.05)  # a fall is flat
    assert not flat_curve(rows((1000, 20.0), (1500, 20.2)), last_densify=800, plateau_db=0.05)
    assert not flat_curve(rows((1000, 20.0), (1500, 20.0)), last_densify=800, plateau_db=0.0)  # off


def _metrics(test, train, curve=()):
    return {"test_psnr": test, "test_ssim": 0.5, "train_psnr": train, "train_seconds": 300.0,
            "num_gaussians": 30000, "iterations": 1500, "curve": list(curve)}


def test_accuracy_record_next_level_and_warning():
    p = plan("auto", STREET, COST, 1500)
    curve = [{"iteration": s, "test_psnr": 18 + 0.5 * i} for i, s in enumerate((0, 500, 1000, 1500, 2000))]
    good = accuracy_record(_metrics(26.0, 28.0, curve), p, STREET, COST, 1500)
    assert good["warning"] is None
    assert good["next"]["level"] == "quality" and good["next"]["estimated_minutes"] > p.estimated_seconds / 60
    assert good["next"]["test_psnr_from_curve"] > 20.0  # the curve still rises: more steps extrapolate higher
    poor = accuracy_record(_metrics(MIN_TEST_PSNR - 5, MIN_TRAIN_PSNR - 3), p, STREET, COST, 1500)
    assert "too blurry" in poor["warning"] and "cheapest change" in poor["warning"]
    assert "static.max_side" in poor["warning"] or "static.budget: quality" in poor["warning"]
    overfit = accuracy_record(_metrics(MIN_TEST_PSNR - 4, MIN_TRAIN_PSNR + 4), p, STREET, COST, 1500)
    assert "more photos" in overfit["warning"]
    street = accuracy_record(_metrics(15.0, 23.7), p, STREET, COST, 1500)  # lund-street at auto: under both
    assert "more photos" in street["warning"] and "9 dB better" in street["warning"]


def _scene(n_cams: int, width: int, height: int) -> tuple:
    """A small synthetic capture and its SfM-like points: (photos, cameras, points, colours)."""
    gt, cams, imgs = make_scene(n_cams=n_cams, width=width, height=height)
    return (imgs, cams, *sfm_points(gt, every=3))


def test_fit_reports_plan_and_stops_on_a_flat_curve():
    imgs, cams, p, c = _scene(n_cams=16, width=48, height=36)
    cfg = StaticConfig.from_dict({"iterations": 400, "eval_every": 40, "sh_degree": 0, "plateau_db": 5.0,
                               "densify": {"start": 20, "stop": 60, "every": 20}})
    _, m = fit_static(imgs, cams, p, c, cfg, progress=False)
    # densification ends at step 40; the evaluations at 80 and 120 are both after it: +5 dB is not
    # reached between them, so the fit ends at 120 of its 400 steps
    assert m["iterations"] == 120 and m["plan"]["stopped_early"]
    its = [r["iteration"] for r in m["curve"]]
    assert its[-1] == 120 and 80 in its and max(its) == 120  # (120 twice when the final prune removed splats)
    assert m["plan"]["pinned"] == ["iterations", "densify.stop"] and m["plan"]["estimated_seconds"] > 0
    assert set(m["accuracy"]) >= {"now", "next", "warning", "thresholds"}
    cfg_off = StaticConfig.from_dict({**cfg.__dict__, "densify": cfg.densify.__dict__, "plateau_db": 0.0,
                                   "iterations": 160})
    _, m_off = fit_static(imgs, cams, p, c, cfg_off, progress=False)
    assert m_off["iterations"] == 160 and not m_off["plan"]["stopped_early"]


def test_the_plan_is_decided_before_the_fit_and_the_fit_follows_it():
    imgs, cams, p, c = _scene(n_cams=10, width=64, height=48)
    cfg = StaticConfig.from_dict({"budget": "fast", "max_side": 32, "sh_degree": 0, "plateau_db": 0.0})
    plan_ = plan_static(imgs, cams, p, c, cfg)
    assert cfg.iterations is None and cfg.densify.max_gaussians is None  # the requested config is left as it was
    assert plan_.config.iterations == plan_.schedule.iterations == LEVELS["fast"].max_steps
    assert plan_.config.densify.max_gaussians == plan_.schedule.max_gaussians
    assert plan_.config.eval_every == plan_.schedule.eval_every and plan_.config.densify.stop == plan_.schedule.densify_stop
    assert plan_.as_dict()["fit_size"] == [32, 24] and plan_.size == CaptureSize(8, 64, 48)  # 2 of 10 held out
    assert "at most 1500 steps" in plan_.text()
    with pytest.raises(ValueError, match="the plan was made for another config"):
        fit_static(imgs, cams, p, c, StaticConfig.from_dict({"budget": "fast", "seed": 1}), plan=plan_)
    short = StaticConfig.from_dict({"iterations": 20, "eval_every": 0, "sh_degree": 0, "max_side": 32,
                                 "densify": {"start": 10, "stop": 20, "every": 10}})
    _, m = fit_static(imgs, cams, p, c, short, progress=False, plan=plan_static(imgs, cams, p, c, short))
    _, m_here = fit_static(imgs, cams, p, c, short, progress=False)  # planned inside: the same fit
    assert m["iterations"] == m_here["iterations"] == 20 and m["test_psnr"] == m_here["test_psnr"]
    assert {k: v for k, v in m["plan"].items() if k not in ("estimated_seconds", "estimate_ratio")} == \
        {k: v for k, v in m_here["plan"].items() if k not in ("estimated_seconds", "estimate_ratio")}


def test_fit_downscales_to_its_side_and_measures_there():
    imgs, cams, p, c = _scene(n_cams=10, width=64, height=48)
    cfg = StaticConfig.from_dict({"iterations": 20, "eval_every": 0, "sh_degree": 0, "max_side": 32,
                               "densify": {"start": 10, "stop": 20, "every": 10}})
    g, m = fit_static(imgs, cams, p, c, cfg, progress=False)
    assert m["image_size"] == [32, 24] and m["plan"]["max_side"] == 32
    with pytest.raises(ValueError, match="static.max_side"):
        StaticConfig.from_dict({"max_side": -1})


def test_fit_picture_and_warning_do_not_depend_on_this_machines_speed(tmp_path):
    from anigs.static.report import draw_fit

    p = plan("auto", STREET, COST, 1500)
    curve = [{"iteration": s, "test_psnr": 15 + 0.1 * i, "num_gaussians": 5000 * (i + 1), "train_seconds": 9.0 * s}
             for i, s in enumerate((0, 250, 500, 750))]
    slow = COST.calibrated(COST.step(STREET.pixels, 1500) * 5, STREET.pixels, 1500)  # the same fit, 5x slower
    pictures = []
    for cost, secs in ((COST, 300.0), (slow, 1500.0)):
        m = {**_metrics(15.0, 23.7, curve), "train_seconds": secs, "plan": {**p.as_dict(), "stopped_early": True}}
        m["accuracy"] = accuracy_record(m, p, STREET, cost, 1500)
        draw_fit(m, tmp_path / f"fit{len(pictures)}.png")
        pictures.append(((tmp_path / f"fit{len(pictures)}.png").read_bytes(), m["accuracy"]["warning"]))
    assert pictures[0] == pictures[1]  # the picture and the warning are artifacts: same config, same bytes
    assert m["accuracy"]["next"]["estimated_minutes"] > m["accuracy"]["next"]["reference_cpu_minutes"]
