"""Material field and wind of the physics baseline (:mod:`anigs.baselines.physics`): regions,
the wind's basis forces and the system's responses to them, and the material fit.

The system is linear in the forcing, so the wind is a set of basis forces (cos and sin of each
harmonic, per horizontal axis) whose amplitudes are solved in closed form; only the per-region
stiffness and damping are searched. Shapes: D dynamic Gaussians, M harmonics, B = 2M basis
forces per axis, T frames, R regions.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from anigs.animate.method_config import PhysicsConfig
from anigs.baselines.springs import ImplicitIntegrator, SpringGraph, stiffness_matrix
from anigs.baselines.tracks import ViewObservation


def kmeans(points: np.ndarray, k: int, iters: int = 25) -> np.ndarray:
    """Deterministic k-means labels [P] of points [P,3] (farthest-point initialisation)."""
    P = len(points)
    k = max(1, min(k, P))
    centers = [points[np.argmin(points[:, 2])]]
    for _ in range(1, k):
        d = np.min([np.linalg.norm(points - c, axis=1) for c in centers], axis=0)
        centers.append(points[int(np.argmax(d))])
    C = np.stack(centers)
    lab = np.zeros(P, np.int64)
    for _ in range(iters):
        lab = np.argmin(((points[:, None] - C[None]) ** 2).sum(-1), axis=1)
        for j in range(k):
            if (lab == j).any():
                C[j] = points[lab == j].mean(0)
    return lab


def material_regions(points: np.ndarray, labels: np.ndarray, per_effect: int) -> tuple[np.ndarray, list[int]]:
    """Region index [D] per dynamic Gaussian (k-means within each effect label) and the label of each region."""
    region = np.zeros(len(points), np.int64)
    region_label: list[int] = []
    for lab in np.unique(labels):
        sel = np.nonzero(labels == lab)[0]
        sub = kmeans(points[sel], per_effect)
        for j in np.unique(sub):
            region[sel[sub == j]] = len(region_label)
            region_label.append(int(lab))
    return region, region_label


class WindResponse:
    """Responses of the system to the wind's basis forces; see :func:`responses`."""

    def __init__(self, graph: SpringGraph, cfg: PhysicsConfig, num_frames: int) -> None:
        self.graph, self.cfg, self.T = graph, cfg, num_frames
        freqs = list(cfg.wind_freqs_hz) or [j * cfg.fps / max(num_frames, 2) for j in range(1, cfg.wind_modes + 1)]
        self.omega = 2 * math.pi * np.asarray(freqs, np.float64)              # [M]
        if cfg.gust_speed > 0:
            a = math.radians(cfg.wind_dir_deg)
            along = graph.rest[:, :2] @ np.array([math.cos(a), math.sin(a)])
            self.phase = self.omega[None] * along[:, None] / cfg.gust_speed  # [D,M]
        else:
            self.phase = np.zeros((graph.num_nodes, len(self.omega)))
        self.dt = 1.0 / (cfg.fps * cfg.substeps)
        self.warm = int(round(cfg.warmup_s * cfg.fps)) * cfg.substeps

    def force(self, t: float) -> np.ndarray:
        """Basis forces [D,2M] at time t (s): cos and sin of each harmonic."""
        arg = self.omega[None] * t - self.phase
        return np.concatenate([np.cos(arg), np.sin(arg)], 1)

    def harmonic(self, stiffness: np.ndarray, damping: np.ndarray) -> np.ndarray:
        """Complex steady-state amplitudes [D,M] of the continuous system under the cos basis forces.

        Per harmonic: ``(K - w^2 I + i w C) X = exp(-i phase)`` (one complex sparse solve); the
        cos force's response is ``Re(X e^{iwt})``, the sin force's ``Re(-i X e^{iwt})``.
        """
        K = stiffness_matrix(self.graph, stiffness)
        c = np.asarray(damping, np.float64)
        D = self.graph.num_nodes
        cols = []
        for m, w in enumerate(self.omega):
            A = (K - (w * w) * sp.identity(D, format="csc") + sp.diags(1j * w * c, format="csc")).tocsc()
            cols.append(splu(A).solve(np.exp(-1j * self.phase[:, m]).astype(np.complex128)))
        X = np.stack(cols, 1)
        if not np.isfinite(X).all():
            raise FloatingPointError("physics baseline: the harmonic response is not finite (resonance without damping)")
        return X

    def _state(self, X: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Steady-state displacement and velocity [D,2M] at time t from the amplitudes X [D,M]."""
        e = X * np.exp(1j * self.omega * t)[None]                              # [D,M]
        u = np.concatenate([e.real, (-1j * e).real], 1)
        v = np.concatenate([(1j * self.omega * e).real, (self.omega * e).real], 1)
        return u, v

    def steady_responses(self, stiffness: np.ndarray, damping: np.ndarray) -> np.ndarray:
        """Displacement responses [T,D,2M] at frames 0..T-1, relative to frame 0, in the periodic
        steady state of the continuous system (the material fit's fast exact model)."""
        X = self.harmonic(stiffness, damping)
        out = np.stack([self._state(X, j / self.cfg.fps)[0] for j in range(self.T)])
        return out - out[:1]

    def responses(self, stiffness: np.ndarray, damping: np.ndarray) -> np.ndarray:
        """Simulated displacement responses [T,D,2M] at frames 0..T-1 relative to frame 0, one
        column per basis force: implicit Euler (:class:`ImplicitIntegrator`, ``substeps`` per
        frame), started ``warmup_s`` before frame 0 in the steady state (so no start-up transient;
        the warm-up lets the integrator settle into its own discrete orbit)."""
        integ = ImplicitIntegrator(self.graph, stiffness, damping, self.dt, self.cfg.integrator)
        S = self.cfg.substeps
        t = -self.warm * self.dt
        u, v = self._state(self.harmonic(stiffness, damping), t)
        f_prev = self.force(t)
        for _ in range(self.warm):
            t += self.dt
            f = self.force(t)
            u, v = integ.step(u, v, f, f_prev)
            f_prev = f
        frames = [u.copy()]
        for n in range(1, (self.T - 1) * S + 1):
            f = self.force(n * self.dt)
            u, v = integ.step(u, v, f, f_prev)
            f_prev = f
            if n % S == 0:
                frames.append(u.copy())
        out = np.stack(frames)
        if not np.isfinite(out).all():
            raise FloatingPointError("physics baseline: the simulation produced non-finite displacements")
        return out - out[:1]


def _design(U: np.ndarray, obs: ViewObservation, sel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted design matrix [T*V*2, 2M*2] and target [T*V*2] for the wind amplitudes (x, y axes)."""
    Uv = U[:, sel]                                     # [T,V,B]
    J = obs.jac[sel][:, :, :2]                         # [V,2,2]: pixel per world x, y
    phi = np.einsum("tvb,vka->tvkba", Uv, J)           # [T,V,2,B,2]
    sw = np.sqrt(obs.weight[:, sel])[..., None]        # [T,V,1]
    A = (phi * sw[..., None, None]).reshape(-1, Uv.shape[2] * 2)
    y = (obs.disp[:, sel] * sw).reshape(-1)
    return A, y


def solve_wind(A: np.ndarray, y: np.ndarray, ridge: float) -> tuple[np.ndarray, float]:
    """Ridge least squares: (amplitudes [B*2], residual / |y|^2)."""
    G = A.T @ A
    lam = ridge * max(float(np.trace(G)) / max(len(G), 1), 1e-300)
    a = np.linalg.solve(G + lam * np.eye(len(G)), A.T @ y)
    r = A @ a - y
    return a, float(r @ r) / max(float(y @ y), 1e-300)


@dataclass
class MaterialFit:
    """Result of :func:`fit_material`: log-parameters theta [2R] (log k_r, log c_r), wind
    amplitudes [2M*2], responses [T,D,2M], relative residuals, evaluations, log bounds, the wind."""

    theta: np.ndarray
    amplitudes: np.ndarray
    responses: np.ndarray
    loss_initial: float
    loss: float
    evaluations: int
    log_bounds: tuple[np.ndarray, np.ndarray]
    wind: WindResponse

    @property
    def stiffness(self) -> np.ndarray:
        """Per-region stiffness [R] (1/s^2)."""
        R = len(self.theta) // 2
        return np.exp(np.clip(self.theta[:R], self.log_bounds[0][0], self.log_bounds[1][0]))

    @property
    def damping(self) -> np.ndarray:
        """Per-region damping [R] (1/s)."""
        R = len(self.theta) // 2
        return np.exp(np.clip(self.theta[R:], self.log_bounds[0][1], self.log_bounds[1][1]))


def fit_material(graph: SpringGraph, region: np.ndarray, num_regions: int, obs: ViewObservation,
                 sel: np.ndarray, cfg: PhysicsConfig, num_frames: int) -> MaterialFit:
    """Fit per-region stiffness and damping to the tracks ``obs`` of the Gaussians ``sel`` (indices into D).

    The wind is solved in closed form at every evaluation (steady-state responses); the material
    search is a coarse grid over one shared (k, c), then ``sweeps`` coordinate scans (each
    log-parameter over +-1 decade alone), then a Nelder-Mead polish of the 2R log-parameters (bounds by clipping).
    The returned responses and amplitudes come from the implicit time integration (the wind is
    re-solved on them), so the trajectories are the simulator's.

    region [D] in [0, num_regions); obs.jac [D,2,3], obs.disp [T,D,2], obs.weight [T,D].
    """
    from scipy.optimize import minimize

    R = num_regions
    wind = WindResponse(graph, cfg, num_frames)
    lo = np.log([cfg.stiffness_bounds[0], cfg.damping_bounds[0]])
    hi = np.log([cfg.stiffness_bounds[1], cfg.damping_bounds[1]])
    blo, bhi = np.repeat(lo, R), np.repeat(hi, R)

    def evaluate(theta: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        th = np.clip(theta, blo, bhi)
        U = wind.steady_responses(np.exp(th[:R])[region], np.exp(th[R:])[region])
        a, loss = solve_wind(*_design(U, obs, sel), cfg.wind_ridge)
        return loss, a, U

    theta0 = np.concatenate([np.full(R, math.log(cfg.stiffness_init)), np.full(R, math.log(cfg.damping_init))])
    loss0 = evaluate(theta0)[0]
    theta, best, nfev = theta0, loss0, 1
    # coarse grid over one shared (k, c): the loss has a local minimum near every resonance
    gk = np.linspace(lo[0], hi[0], cfg.grid_stiffness) if cfg.grid_stiffness > 1 else np.array([])
    gc = math.log(cfg.damping_init) + math.log(4.0) * (np.arange(cfg.grid_damping) - (cfg.grid_damping - 1) / 2)
    for lk in gk:
        for lc in np.clip(gc, lo[1], hi[1]):
            th = np.concatenate([np.full(R, lk), np.full(R, lc)])
            val = evaluate(th)[0]
            nfev += 1
            if val < best:
                theta, best = th, val
    # coordinate sweeps: a global scan of one log-parameter at a time (regions differ by decades)
    for _ in range(cfg.sweeps):
        for j in range(2 * R):
            for val in np.clip(theta[j] + np.linspace(-math.log(10), math.log(10), cfg.scan_points), blo[j], bhi[j]):
                if val == theta[j]:
                    continue
                th = theta.copy()
                th[j] = val
                loss = evaluate(th)[0]
                nfev += 1
                if loss < best:
                    theta, best = th, loss
    if cfg.max_evals > 0:
        # local polish: Nelder-Mead from a small simplex (a bounded Powell line search spans the whole
        # bounds and jumps into other resonance basins); bounds by clipping inside evaluate
        simplex = np.vstack([theta, theta + 0.1 * np.eye(2 * R)])
        res = minimize(lambda th: evaluate(th)[0], theta, method="Nelder-Mead",
                       options={"maxfev": cfg.max_evals, "initial_simplex": simplex, "xatol": 1e-3, "fatol": 1e-9})
        nfev += int(res.nfev)
        if res.fun <= best:
            theta, best = np.clip(res.x, blo, bhi), float(res.fun)
    th = np.clip(theta, blo, bhi)
    U = wind.responses(np.exp(th[:R])[region], np.exp(th[R:])[region])   # the implicit simulation
    a, loss = solve_wind(*_design(U, obs, sel), cfg.wind_ridge)
    return MaterialFit(theta, a, U, loss0, loss, nfev, (lo, hi), wind)
