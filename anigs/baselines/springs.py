"""Mass-spring system over the dynamic Gaussians, anchored to the static scene, and its implicit integrator.

Nodes are the D dynamic Gaussians (unit mass each) at rest positions X [D,3]. Springs:

- a symmetric kNN graph among the dynamic Gaussians (``k_neighbors``);
- anchor springs from each dynamic Gaussian to up to ``anchor_neighbors`` static Gaussians
  within ``anchor_radius`` x the median kNN edge length (anchors never move);
- every connected component without an anchor is tied by its lowest node (min z, the scene is
  z-up) to the nearest static Gaussian, so no part of the system floats free. A scene with no
  static Gaussian at all cannot be anchored: :class:`ValueError`.

Small-displacement (linearised, isotropic) springs: the force of spring (i,j) on i is
``-k_ij (u_i - u_j)`` with u the displacement from rest (an anchor has u = 0). The stiffness
operator is then a weighted graph Laplacian with Dirichlet anchors, the same [D,D] matrix K
for each axis, symmetric positive definite when every component is anchored. Spring constants
``k_ij = sqrt(k_i k_j) (l_med / l_ij)^2`` from a per-node stiffness field k [D] (1/s^2 per unit
mass), so the field is a material property independent of the sampling density. Damping is
per node (``c`` [D], 1/s): ``C = diag(c)``.

Integrators (:class:`ImplicitIntegrator`) on ``u'' + C u' + K u = f``, both unconditionally
stable for any k, c >= 0 and any step h > 0 (without forcing the energy ``|v|^2/2 + u^T K u/2``
never increases, for zero damping too):

- ``midpoint`` (default; trapezoidal rule = Newmark average acceleration):
  ``(I + h/2 C + h^2/4 K) v_{n+1} = (I - h/2 C - h^2/4 K) v_n - h K u_n + h f_{n+1/2}``,
  ``u_{n+1} = u_n + h (v_n + v_{n+1}) / 2``; second order, energy-conserving without damping.
- ``euler`` (backward Euler): ``(I + h C + h^2 K) v_{n+1} = v_n + h (f_{n+1} - K u_n)``,
  ``u_{n+1} = u_n + h v_{n+1}``; first order, L-stable: a huge step lands on the static
  equilibrium ``K u = f`` and very stiff modes are damped out.

The matrix is factorised once (sparse LU) per parameter set and step.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.sparse.linalg import splu
from scipy.spatial import cKDTree

from anigs.animate.method_config import INTEGRATORS


@dataclass
class SpringGraph:
    """Topology and rest geometry.

    rest [D,3] float64; edges [E,2] (i < j); edge_scale [E] = (l_med / l_ij)^2; anchor_node [A]
    (dynamic node of each anchor spring); anchor_pos [A,3]; anchor_scale [A]; median_edge (l_med).
    """

    rest: np.ndarray
    edges: np.ndarray
    edge_scale: np.ndarray
    anchor_node: np.ndarray
    anchor_pos: np.ndarray
    anchor_scale: np.ndarray
    median_edge: float

    @property
    def num_nodes(self) -> int:
        return int(self.rest.shape[0])


def build_graph(rest: np.ndarray, static: np.ndarray, k_neighbors: int = 8, anchor_neighbors: int = 4,
                anchor_radius: float = 1.5) -> SpringGraph:
    """Spring graph of the dynamic points rest [D,3] anchored to the static points static [S,3] (see module doc)."""
    X = np.asarray(rest, np.float64).reshape(-1, 3)
    S = np.asarray(static, np.float64).reshape(-1, 3)
    D = len(X)
    if D == 0:
        raise ValueError("mass-spring system: no dynamic Gaussians")
    if not (np.isfinite(X).all() and np.isfinite(S).all()):
        raise ValueError("mass-spring system: positions contain NaN or Inf")
    if len(S) == 0:
        raise ValueError(f"mass-spring system: the scene has no static Gaussian to anchor the {D} dynamic "
                         "Gaussians to; an unanchored system drifts away under any wind")
    if k_neighbors < 1 or anchor_neighbors < 0 or not anchor_radius >= 0:
        raise ValueError("mass-spring system: k_neighbors >= 1, anchor_neighbors >= 0, anchor_radius >= 0 required")
    edges = np.zeros((0, 2), np.int64)
    if D > 1:
        kk = min(k_neighbors, D - 1)
        _, nn = cKDTree(X).query(X, k=kk + 1)
        nn = nn.reshape(D, kk + 1)[:, 1:]
        pairs = np.stack([np.repeat(np.arange(D), kk), nn.reshape(-1)], 1)
        pairs = np.sort(pairs, 1)
        edges = np.unique(pairs[pairs[:, 0] != pairs[:, 1]], axis=0)
    length = np.linalg.norm(X[edges[:, 0]] - X[edges[:, 1]], axis=1) if len(edges) else np.zeros(0)
    positive = length[length > 0]
    tree_s = cKDTree(S)
    if len(positive):
        l_med = float(np.median(positive))
    else:  # a single Gaussian (or coincident ones): the distance to the static scene sets the scale
        l_med = float(max(tree_s.query(X, k=1)[0].min(), 1e-6))
    length = np.maximum(length, 1e-3 * l_med)
    edge_scale = (l_med / length) ** 2
    a_node, a_idx = [], []
    if anchor_neighbors > 0 and anchor_radius > 0:
        ka = min(anchor_neighbors, len(S))
        dist, nn = tree_s.query(X, k=ka, distance_upper_bound=anchor_radius * l_med)
        dist, nn = dist.reshape(D, ka), nn.reshape(D, ka)
        ok = np.isfinite(dist)
        a_node = list(np.nonzero(ok)[0])
        a_idx = list(nn[ok])
    adj = sp.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(D, D)) if len(edges) else \
        sp.coo_matrix((D, D))
    ncomp, comp = connected_components(adj, directed=False)
    anchored = np.zeros(ncomp, bool)
    anchored[comp[np.asarray(a_node, np.int64)]] = True
    for c in np.nonzero(~anchored)[0]:
        members = np.nonzero(comp == c)[0]
        low = members[np.argmin(X[members, 2])]
        a_node.append(low)
        a_idx.append(int(tree_s.query(X[low], k=1)[1]))
    a_node = np.asarray(a_node, np.int64)
    a_pos = S[np.asarray(a_idx, np.int64)]
    a_len = np.maximum(np.linalg.norm(X[a_node] - a_pos, axis=1), 1e-3 * l_med)
    return SpringGraph(X, edges, edge_scale, a_node, a_pos, (l_med / a_len) ** 2, l_med)


def _check_field(x: np.ndarray | float, D: int, name: str) -> np.ndarray:
    a = np.broadcast_to(np.asarray(x, np.float64), (D,)).copy()
    if not np.isfinite(a).all():
        raise ValueError(f"mass-spring system: {name} contains NaN or Inf")
    if (a < 0).any():
        raise ValueError(f"mass-spring system: {name} must be >= 0, got min {a.min():.3g}")
    return a


def stiffness_matrix(graph: SpringGraph, stiffness: np.ndarray | float) -> sp.csc_matrix:
    """K [D,D] (sparse, symmetric PSD; PD when every component is anchored and k > 0)."""
    D = graph.num_nodes
    k = _check_field(stiffness, D, "stiffness")
    i, j = graph.edges[:, 0], graph.edges[:, 1]
    ke = np.sqrt(k[i] * k[j]) * graph.edge_scale
    ka = k[graph.anchor_node] * graph.anchor_scale
    diag = np.bincount(i, ke, D) + np.bincount(j, ke, D) + np.bincount(graph.anchor_node, ka, D)
    rows = np.concatenate([i, j, np.arange(D)])
    cols = np.concatenate([j, i, np.arange(D)])
    vals = np.concatenate([-ke, -ke, diag])
    return sp.csc_matrix((vals, (rows, cols)), shape=(D, D))


SCHEMES = INTEGRATORS  # (defined with the physics baseline's config)


class ImplicitIntegrator:
    """Implicit integrator for ``u'' + diag(c) u' + K u = f`` (module docstring); u, v, f are [D,C].

    ``scheme``: ``midpoint`` (trapezoidal / Newmark average acceleration: A-stable, conserves the
    energy exactly without damping and forcing, second order, so no numerical damping of the
    sway) or ``euler`` (backward Euler: L-stable, first order, damps stiff modes and large
    steps towards the static equilibrium). Both factorise their [D,D] matrix once.
    """

    def __init__(self, graph: SpringGraph, stiffness: np.ndarray | float, damping: np.ndarray | float,
                 dt: float, scheme: str = "midpoint") -> None:
        dt = float(dt)
        if not (np.isfinite(dt) and dt > 0):
            raise ValueError(f"mass-spring system: time step must be finite and > 0, got {dt}")
        if scheme not in SCHEMES:
            raise ValueError(f"mass-spring system: unknown integrator {scheme!r}; choose one of {SCHEMES}")
        D = graph.num_nodes
        self.D, self.dt, self.scheme = D, dt, scheme
        self.K = stiffness_matrix(graph, stiffness)
        self.c = _check_field(damping, D, "damping")
        a = 1.0 if scheme == "euler" else 0.5   # weight of the new state in C and K terms
        A = sp.identity(D, format="csc") + sp.diags(a * dt * self.c, format="csc") + (a * a * dt * dt) * self.K
        self._lu = splu(A.tocsc())

    def step(self, u: np.ndarray, v: np.ndarray, f: np.ndarray, f_prev: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray]:
        """One step from (u [D,C], v [D,C]); ``f`` is the force at the end of the step, ``f_prev`` at its
        start (midpoint averages the two; default: f). Returns (u, v) at the end of the step."""
        h = self.dt
        if self.scheme == "euler":
            # (I + h C + h^2 K) v' = v + h (f - K u);  u' = u + h v'
            v_new = self._lu.solve(np.ascontiguousarray(v + h * (f - self.K @ u)))
            v_new = v_new.reshape(u.shape)
            return u + h * v_new, v_new
        # (I + h/2 C + h^2/4 K) v' = v - h/2 C v - h^2/4 K v - h K u + h fm;  u' = u + h/2 (v + v')
        fm = f if f_prev is None else 0.5 * (f + f_prev)
        cv = self.c[:, None] * v if v.ndim == 2 else self.c * v
        rhs = v - 0.5 * h * cv - 0.25 * h * h * (self.K @ v) - h * (self.K @ u) + h * fm
        v_new = self._lu.solve(np.ascontiguousarray(rhs)).reshape(u.shape)
        return u + 0.5 * h * (v + v_new), v_new

    def energy(self, u: np.ndarray, v: np.ndarray) -> float:
        """Kinetic + elastic energy ``|v|^2/2 + u^T K u / 2`` (per unit mass)."""
        return float(0.5 * (v * v).sum() + 0.5 * (u * (self.K @ u)).sum())


def simulate(graph: SpringGraph, stiffness: np.ndarray | float, damping: np.ndarray | float,
             force: Callable[[float], np.ndarray], dt: float, steps: int, record_every: int = 1,
             u0: np.ndarray | None = None, v0: np.ndarray | None = None, t0: float = 0.0,
             scheme: str = "midpoint") -> np.ndarray:
    """Integrate ``steps`` steps from (u0, v0) (default rest) starting at time t0.

    ``force(t)`` -> [D,C] at time t. Returns the displacements [R,D,C] after every
    ``record_every``-th step (R = steps // record_every), preceded by the initial state (so R+1
    rows). Raises FloatingPointError if the state stops being finite (it cannot with finite,
    non-negative parameters: the check guards against non-finite forces).
    """
    if steps < 0 or record_every < 1:
        raise ValueError(f"simulate: steps >= 0 and record_every >= 1 required, got {steps}, {record_every}")
    integ = ImplicitIntegrator(graph, stiffness, damping, dt, scheme)
    f0 = np.asarray(force(t0), np.float64)
    if f0.ndim != 2 or f0.shape[0] != graph.num_nodes:
        raise ValueError(f"simulate: force(t) must be [D={graph.num_nodes},C], got {f0.shape}")
    u = np.zeros_like(f0) if u0 is None else np.array(u0, np.float64).reshape(f0.shape)
    v = np.zeros_like(f0) if v0 is None else np.array(v0, np.float64).reshape(f0.shape)
    out = [u.copy()]
    f_prev = f0
    for n in range(1, steps + 1):
        f = np.asarray(force(t0 + n * dt), np.float64)
        u, v = integ.step(u, v, f, f_prev)
        f_prev = f
        if n % record_every == 0:
            if not (np.isfinite(u).all() and np.isfinite(v).all()):
                raise FloatingPointError(f"mass-spring simulation: non-finite state at step {n} (t = {t0 + n * dt:.4g} s);"
                                         " check that the forcing is finite")
            out.append(u.copy())
    return np.stack(out)
