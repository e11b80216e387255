"""Scene geometry shared by the stages: up direction, ground plane, scene extent, capture layout,
quaternions (one module each: basics, planes, up, ground, layout, quaternion), the real spherical harmonics
of 3DGS colours (``sh``: the renderer's basis), and a similarity
applied to a Gaussian set, SH colours rotated (``transform``: import it from
:mod:`anigs.geometry.transform`).

One home for what used to be three estimates (``views.estimate_up``, ``align.estimate_up``,
``masks.vegetation.estimate_ground``, now ``ground.ground_plane`` on top of ``ground.estimate_ground``).

Up (:func:`estimate_up`) combines three cues:

1. **Camera axes.** A photo is taken upright, in landscape or portrait: the world up lies
   (up to the camera's pitch) along one of the four image axes -y, +x, +y, -x (roll 0, 90,
   180, 270 degrees), and the other image axis is horizontal. Each camera picks the roll that
   fits a candidate up best; the candidate is scored by how horizontal the chosen axes are.
2. **Gravity cue of the photo orientation.** Most photos are upright (roll 0; a portrait photo
   imported with its EXIF orientation is upright too), sideways photos (+-90) are less likely,
   upside-down ones rare; and cameras are mostly held near level (a pitch penalty).
3. **Point cloud planes.** Dominant planar structure is either ground/ceiling (normal along
   up) or wall (normal horizontal). This settles the direction the cameras cannot: when all
   cameras face the same way (forward-facing, one facade) their horizontal axes are parallel
   and up is only known within a plane; without planes the mean image-up axis is used there,
   which keeps the cameras' common pitch in the estimate.

The best candidate of a dense search is refined in closed form (the smallest eigenvector of
the horizontal axes' scatter, as in the former ``align.estimate_up``). When two solutions
more than 30 degrees apart score within ``UpConfig.min_margin``, or there are no cameras, the
documented fallback applies, logged as a warning, ``UpEstimate.fallback`` set: when the tie
is between up and -up (every photo sideways, no ground to tell), the sign for which the
cameras' median pitch looks down; otherwise every photo upright (roll 0), up = the refined
mean image-up axis; +z without cameras.

Ground (:func:`estimate_ground`): the densest thin layer of points below the median height
(the former ``estimate_ground``). When the cameras are not above that layer (a capture looking
up at a building: ledges and eaves are dense layers), only points below the cameras are
searched; when none are (a close-up without visible ground), the fallback plane lies just
below all content, with ``fallback`` set and a warning logged. It never raises for geometry.

Layout (:func:`classify_layout`): forward-facing, orbit (inward) or walk (walk-through /
outward), from the cameras' horizontal viewing directions, where their optical axes meet and
where the content lies relative to the camera ring.
"""
from anigs.geometry.basics import Z_UP, angle_deg, camera_axes, fibonacci_sphere, horizontal_basis, roll_axes, unit
from anigs.geometry.extent import box_diagonal, scene_extent
from anigs.geometry.ground import GroundEstimate, estimate_ground
from anigs.geometry.layout import LAYOUTS, Layout, axis_hits, classify_layout, rays_meet
from anigs.geometry.planes import observed_points, plane_cost, point_normals
from anigs.geometry.quaternion import axis_angle_to_quat, quat_from_matrix, quat_multiply, quat_to_rotmat
from anigs.geometry.up import ROLL_PRIOR, UpConfig, UpEstimate, estimate_up, refine_up

__all__ = ["UpConfig", "UpEstimate", "estimate_up", "refine_up", "roll_axes", "camera_axes", "GroundEstimate",
           "estimate_ground", "scene_extent", "box_diagonal", "Layout", "LAYOUTS", "classify_layout", "rays_meet", "axis_hits",
           "horizontal_basis", "unit", "angle_deg", "observed_points", "fibonacci_sphere", "point_normals", "plane_cost", "Z_UP", "ROLL_PRIOR",
           "axis_angle_to_quat", "quat_from_matrix", "quat_multiply", "quat_to_rotmat"]
