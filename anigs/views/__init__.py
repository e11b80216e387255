"""Incremental viewpoint expansion: the queue of views the dataset-model loop adds.

Paper ("Incremental viewpoint expansion"): choose N camera locations with farthest-point
sampling among candidate positions, favouring those that see the regions of interest
(the dynamic Gaussians); order them counter-clockwise around the regions; at each location
three yaw directions 0, +90, -90 degrees with a fixed 95 degree FOV; the queue goes location
by location, directions 0 -> 90 -> -90.

Conventions: the world "up" is +z (``up="z"``) or estimated from the candidate cameras
(``up="auto"``: mean of their image-up axes). Yaw is measured counter-clockwise seen from
above (right-handed about up): +90 turns left. The forward direction (yaw 0) at a location
is, by ``forward``: ``best`` the heading whose views see the most ROI Gaussians (estimated
from a 4-view panorama rendered at the location), ``centroid`` the horizontal direction to
the ROI centroid, or ``camera`` the horizontal direction of the capture camera there.

Layouts (:func:`anigs.geometry.classify_layout`, ``layout: auto``): the paper's schedule
assumes a walk-through that surrounds the camera (``walk``): there it is kept, yaw 0 at the
``forward`` heading. In a forward-facing capture (all cameras on one side looking the same
way) or an inward orbit, yaw 0 looks at the ROI centroid, the pitch is the capture's median
pitch and the FOV at most the photos' (``match_capture_fov``: a 95 degree view from a
forward-facing capture position mostly sees what no photo saw), and the +-90 directions are
only kept where they pass the coverage test.

Scene coverage of a view: the fraction of its pixels with accumulated alpha >= ``coverage_alpha``
rendering only the Gaussians observed (visible) in >= ``min_observations`` capture photos.
Every queued view reaches ``min_coverage``. A direction that fails is replaced, in this
order, by: the same yaw pitched down in ``pitch_step_deg`` steps (to ``max_pitch_drop_deg``;
sky above low walls), then yaws moved towards the ROI (``yaw_steps`` of the way) with those
pitches, then the requested yaw at an extra location (the next farthest-point candidates).
Rejected directions are kept in :attr:`ViewPlan.rejected` (and drawn on the top-down map);
they are never queued. A slot no location can fill is left out (logged).

Negligible views (``min_dynamic_fraction``, :func:`drop_negligible`): the dynamic fraction of a
view is the share of its width x height pixels in the dynamic mask of the ROI, i.e. the pixels
the masks stage would mark: all Gaussians rendered, alpha >= 0.3 and the ROI Gaussians carrying
>= 0.5 of it (:func:`anigs.render.labels.dynamic_masks`; occluded ROI counts for nothing). A
placed view below ``min_dynamic_fraction`` is not queued; it is listed in ``views.json``
(``dynamic_fraction.dropped``, with its fraction and the reason) and the kept views are numbered
v00, v01, ... consecutively. If every view is negligible, the one with the largest fraction is
kept (``dynamic_fraction.kept_below_min``). Nothing is dropped under the whole-scene ROI
fallback (nothing moves), and with ``min_dynamic_fraction: 0`` nothing is computed (the
``views.json`` has no ``dynamic_fraction`` section). :func:`anigs.stages.targets.queued_view_count`
reads the queue's size back (json only, no torch: the workflow imports it).

ROI coverage counts a Gaussian as seen by a view when it is visible there
(:mod:`anigs.masks.lift`: ``weight`` = it contributes at least ``min_weight`` pixels of
blending weight to the rendered image; ``depth`` = its centre passes a depth test).
"""
from __future__ import annotations

from anigs.views.candidates import (azimuth_deg, ccw_order, farthest_point_order, in_wedges, location_cameras,
                                    make_candidates, score_candidate, view_camera)
from anigs.views.config import ViewsConfig
from anigs.views.coverage import (capture_pitch_deg, dynamic_fraction, observation_counts, replacement_directions,
                                  scene_coverage)
from anigs.views.plan import ViewPlan, cameras_from_views, drop_negligible, plan_views

__all__ = ["ViewsConfig", "ViewPlan", "plan_views", "cameras_from_views", "drop_negligible",
           "view_camera", "farthest_point_order", "ccw_order", "make_candidates", "location_cameras",
           "score_candidate", "in_wedges", "azimuth_deg", "observation_counts", "scene_coverage",
           "capture_pitch_deg", "replacement_directions", "dynamic_fraction"]
