"""Made-thing decoys (issue 47): green made things under prompts that name plants, with labels.

Built through :func:`anigs.synth.decoys.build_decoy` (names ``MADE_DECOYS``); the parts (``extras["decoy"]``)
continue the numbering of :data:`anigs.synth.decoy_parts.DECOY_PARTS`, and none of them may move. Scenes (z up,
metres, ground z = 0):

- ``yard``: a paved castle courtyard (grey paving, two pale plastered facades with sandstone window surrounds
  and slate roofs), a green tractor (hood, cab with dark glass, fenders, black tyres with yellow rims), three
  green wheelie bins against a facade and a leafless tree (trunk, bare branches and twigs) trained on the wall.
  Like the real capture (``courtyard-p30``), the facades hold most Gaussians: the paving covers a quarter of
  each view but holds 1.3% of the Gaussians (large flat ones), so the ground is not trusted ("ground uncertain:
  only 2.6% of the Gaussians lie on the lowest dense layer"). No real effect.
- ``hall``: an indoor hall seen from standing height looking up (the dark green-grey floor is about 2% of each
  view): four smooth green painted pillars, an orange wooden table with a carton printed with leaves (leaf
  shapes in greens with dark gaps, a few printed red and yellow fruits), and a real potted plant (terracotta
  pot, mostly out of view, and a leafy crown: label ``foliage``, which must move). The ground is not trusted
  (the lowest dense layer is the carton's top or the table's, 12-40% of the Gaussians lie under it). Real
  effects: the plant's foliage.

The made things' sampling steps scale with ``sqrt(12000 / n)``; scene seeds change the tree's branches, the
bins' places, the carton's print and the plant's leaves.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

from anigs.cameras import Camera
from anigs.geometry.quaternion import quat_from_matrix
from anigs.synth.decoy_parts import Tagged, arc_cameras, noise_colour
from anigs.synth.scene import SURFACE_OPACITY, Noise, jittered_grid, shade, frame_from_normal

GREEN_PAINT = np.array([0.10, 0.46, 0.12])   # the tractor's and the bins' saturated green
PILLAR_GREEN = np.array([0.11, 0.50, 0.26])  # the hall's painted pillars
DARK = np.array([0.07, 0.07, 0.075])
MADE_DECOYS = ("yard", "hall")  # green made things under prompts that name plants (issue 47)


def _flat(colour) -> Callable[[np.ndarray], np.ndarray]:
    """A colour function of one colour with a faint sheen."""
    c = np.asarray(colour, float)
    return lambda p: c * (1 + 0.04 * np.sin(p[:, :1] * 23.0 + p[:, 1:2] * 17.0))


def _local(p: np.ndarray, origin, yaw: float) -> np.ndarray:
    """Points [M,3] in the frame of a part turned by ``yaw`` about z at ``origin``."""
    c, s = math.cos(yaw), math.sin(yaw)
    d = p - np.asarray(origin, float)
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], d[:, 2]])


def _disc(T: Tagged, part: str | None, centre, normal, radius: float, step: float,
          colour_fn: Callable[[np.ndarray], np.ndarray], label: str) -> None:
    """Flat Gaussians on a disc facing ``normal``; ``colour_fn(rho [M])`` (distance from the centre / radius)."""
    B = T.B
    ab = jittered_grid(B.rng, (-radius, -radius), (radius, radius), (step, step))
    rho = np.hypot(ab[:, 0], ab[:, 1]) / radius
    ab, rho = ab[rho <= 1], rho[rho <= 1]
    nrm = np.tile(np.asarray(normal, float), (len(ab), 1))
    R = frame_from_normal(nrm)
    means = np.asarray(centre, float) + ab[:, :1] * R[:, :, 0] + ab[:, 1:] * R[:, :, 1]
    scales = np.tile([0.72 * step, 0.72 * step, 0.002], (len(ab), 1))
    cols = B.jitter(colour_fn(rho)) * shade(nrm)[:, None]
    T.tag(part, B.add, means, scales, quat_from_matrix(R), cols, SURFACE_OPACITY, label)


def _castle_wall(rng: np.random.Generator, height: float, door_at: float | None) -> Callable:
    """Pale plaster with a stone plinth, two rows of windows in sandstone surrounds, a cornice and, at
    ``door_at`` (along the wall), an arched doorway: f(ab [M,2]) -> colours [M,3]."""
    noise = Noise(rng, 2, 0.3, 6.0)
    tone = np.array([0.55, 0.55, 0.53]) * rng.uniform(0.8, 1.12, (331, 1))

    def f(ab: np.ndarray) -> np.ndarray:
        a, z = ab[:, 0], ab[:, 1]
        c = np.array([0.80, 0.80, 0.83]) * (1 + 0.04 * noise(ab))[:, None]
        row = np.floor(z / 0.33).astype(np.int64)
        col = np.floor(a / 0.7 + 0.5 * (row % 2)).astype(np.int64)
        plinth = z < 1.0
        c[plinth] = tone[(row * 7919 + col * 104729)[plinth] % 331]
        for z0, z1 in ((1.7, 3.1), (4.0, 5.4)):
            for xc in np.arange(1.3, a.max() - 0.8, 2.3):
                if door_at is not None and z0 < 3 and abs(xc - door_at) < 2.0:
                    continue
                dx, sky = np.abs(a - xc), np.clip((z - z0) / (z1 - z0), 0, 1)
                c[(dx < 0.7) & (z > z0 - 0.16) & (z < z1 + 0.16)] = [0.78, 0.63, 0.53]
                glass = (dx < 0.52) & (z > z0) & (z < z1)
                g = np.column_stack([0.13 + 0.2 * sky, 0.15 + 0.22 * sky, 0.19 + 0.26 * sky])
                c[glass] = g[glass]
                c[glass & ((dx < 0.03) | (dx > 0.48) | (np.abs(z - z0 - 0.65 * (z1 - z0)) < 0.03))] = [0.9, 0.9, 0.88]
        if door_at is not None:
            dx = np.abs(a - door_at)
            arch = (dx < 1.45) & (z < 2.5 + 0.6 * np.sqrt(np.clip(1 - (dx / 1.45) ** 2, 0, 1)))
            c[arch] = [0.76, 0.6, 0.52]
            inner = (dx < 1.2) & (z < 2.5 + 0.5 * np.sqrt(np.clip(1 - (dx / 1.2) ** 2, 0, 1)))
            c[inner] = [0.16, 0.14, 0.13]
        c[z > height - 0.35] = [0.7, 0.68, 0.64]
        return c
    return f


def _machine(T: Tagged, at, yaw: float, step: float) -> None:
    """A green tractor at ``at`` (x, y) heading ``yaw``: hood, chassis, cab with dark glass, fenders, exhaust,
    wheels (black tyres, yellow rims)."""
    B = T.B
    c, s = math.cos(yaw), math.sin(yaw)
    ex, ey = np.array([c, s, 0.0]), np.array([-s, c, 0.0])
    P = lambda u, v, z: np.array([at[0], at[1], z]) + u * ex + v * ey
    paint = _flat(GREEN_PAINT)
    hood_at, cab_at = P(0.85, 0, 0.75), P(-0.7, 0, 1.2)

    def hood(p: np.ndarray) -> np.ndarray:
        q, col = _local(p, hood_at, yaw), paint(p)
        col[q[:, 0] > 1.03] = DARK * 1.6  # the grille
        vents = (np.abs(q[:, 1]) > 0.44) & (q[:, 0] > 0.3) & (q[:, 0] < 0.9) & (np.sin(q[:, 2] * 60) > 0.3)
        col[vents] = DARK
        return col

    def cab(p: np.ndarray) -> np.ndarray:
        q, col = _local(p, cab_at, yaw), paint(p)
        glass = (q[:, 2] > 0.45) & (q[:, 2] < 1.5) & ~((np.abs(q[:, 0]) > 0.5) & (np.abs(q[:, 1]) > 0.55))
        sky = np.clip((q[:, 2] - 0.45) / 1.05, 0, 1)[glass, None]
        col[glass] = np.array([0.1, 0.12, 0.14]) + 0.12 * sky
        return col
    T.tag("machine", B.box, hood_at, (2.1, 0.9, 0.8), yaw, step, hood, "clutter")
    T.tag("machine", B.box, P(0.8, 0, 0.42), (2.0, 0.6, 0.33), yaw, step, _flat(DARK * 1.5), "clutter")
    T.tag("machine", B.box, cab_at, (1.2, 1.3, 1.6), yaw, step, cab, "clutter")
    for side in (-1, 1):
        T.tag("machine", B.box, P(-0.7, side * 0.95, 1.45), (1.5, 0.6, 0.06), yaw, step, paint, "clutter")
    T.tag("machine", B.cylinder, P(1.3, 0.3, 1.55), P(1.3, 0.3, 2.5), 0.05, 0.05, step / 2, _flat(DARK), "clutter")
    tread = lambda tv: DARK * (1 + 0.5 * (np.sin(tv[:, :1] * 40) > 0.5))
    rim = lambda rho: np.where((rho < 0.62)[:, None] & (rho > 0.2)[:, None], [[0.9, 0.74, 0.1]], [DARK * 1.3])
    for u, r, w, off in ((-0.7, 0.78, 0.5, 0.95), (1.4, 0.48, 0.35, 0.72)):
        for side in (-1, 1):
            a, b = P(u, side * (off - w / 2), r), P(u, side * (off + w / 2), r)
            T.tag("machine", B.cylinder, a, b, r, r, step, tread, "clutter")
            _disc(T, "machine", P(u, side * (off + w / 2 + 0.004), r), side * ey, r, 0.6 * step, rim, "clutter")


def _bins(T: Tagged, sites: list, step: float) -> None:
    """Green wheelie bins at ``sites`` [(x, y, yaw, height)], fronts towards -y turned by yaw: body, lid, handle,
    wheels, a sticker."""
    B = T.B
    for x, y, yaw, h in sites:
        at = np.array([x, y, 0.0])

        def body(p: np.ndarray, at=at, yaw=yaw) -> np.ndarray:
            q, col = _local(p, at, yaw), _flat(GREEN_PAINT * 1.05)(p)
            col[(q[:, 1] < -0.35) & (np.abs(q[:, 0]) < 0.14) & (np.abs(q[:, 2] - 0.7) < 0.09)] = [0.9, 0.9, 0.88]
            return col
        n0 = len(B.parts)
        T.tag("bins", B.box, at, (0.6, 0.72, h), yaw, step, body, "clutter")
        del B.parts[n0], T.tags[n0]  # the body's top (the box's first face) lies hidden under the lid
        T.tag("bins", B.box, at + [0, 0.02, h], (0.64, 0.8, 0.07), yaw, 1.3 * step, _flat(GREEN_PAINT * 0.8),
              "clutter")
        c, s = math.cos(yaw), math.sin(yaw)
        back = at + 0.4 * np.array([-s, c, 0.0])
        T.tag("bins", B.box, back + [0, 0, h - 0.05], (0.5, 0.06, 0.06), yaw, step / 2, _flat(DARK * 1.4), "clutter")
        for k in (-1, 1):
            w = back + 0.25 * k * np.array([c, s, 0.0]) + [0, 0, 0.1]
            T.tag("bins", B.cylinder, w - 0.05 * np.array([c, s, 0]), w + 0.05 * np.array([c, s, 0]), 0.1, 0.1,
                  step / 2, _flat(DARK), "clutter")


def _bare_tree(T: Tagged, at, step: float) -> None:
    """A leafless tree trained on a wall (the x-z plane at ``at``): trunk, six bare branches, twigs."""
    B, rng = T.B, T.B.rng
    bark = lambda tv: np.array([0.36, 0.33, 0.3]) * (1 + 0.15 * np.sin(tv[:, 1:2] * 13 + tv[:, :1] * 3))
    base = np.array([at[0], at[1], 0.0])
    top = base + [0, 0, 2.0]
    T.tag("bare_tree", B.cylinder, base, top, 0.14, 0.1, step, bark, "trunk")
    for k in range(6):
        ang = math.radians(-68 + 27 * k + rng.uniform(-8, 8))
        d = np.array([math.sin(ang), rng.uniform(-0.2, 0.05), math.cos(ang)])
        d /= np.linalg.norm(d)
        length = rng.uniform(1.4, 2.2)
        T.tag("bare_tree", B.cylinder, top, top + d * length, 0.06, 0.025, step, bark, "trunk")
        side = np.cross(d, [0, 1.0, 0])
        for i, t in enumerate((0.4, 0.75)):
            p = top + d * length * t
            twig = d + (1 if (i + k) % 2 else -1) * 0.9 * side + [0, rng.uniform(-0.2, 0.1), 0.3]
            twig /= np.linalg.norm(twig)
            T.tag("bare_tree", B.cylinder, p, p + twig * rng.uniform(0.5, 0.9), 0.022, 0.01, step, bark, "trunk")


def _yard(T: Tagged, n: int) -> None:
    rng, B = T.B.rng, T.B
    X0, X1, Y0, Y1, H = -7.0, 7.0, -7.0, 6.5, 6.5
    s = math.sqrt((X1 - X0) * (Y1 - Y0) / (0.014 * n))  # a uniform pavement: a few large flat Gaussians
    T.tag("paving", B.surface, (X0, Y0, 0.0), (1, 0, 0), (0, 1, 0), (X1 - X0, Y1 - Y0), (s, s),
          noise_colour(rng, (0.42, 0.42, 0.44), 0.1), "ground", thin=0.003, scale_frac=0.8)
    s = math.sqrt(((X1 - X0) + (Y1 - Y0)) * H / (0.6 * n))
    T.tag(None, B.surface, (X0, Y1, 0.0), (1, 0, 0), (0, 0, 1), (X1 - X0, H), (s, s), _castle_wall(rng, H, None),
          "building")
    T.tag(None, B.surface, (X1, Y1, 0.0), (0, -1, 0), (0, 0, 1), (Y1 - Y0, H), (s, s), _castle_wall(rng, H, 9.0),
          "building")
    a, slate = math.radians(40), noise_colour(rng, (0.3, 0.31, 0.35), 0.08)
    T.tag(None, B.surface, (X0, Y1, H), (1, 0, 0), (0, math.cos(a), math.sin(a)), (X1 - X0, 2.5), (1.4 * s, 1.4 * s),
          slate, "building")
    T.tag(None, B.surface, (X1, Y1, H), (0, -1, 0), (math.cos(a), 0, math.sin(a)), (Y1 - Y0, 2.5), (1.4 * s, 1.4 * s),
          slate, "building")
    k = math.sqrt(12000 / n)  # the made things' steps at the default budget
    _machine(T, (1.6, 3.4), 0.45, 0.16 * k)
    _bins(T, [(6.45, 4.0 + 0.75 * i + rng.uniform(-0.05, 0.05), -math.pi / 2 + rng.uniform(-0.15, 0.15), h)
              for i, h in enumerate((0.93, 1.0, 0.86))], 0.1 * k)
    _bare_tree(T, (-2.6, 6.3), 0.12 * k)


def _leaf_print(rng: np.random.Generator, centre, size) -> Callable[[np.ndarray], np.ndarray]:
    """A carton's print: overlapping leaves (pointed shapes in several greens, a lighter midrib) on dark green
    gaps, a few red and yellow fruits: f(points [M,3]) -> colours [M,3]."""
    m = 220
    lo = np.asarray(centre, float) - [size[0] / 2 + 0.05, size[1] / 2 + 0.05, 0.0]
    c = lo + rng.uniform(0, 1, (m, 3)) * (np.asarray(size) + [0.1, 0.1, 0.05])
    axis = rng.normal(size=(m, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    length = rng.uniform(0.06, 0.12, m)
    greens = np.array([[0.18, 0.45, 0.14], [0.26, 0.55, 0.2], [0.12, 0.36, 0.12], [0.34, 0.58, 0.16]])
    tone = greens[rng.integers(len(greens), size=m)] * rng.uniform(0.85, 1.15, (m, 1))
    fruit = lo + rng.uniform(0, 1, (9, 3)) * (np.asarray(size) + [0.1, 0.1, 0.05])
    fruit_col = np.array([[0.85, 0.16, 0.1], [0.95, 0.72, 0.12]])[np.arange(9) % 2]

    def f(p: np.ndarray) -> np.ndarray:
        out = np.tile([0.05, 0.13, 0.07], (len(p), 1))
        d = p[:, None, :] - c[None]
        along = (d * axis[None]).sum(-1) / length[None]
        perp = np.linalg.norm(d - along[..., None] * length[None, :, None] * axis[None], axis=-1) / length[None]
        inside = (np.abs(along) < 1) & (perp < 0.38 * (1 - along ** 2))
        hit = inside.any(1)
        top = m - 1 - np.argmax(inside[:, ::-1], axis=1)  # the last printed leaf lies on top
        rows = np.flatnonzero(hit)
        out[hit] = tone[top[hit]]
        rib = perp[rows, top[hit]] < 0.04
        out[rows[rib]] *= 1.35
        dist = np.linalg.norm(p[:, None, :] - fruit[None], axis=-1)
        near = dist.min(1) < 0.035
        out[near] = fruit_col[dist.argmin(1)[near]]
        return out
    return f


def _hall(T: Tagged, n: int) -> None:
    rng, B = T.B.rng, T.B
    X, Y0, Y1, H = 6.0, -6.0, 6.0, 4.5
    s = math.sqrt((2 * X * H + 2 * (Y1 - Y0) * H + 2 * X * (Y1 - Y0)) / (0.42 * n))
    plaster = noise_colour(rng, (0.86, 0.84, 0.79), 0.03)

    def back(ab: np.ndarray) -> np.ndarray:
        c = plaster(ab)
        c[ab[:, 1] < 1.1] = [0.62, 0.6, 0.55]
        for xc in (2.5, 6.0, 9.5):
            win = (np.abs(ab[:, 0] - xc) < 0.8) & (ab[:, 1] > 1.3) & (ab[:, 1] < 3.8)
            c[win] = np.array([0.78, 0.85, 0.92]) * (1 - 0.1 * (np.abs(ab[win, 0] - xc) < 0.04))[:, None]
        return c

    def ceiling(ab: np.ndarray) -> np.ndarray:
        c = np.tile([0.9, 0.9, 0.88], (len(ab), 1))
        c[(ab[:, 0] % 1.2 < 0.04) | (ab[:, 1] % 1.2 < 0.04)] = [0.62, 0.62, 0.6]
        c[(np.abs(ab[:, 0] % 2.4 - 1.2) < 0.3) & (np.abs(ab[:, 1] % 2.4 - 1.2) < 0.3)] = [0.97, 0.96, 0.9]
        return c
    T.tag(None, B.surface, (-X, Y1, 0.0), (1, 0, 0), (0, 0, 1), (2 * X, H), (s, s), back, "building")
    T.tag(None, B.surface, (-X, Y0, 0.0), (0, 1, 0), (0, 0, 1), (Y1 - Y0, H), (s, s), plaster, "building")
    T.tag(None, B.surface, (X, Y1, 0.0), (0, -1, 0), (0, 0, 1), (Y1 - Y0, H), (s, s), plaster, "building")
    T.tag(None, B.surface, (-X, Y0, H), (1, 0, 0), (0, 1, 0), (2 * X, Y1 - Y0), (s, s), ceiling, "building")
    sf = math.sqrt(2 * X * (Y1 - Y0) / (0.03 * n))  # a dark linoleum floor, mostly out of view
    T.tag("hall_floor", B.surface, (-X, Y0, 0.0), (1, 0, 0), (0, 1, 0), (2 * X, Y1 - Y0), (sf, sf),
          noise_colour(rng, (0.2, 0.25, 0.21), 0.08), "ground", thin=0.003, scale_frac=0.8)
    k = math.sqrt(12000 / n)  # the made things' steps at the default budget
    smooth = lambda tv: PILLAR_GREEN * (1 + 0.05 * np.sin(tv[:, 1:2] * 0.7))
    for px, py in ((-2.6, -0.2), (2.6, -0.2), (-2.6, 3.2), (2.6, 3.2)):
        T.tag("pillars", B.cylinder, (px, py, 0.0), (px, py, H), 0.22, 0.22, 0.12 * k, smooth, "building")
    wood = _flat((0.68, 0.42, 0.22))
    T.tag("table", B.box, (0.6, 0.9, 0.72), (1.8, 0.8, 0.04), 0.1, 0.06 * k, wood, "clutter")
    for dx, dy in ((-0.82, -0.33), (0.82, -0.33), (-0.82, 0.33), (0.82, 0.33)):
        c, sn = math.cos(0.1), math.sin(0.1)
        T.tag("table", B.box, (0.6 + c * dx - sn * dy, 0.9 + sn * dx + c * dy, 0.0), (0.05, 0.05, 0.72), 0.1, 0.05 * k,
              _flat(DARK * 2), "clutter")
    carton = (0.75, 0.9, 0.76)
    T.tag("leaf_carton", B.box, carton, (0.8, 0.55, 0.55), 0.25, 0.035 * k, _leaf_print(rng, carton, (0.8, 0.55, 0.55)),
          "clutter")
    # the real plant: a terracotta pot and a leafy crown
    x, y = -1.1, 1.5
    T.tag("pot", B.cylinder, (x, y, 0.0), (x, y, 0.55), 0.17, 0.23, 0.05 * k, _flat((0.62, 0.36, 0.22)), "clutter")
    _disc(T, "pot", (x, y, 0.52), (0, 0, 1), 0.22, 0.04 * k, lambda rho: np.tile([0.2, 0.14, 0.1], (len(rho), 1)), "clutter")
    crown = [((x, y, 1.2), (0.5, 0.5, 0.5)), ((x + 0.15, y - 0.1, 1.5), (0.32, 0.32, 0.3))]
    leaves = int(0.12 * n)
    T.tag(None, B.blob, crown, leaves, (0.2, 0.42, 0.12), "foliage", (x, y, 0.55),
          0.7 * math.sqrt(4 * math.pi * 0.2 / leaves))


def build_made(name: str, T: Tagged, n: int, images: int, size: tuple[int, int]) -> list[Camera]:
    """Add the made decoy ``name`` (one of ``MADE_DECOYS``) to ``T`` (about ``n`` Gaussians); its cameras."""
    if name not in MADE_DECOYS:
        raise ValueError(f"unknown made decoy {name!r}; known: {list(MADE_DECOYS)}")
    if name == "yard":  # a walk along an arc at standing height, looking at the tractor and the facades
        _yard(T, n)
        return arc_cameras((1.0, 3.0, 2.2), 8.5, 1.6, images, -100.0, 60.0, size)
    _hall(T, n)  # level to slightly up: the floor is mostly out of view
    return arc_cameras((0.0, 2.5, 3.3), 6.5, 1.6, images, -90.0, 60.0, size, fov=65.0)

