"""The demo garden's parts (ground, building, clutter, trees, bushes, grass, flower beds), each
drawn into a :class:`anigs.synth.scene.Builder` in a fixed order of random draws (the default
garden is deterministic for its seed)."""
from __future__ import annotations

import math
from typing import Callable

import numpy as np
from scipy.spatial import cKDTree

from anigs.geometry.quaternion import quat_from_matrix
from anigs.synth.scene import (BEDS, BENCH, BUSH_SITES, FACADE_H, FENCE_H, FINE_GROUND, PATH_W, PLANTER,
                               SURFACE_OPACITY, TREE_SITES, WALL_H, X0, X1, Y0, Y1, Noise, Builder, jittered_grid,
                               shade, frame_from_normal, path_x)


def brick_color(rng: np.random.Generator, palette_base, mortar=(0.72, 0.70, 0.66)):
    """Running-bond bricks 0.42 x 0.19 m with 2.5 cm mortar; returns f(a[M], b[M]) -> [M,3]."""
    palette = np.asarray(palette_base) * rng.uniform(0.72, 1.18, (997, 1)) + rng.normal(0, 0.025, (997, 3))
    noise = Noise(rng, 2, 0.5, 12.0)

    def f(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        bh, bl, m = 0.19, 0.42, 0.025
        row = np.floor(b / bh).astype(np.int64)
        x = a / bl + 0.5 * (row % 2)
        col = np.floor(x).astype(np.int64)
        in_mortar = ((b - row * bh) < m) | ((x - col) * bl < m)
        c = palette[(row * 7919 + col * 104729) % 997].copy()
        c *= (1 + 0.08 * noise(np.column_stack([a, b])))[:, None]
        c[in_mortar] = np.asarray(mortar) * (1 + 0.05 * noise(np.column_stack([a, b])[in_mortar] * 3))[:, None]
        return c
    return f


def add_ground(B: Builder, n: int, trees: list) -> None:
    rng = B.rng
    length = Y1 - Y0
    cx, cy, rx, ry = FINE_GROUND
    a_path = PATH_W * length * 1.03
    a_fine = math.pi * rx * ry - PATH_W * 2 * ry
    a_lawn = (X1 - X0) * length - a_path - a_fine
    n_speck = int(0.3 * n)  # small high-contrast details (daisies, pebbles, leaves) on top of the lawn
    s = math.sqrt((a_lawn + a_fine / 0.36 + a_path / 0.36) / (n - n_speck))
    # lawn: coarse outside, finer inside the walkable ellipse (seen from close by); then the path
    coarse = jittered_grid(rng, (X0, Y0), (X1, Y1), (s, s))
    fine = jittered_grid(rng, (cx - rx, cy - ry), (cx + rx, cy + ry), (0.6 * s, 0.6 * s))
    in_fine = lambda q: ((q[:, 0] - cx) / rx) ** 2 + ((q[:, 1] - cy) / ry) ** 2 < 1
    lawn = np.concatenate([coarse[~in_fine(coarse)], fine[in_fine(fine)]])
    lawn_s = np.concatenate([np.full((~in_fine(coarse)).sum(), s), np.full(in_fine(fine).sum(), 0.6 * s)])
    off_path = np.abs(lawn[:, 0] - path_x(lawn[:, 1])) > PATH_W / 2 - 0.15 * s
    lawn, lawn_s = lawn[off_path], lawn_s[off_path]
    sp = 0.6 * s
    loc = jittered_grid(rng, (-PATH_W / 2, Y0), (PATH_W / 2, Y1), (sp, sp))
    path = np.column_stack([path_x(loc[:, 1]) + loc[:, 0], loc[:, 1]])
    big, small = Noise(rng, 2, 0.12, 1.0), Noise(rng, 2, 1.0, 7.0)
    # lawn colour: patchy green, tree shade, clover/daisy specks, bare soil spots
    p = lawn
    c = np.tile([0.30, 0.45, 0.16], (len(p), 1))
    nb, ns = big(p), small(p)
    c *= (1 + 0.13 * nb + 0.09 * ns)[:, None]
    c[:, 0] += 0.035 * np.clip(nb, 0, None)
    for tx, ty, rad in trees:
        d = np.hypot(p[:, 0] - tx, p[:, 1] - ty)
        c *= (1 - 0.3 * np.clip(1.2 - d / rad, 0, 1))[:, None]
    u = rng.random(len(p))
    c[u < 0.025] = [0.92, 0.9, 0.82]
    c[(u >= 0.025) & (u < 0.04)] = [0.9, 0.8, 0.2]
    c[(u >= 0.04) & (u < 0.07)] *= 0.55
    for x0, x1, y0, y1 in BEDS:  # soil with a stone edging
        inside = (p[:, 0] > x0) & (p[:, 0] < x1) & (p[:, 1] > y0) & (p[:, 1] < y1)
        edge = inside & ((p[:, 0] < x0 + 0.12) | (p[:, 0] > x1 - 0.12) | (p[:, 1] < y0 + 0.12) | (p[:, 1] > y1 - 0.12))
        c[inside] = np.array([0.33, 0.23, 0.15]) * (1 + 0.15 * ns[inside] + rng.normal(0, 0.08, inside.sum()))[:, None]
        c[edge] = np.array([0.62, 0.6, 0.56]) * rng.uniform(0.8, 1.1, (edge.sum(), 1))
    lawn_c = c
    # cobbles: Voronoi cells with dark joints, a dark curb along the edges
    seeds = jittered_grid(rng, (-PATH_W / 2, Y0), (PATH_W / 2, Y1), (0.2, 0.2))
    stone = np.array([0.66, 0.62, 0.55]) * rng.uniform(0.72, 1.15, (len(seeds), 1)) + rng.normal(0, 0.03, (len(seeds), 3))
    d, idx = cKDTree(seeds).query(loc, k=2)
    c = stone[idx[:, 0]] * (1 + 0.06 * small(path))[:, None]
    c[(d[:, 1] - d[:, 0]) < 0.035] = [0.27, 0.25, 0.22]
    c[np.abs(loc[:, 0]) > PATH_W / 2 - 0.06] = [0.42, 0.41, 0.4]
    pts = np.concatenate([lawn, path])
    cols = np.concatenate([lawn_c, c])
    steps = np.concatenate([lawn_s, np.full(len(path), sp)])
    m = len(pts)
    means = np.column_stack([pts, rng.uniform(0, 0.002, m)])
    scales = np.column_stack([0.8 * steps, 0.68 * steps, np.full(m, 0.003)])
    R = frame_from_normal(np.tile([0.0, 0, 1], (m, 1)), rng.uniform(0, math.pi, m))
    B.add(means, scales, quat_from_matrix(R), B.jitter(cols, 0.1) * shade(np.tile([0.0, 0, 1], (m, 1)))[:, None],
          SURFACE_OPACITY, "ground")
    _specks(B, n_speck, in_fine)


def _specks(B: Builder, n: int, inside: Callable) -> None:
    """Daisies, dandelions, soil spots, dead leaves and light blades on the lawn: 70% near the walk."""
    rng = B.rng
    cand = np.column_stack([rng.uniform(X0 + 0.1, X1 - 0.1, 8 * n), rng.uniform(Y0 + 0.1, Y1 - 0.1, 8 * n)])
    ok = np.abs(cand[:, 0] - path_x(cand[:, 1])) > PATH_W / 2 + 0.02
    for x0, x1, y0, y1 in BEDS:
        ok &= ~((cand[:, 0] > x0) & (cand[:, 0] < x1) & (cand[:, 1] > y0) & (cand[:, 1] < y1))
    near = cand[ok & inside(cand)][: int(0.7 * n)]
    far = cand[ok & ~inside(cand)][: n - len(near)]
    p = np.concatenate([near, far])
    m = len(p)
    palette = np.array([[0.93, 0.92, 0.85], [0.92, 0.8, 0.2], [0.2, 0.16, 0.1], [0.5, 0.35, 0.18], [0.55, 0.7, 0.3]])
    cols = palette[rng.choice(len(palette), size=m, p=[0.15, 0.1, 0.25, 0.2, 0.3])]
    scales = np.column_stack([rng.uniform(0.025, 0.045, m), rng.uniform(0.015, 0.03, m), np.full(m, 0.002)])
    R = frame_from_normal(np.tile([0.0, 0, 1], (m, 1)), rng.uniform(0, math.pi, m))
    B.add(np.column_stack([p, np.full(m, 0.005)]), scales, quat_from_matrix(R), B.jitter(cols, 0.1), 0.95, "ground")


def facade_color(rng: np.random.Generator):
    brick = brick_color(rng, (0.62, 0.30, 0.21))
    door_x = float(path_x(Y1))
    win_x = [door_x + k * 2.3 for k in (-2, -1, 1, 2)]
    glass_noise = Noise(rng, 2, 0.5, 4.0)
    wood = Noise(rng, 2, 2.0, 20.0)

    def f(ab: np.ndarray) -> np.ndarray:
        x, z = X0 + ab[:, 0], ab[:, 1]
        c = brick(ab[:, 0], z)
        c[z < 0.4] = np.array([0.55, 0.54, 0.52]) * (1 + 0.1 * glass_noise(ab[z < 0.4] * 4))[:, None]
        top = z > FACADE_H - 0.3
        c[top] = np.array([0.8, 0.78, 0.72]) * (1 - 0.25 * (z[top] < FACADE_H - 0.24))[:, None]
        rows = [(0.9, 2.15, win_x), (2.85, 4.05, win_x + [door_x])]
        for z0, z1, xs in rows:
            for xc in xs:
                w = 1.1
                inside = (np.abs(x - xc) < w / 2) & (z > z0) & (z < z1)
                fr = inside & ((np.abs(x - xc) > w / 2 - 0.09) | (z < z0 + 0.09) | (z > z1 - 0.09)
                               | (np.abs(x - xc) < 0.035) | (np.abs(z - (z0 + z1) / 2 - 0.15) < 0.035))
                sky = 0.25 + 0.25 * np.clip((z - z0) / (z1 - z0), 0, 1)
                g = np.column_stack([0.16 + 0.5 * sky, 0.2 + 0.55 * sky, 0.28 + 0.6 * sky])
                g *= (1 + 0.15 * glass_noise(ab))[:, None]
                c[inside] = g[inside]
                c[fr] = [0.9, 0.9, 0.86]
                sill = (np.abs(x - xc) < w / 2 + 0.08) & (z > z0 - 0.1) & (z <= z0)
                c[sill] = [0.7, 0.68, 0.64]
        door = (np.abs(x - door_x) < 0.6) & (z < 2.3)
        plank = np.floor((x - door_x + 0.6) / 0.15)
        dc = np.array([0.38, 0.22, 0.12]) * (1 + 0.12 * np.sin(plank * 2.7))[:, None] * (1 + 0.1 * wood(ab))[:, None]
        c[door] = dc[door]
        dframe = door & ((np.abs(x - door_x) > 0.52) | (z > 2.22))
        c[dframe] = [0.85, 0.84, 0.8]
        c[door & (np.abs(x - door_x - 0.4) < 0.04) & (np.abs(z - 1.05) < 0.04)] = [0.9, 0.8, 0.3]
        return c
    return f


def add_building(B: Builder, n: int) -> None:
    rng = B.rng
    area = (X1 - X0) * FACADE_H + (Y1 - Y0) * (WALL_H + 0.25)
    s = math.sqrt(area / n)
    B.surface((X0, Y1, 0), (1, 0, 0), (0, 0, 1), (X1 - X0, FACADE_H), (s, s), facade_color(rng), "building")
    wall = brick_color(rng, (0.55, 0.33, 0.25))
    coping = Noise(rng, 2, 1.0, 8.0)
    B.surface((X0, Y0, 0), (0, 1, 0), (0, 0, 1), (Y1 - Y0, WALL_H), (s, s),
              lambda ab: wall(ab[:, 0], ab[:, 1]), "building")
    B.surface((X0 - 0.25, Y0, WALL_H), (1, 0, 0), (0, 1, 0), (0.25, Y1 - Y0), (0.125, s),
              lambda ab: np.array([0.6, 0.58, 0.55]) * (1 + 0.12 * coping(ab))[:, None], "building")


def stone_color(rng: np.random.Generator, center, extent: float, base=(0.6, 0.58, 0.54), cell: float = 0.12):
    """3D Voronoi stones around ``center`` (cube of half-size ``extent``): f(points[M,3]) -> colours [M,3]."""
    count = int(min(4000, max(50, (2 * extent / cell) ** 3)))
    seeds = np.asarray(center, float) + rng.uniform(-extent, extent, (count, 3))
    tree = cKDTree(seeds)
    tone = rng.uniform(0.75, 1.15, (count, 1)) * np.asarray(base) + rng.normal(0, 0.02, (count, 3))

    def f(p: np.ndarray) -> np.ndarray:
        d, idx = tree.query(p, k=2)
        c = tone[idx[:, 0]].copy()
        c[(d[:, 1] - d[:, 0]) < 0.15 * cell] *= 0.55
        return c
    return f


def add_bench(B: Builder, at: tuple[float, float], step: float) -> None:
    """A bench at ``at`` (x, y), long axis along y, facing +x: seat slats, backrest, dark metal legs."""
    bx, by = at
    wood = Noise(B.rng, 3, 2.0, 30.0)
    woodc = lambda p: np.array([0.58, 0.38, 0.22]) * (1 + 0.15 * wood(p * np.array([0.2, 1.0, 1.0])))[:, None]
    metal = lambda p: np.tile([0.16, 0.16, 0.17], (len(p), 1)) * (1 + 0.3 * (np.sin(p[:, 2] * 40) > 0.6))[:, None]
    for i in range(4):
        B.box((bx - 0.2 + 0.135 * i, by, 0.43), (0.11, 1.7, 0.035), 0.0, step, woodc, "clutter")
    for j in range(3):
        B.box((bx - 0.29, by, 0.55 + 0.13 * j), (0.035, 1.7, 0.095), 0.0, step, woodc, "clutter")
    for dx, dy, h in ((-0.22, -0.72, 0.9), (-0.22, 0.72, 0.9), (0.2, -0.72, 0.43), (0.2, 0.72, 0.43)):
        B.box((bx + dx, by + dy, 0.0), (0.05, 0.05, h), 0.0, step, metal, "clutter")


def add_clutter(B: Builder, n: int, keep_out: list) -> None:
    rng = B.rng
    # wooden fences on the south and east sides (planks with dark gaps, grain)
    grain = Noise(rng, 2, 1.0, 25.0)
    planks = np.array([0.52, 0.40, 0.28]) * rng.uniform(0.6, 1.3, (400, 1)) + rng.normal(0, 0.03, (400, 3))

    def fence(ab: np.ndarray) -> np.ndarray:
        k = np.floor(ab[:, 0] / 0.16).astype(int)
        c = planks[k % 400] * (1 + 0.12 * grain(ab * np.array([4.0, 0.3])))[:, None]
        c[(ab[:, 0] - k * 0.16) > 0.135] = [0.18, 0.14, 0.1]
        c[np.abs(ab[:, 1] - 0.3) < 0.03] *= 0.7
        c[np.abs(ab[:, 1] - 1.05) < 0.03] *= 0.7
        return c
    fence_area = (X1 - X0 + Y1 - Y0) * FENCE_H
    s = math.sqrt(fence_area / (0.6 * n))  # shares of n: fences 0.6, bench 0.17, planter 0.1, rocks 0.12
    B.surface((X1, Y0, 0), (-1, 0, 0), (0, 0, 1), (X1 - X0, FENCE_H), (0.8 * s, 1.25 * s), fence, "clutter")
    B.surface((X1, Y1, 0), (0, -1, 0), (0, 0, 1), (Y1 - Y0, FENCE_H), (0.8 * s, 1.25 * s), fence, "clutter")
    add_bench(B, BENCH, math.sqrt(2.6 / (0.17 * n)))
    # stone planter
    B.box((PLANTER[0], PLANTER[1], 0.0), (0.8, 0.8, 0.55), 0.35, math.sqrt(2.4 / (0.1 * n)),
          stone_color(rng, (PLANTER[0], PLANTER[1], 0.3), 0.7, cell=0.12), "clutter")
    # rocks: half-buried ellipsoid shells
    for _ in range(6):
        for _try in range(100):
            c = np.array([rng.uniform(X0 + 0.8, X1 - 0.8), rng.uniform(Y0 + 0.8, 3.4)])
            if _free(c, 0.5, keep_out):
                break
        keep_out.append((c[0], c[1], 0.45))
        radii = np.array([rng.uniform(0.2, 0.35), rng.uniform(0.18, 0.3), rng.uniform(0.12, 0.22)])
        m = int(0.02 * n)
        d = rng.normal(size=(3 * m, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        d = d[d[:, 2] > -0.15][:m]
        means = np.array([c[0], c[1], 0.0]) + d * radii
        spacing = math.sqrt(2.6 * math.pi * radii.mean() ** 2 / len(d))
        sc = np.tile([0.7 * spacing, 0.7 * spacing, 0.003], (len(d), 1))
        nrm = d / radii
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
        R = frame_from_normal(nrm, rng.uniform(0, math.pi, len(d)))
        rock = stone_color(rng, (c[0], c[1], 0.1), 0.4, (0.5, 0.49, 0.47), cell=0.09)
        B.add(means, sc, quat_from_matrix(R), B.jitter(rock(means)) * shade(nrm)[:, None], SURFACE_OPACITY, "clutter")


def _free(p: np.ndarray, r: float, keep_out: list) -> bool:
    """True when a disc of radius r at p avoids path, beds and every keep-out disc."""
    if abs(p[0] - path_x(p[1])) < PATH_W / 2 + r:
        return False
    for x0, x1, y0, y1 in BEDS:
        if x0 - r < p[0] < x1 + r and y0 - r < p[1] < y1 + r:
            return False
    return all(math.hypot(p[0] - x, p[1] - y) > r + rr for x, y, rr in keep_out)


def add_trees(B: Builder, n_trunk: int, n_leaves: int, num_trees: int, keep_out: list) -> list:
    """Trunks (+3 branches) and crowns; returns [(x, y, crown radius)] for ground shading."""
    rng = B.rng
    bark_noise = Noise(rng, 2, 0.5, 10.0)
    greens = np.array([[0.22, 0.40, 0.13], [0.28, 0.42, 0.12], [0.18, 0.35, 0.15], [0.30, 0.45, 0.17]])
    out = []
    for k in range(num_trees):
        x, y = np.asarray(TREE_SITES[k]) + rng.uniform(-0.15, 0.15, 2)
        H, r0 = rng.uniform(1.8, 2.2), rng.uniform(0.16, 0.21)
        step = math.sqrt((2 * math.pi * 0.8 * r0 * (H + 0.5) + 0.7) / (n_trunk / num_trees))

        def bark(tv, shift=rng.uniform(0, 10)):
            c = np.array([0.30, 0.22, 0.15]) * (1 + 0.3 * bark_noise((tv + shift) * np.array([5.0, 0.6])))[:, None]
            c[bark_noise(tv * 2.0 + shift) > 1.6] = [0.45, 0.5, 0.38]  # lichen
            return c
        B.cylinder((x, y, 0.0), (x, y, H + 0.5), r0, 0.6 * r0, step, bark, "trunk")
        for a in rng.uniform(0, 2 * math.pi, 2):
            tip = np.array([x + 0.8 * math.cos(a), y + 0.8 * math.sin(a), H + 0.9])
            B.cylinder((x, y, H - 0.1), tip, 0.05, 0.025, step, bark, "trunk")
        Rh, Rv = rng.uniform(1.35, 1.6), rng.uniform(1.15, 1.35)
        c = np.array([x, y, H + 0.85 + rng.uniform(0, 0.2)])
        spheres = [(c, (0.8 * Rh, 0.8 * Rh, 0.8 * Rv))]
        for az in np.linspace(0, 2 * math.pi, 6, endpoint=False) + rng.uniform(0, 1, 6):
            off = np.array([0.5 * Rh * math.cos(az), 0.5 * Rh * math.sin(az), rng.uniform(-0.3, 0.4) * Rv])
            k = rng.uniform(0.45, 0.65)
            spheres.append((c + off, (k * Rh, k * Rh, 0.9 * k * Rv)))
        count = n_leaves // num_trees
        leaf = 0.75 * math.sqrt(4 * math.pi * Rh * Rh / count)
        B.blob(spheres, count, greens[rng.integers(len(greens))], "foliage", (x, y, 0.0), leaf)
        keep_out.append((x, y, 0.35))
        out.append((x, y, Rh))
    return out


def add_bushes(B: Builder, n: int, keep_out: list) -> None:
    rng = B.rng
    sites = [(x, y, r, 0.0) for x, y, r in BUSH_SITES] + [(PLANTER[0], PLANTER[1], 0.38, 0.55)]
    area = np.array([r * r for _, _, r, _ in sites])
    for (x, y, r, z0), a in zip(sites, area):
        rv = r * rng.uniform(0.8, 0.95)
        c = np.array([x, y, z0 + 0.75 * rv])
        spheres = [(c, (r, r, rv))]
        for az in rng.uniform(0, 2 * math.pi, 2):
            spheres.append((c + [0.45 * r * math.cos(az), 0.45 * r * math.sin(az), 0.1 * rv], (0.7 * r, 0.7 * r, 0.75 * rv)))
        count = int(n * a / area.sum())
        base = np.array([0.2, 0.36, 0.14]) * rng.uniform(0.8, 1.15, 3)
        B.blob(spheres, count, base, "foliage", (x, y, z0), 0.7 * math.sqrt(4 * math.pi * r * r / count))
        if z0 == 0.0:
            keep_out.append((x, y, r))


def add_grass(B: Builder, n: int, keep_out: list) -> None:
    """Tufts of 6 curved blades, 3 elongated Gaussians per blade; anchor = tuft root on the ground."""
    rng = B.rng
    nt, nb = max(n // 18, 1), 6
    roots = []
    for _ in range(1000 * nt):
        if len(roots) == nt:
            break
        p = np.array([rng.uniform(X0 + 0.3, X1 - 0.3), rng.uniform(Y0 + 0.3, Y1 - 0.4)])
        if _free(p, 0.12, keep_out):
            roots.append(p)
    if not roots:
        raise RuntimeError("synthetic scene: no free lawn left for grass tufts")
    roots = np.repeat(np.array(roots), nb, 0)
    m = len(roots)
    base = roots + rng.normal(0, 0.035, (m, 2))
    h = rng.uniform(0.1, 0.28, m)
    az = rng.uniform(0, 2 * math.pi, m)
    ld = np.column_stack([np.cos(az), np.sin(az), np.zeros(m)])
    lean = rng.uniform(0.15, 0.55, m)
    green = np.array([0.30, 0.50, 0.15]) * rng.uniform(0.75, 1.2, (m, 1)) + rng.normal(0, 0.02, (m, 3))
    w = np.column_stack([-ld[:, 1], ld[:, 0], np.zeros(m)])
    for s in (1 / 6, 1 / 2, 5 / 6):
        means = np.column_stack([base, np.zeros(m)]) + ld * (lean * h * s * s)[:, None]
        means[:, 2] = h * s
        tan = ld * (2 * lean * s)[:, None] + np.array([0.0, 0, 1])
        tan /= np.linalg.norm(tan, axis=1, keepdims=True)
        R = np.stack([w, tan, np.cross(w, tan)], 2)
        scales = np.column_stack([np.full(m, 0.009), 0.19 * h, np.full(m, 0.003)])
        col = green * (0.62 + 0.55 * s) + np.array([0.06, 0.04, 0.0]) * s
        B.add(means, scales, quat_from_matrix(R), B.jitter(col), 0.95, "grass",
              np.column_stack([roots, np.zeros(m)]))


FLOWER_COLORS = np.array([[0.88, 0.15, 0.15], [0.95, 0.82, 0.15], [0.94, 0.93, 0.9], [0.58, 0.3, 0.78],
                          [0.95, 0.5, 0.12], [0.95, 0.55, 0.72], [0.3, 0.42, 0.88]])


def add_flowers(B: Builder, n: int) -> None:
    """Flowers in the beds: 3 stem + 2 leaf + 1 centre + 5 petal Gaussians; anchor = stem base."""
    rng = B.rng
    beds = [(x0 + 0.16, x1 - 0.16, y0 + 0.16, y1 - 0.16) for x0, x1, y0, y1 in BEDS]
    area = sum((x1 - x0) * (y1 - y0) for x0, x1, y0, y1 in beds)
    s = math.sqrt(area / max(n // 11, 1))
    pts = np.concatenate([jittered_grid(rng, (x0, y0), (x1, y1), (s, s)) for x0, x1, y0, y1 in beds])
    m = len(pts)
    anchor = np.column_stack([pts, np.zeros(m)])
    h = rng.uniform(0.25, 0.5, m)
    az = rng.uniform(0, 2 * math.pi, m)
    ld = np.column_stack([np.cos(az), np.sin(az), np.zeros(m)])
    lean = rng.uniform(0.0, 0.25, m)
    w = np.column_stack([-ld[:, 1], ld[:, 0], np.zeros(m)])
    stem_c = np.array([0.22, 0.42, 0.14]) * rng.uniform(0.8, 1.15, (m, 1))
    for t in (1 / 6, 1 / 2, 5 / 6):
        means = anchor + ld * (lean * h * t * t)[:, None]
        means[:, 2] = h * t
        tan = ld * (2 * lean * t)[:, None] + np.array([0.0, 0, 1])
        tan /= np.linalg.norm(tan, axis=1, keepdims=True)
        R = np.stack([w, tan, np.cross(w, tan)], 2)
        B.add(means, np.column_stack([np.full(m, 0.007), 0.19 * h, np.full(m, 0.003)]), quat_from_matrix(R),
              B.jitter(stem_c), 0.95, "flowers", anchor)
    for sign in (-1, 1):  # two leaves near the base
        means = anchor + sign * w * 0.045
        means[:, 2] = 0.3 * h
        R = frame_from_normal(np.column_stack([sign * w[:, :2] * 0.4, np.ones(m)]), az)
        B.add(means, np.tile([0.04, 0.014, 0.003], (m, 1)), quat_from_matrix(R), B.jitter(stem_c * 0.85),
              0.95, "flowers", anchor)
    head = anchor + ld * (lean * h)[:, None]
    head[:, 2] = h
    nrm = np.array([0.0, 0, 1]) + 0.9 * ld + rng.normal(0, 0.15, (m, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    F = frame_from_normal(nrm, rng.uniform(0, 2 * math.pi, m))
    petal = FLOWER_COLORS[rng.integers(len(FLOWER_COLORS), size=m)] * rng.uniform(0.85, 1.05, (m, 1))
    B.add(head + 0.004 * nrm, np.tile([0.014, 0.014, 0.006], (m, 1)), quat_from_matrix(F),
          B.jitter(np.tile([0.75, 0.55, 0.1], (m, 1))), 0.98, "flowers", anchor)
    for k in range(5):
        a = 2 * math.pi * k / 5
        radial = math.cos(a) * F[:, :, 0] + math.sin(a) * F[:, :, 1]
        R = np.stack([radial, np.cross(nrm, radial), nrm], 2)
        B.add(head + 0.028 * radial, np.tile([0.026, 0.016, 0.003], (m, 1)), quat_from_matrix(R),
              B.jitter(petal, 0.04), 0.97, "flowers", anchor)
