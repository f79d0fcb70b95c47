"""How the paths of a measurement follow the motion (:class:`MovingPaths`).

The sensor moves and turns during a measurement (30-36 ms), point reflectors and
meshes may move too.  The kinematics stage (:mod:`acousim.kinematics`) solves when
each sample of the call reaches each microphone; what it needs of a path is here: its
last anchor (image source, scatterer or reflector) A and how it moves, and its first
leg F (see :mod:`acousim.kinematics.retarded` for the retarded-time equation).

Approximation of the geometry (stated, measured in ``BENCHMARKS.md``): paths are
traced once, at the pose of the start of the emission.  Then:

1. the receiving side is exact: an image source, a scatterer or a point reflector
   stays where it is while the microphones move (an image source depends only on
   the emitter), so ``|m(t) - A|`` holds for any reception time;
2. the emitting side moves only during the call (2.5 mm at 1 m/s): the image source
   of a first- or second-order reflection moves exactly with the emitter (its
   planes found from the traced path); the first leg
   of higher-order and scattered paths changes, for an emitter displacement de, by
   ``-u.de + (|de|^2 - (u.de)^2) / (2 L)`` with u the departure direction and L the
   unfolded length from the emitter (Fermat: the length is stationary in the
   reflection points, so the first-order term holds them still; the second-order
   term is that of the image source ``|m - A - J de|`` for any orthogonal J of the
   reflections; third order: below 0.1 ns at 2 m/s); point reflectors use
   ``|A - e(tau)|`` exactly;
3. which paths exist (visibility, the energy floor) is that of the emission pose;
4. gains (spreading, directivity, air absorption) are those at the start of the
   echo: the echo's level changes by v T / r during a call (0.1 % at 1 m/s, 2.5 m).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from enum import IntEnum

import numpy as np

from acousim.core.vectors import row_norms
from acousim.trace.paths import KIND, TracedPaths
from processing.base.kernels import optional_kernel

__all__ = ["Endpoints", "FirstLeg", "MovingPaths"]


@dataclass(frozen=True)
class Endpoints:
    """Where the sound of a measurement leaves and arrives, at the start of the
    emission: the emitter (3,) and the receiver (3,: the array's centre) in the
    world frame (m), and the speed of sound (m/s)."""

    emitter_m: np.ndarray
    receiver_m: np.ndarray
    speed_of_sound_m_s: float


class FirstLeg(IntEnum):
    """How a path's first leg follows the emitter (:class:`MovingPaths`): held
    (image sources that move with the emitter, the direct path), by Fermat's law to
    second order, or exactly ``|A - e(tau)|`` (point reflectors)."""

    fixed = 0
    fermat = 1
    exact = 2


@dataclass(frozen=True, eq=False)
class MovingPaths:
    """Paths of one measurement and how they follow the motion.  N paths, world frame,
    at the start of the emission (tau = 0); anchor, first leg and strength as in
    :class:`acousim.trace.paths.TracedPaths` (path length to a microphone p
    ``first_leg + |anchor - p|``, gain ``strength / |anchor - p|``)."""

    anchor_m: np.ndarray
    """(N, 3) the anchor at tau = 0, m."""
    first_leg_m: np.ndarray
    """(N,) path length from the emitter to the anchor at tau = 0, m."""
    strength: np.ndarray
    """(N,) signed pressure gain times the last leg's length, m."""
    departure: np.ndarray
    """(N, 3) unit direction leaving the emitter."""
    order: np.ndarray
    """(N,) int, reflections."""
    mirror: np.ndarray
    """(N, 3, 3): the anchor moves by ``mirror @ (e(tau) - e(0))`` (identity for the
    direct path, the reflections' linear part for a first- or second-order image
    source, zero else)."""
    first_leg: np.ndarray
    """(N,) int, :class:`FirstLeg` codes: fixed, Fermat (``-departure . de``) or exact
    (``|A - e(tau)|``, point reflectors)."""
    velocity_m_s: np.ndarray
    """(N, 3) of the anchor (moving point reflectors), from tau = 0, m/s."""
    fermat_length_m: np.ndarray
    """(N,) L of the second-order term of a Fermat first leg (the first leg of a
    scattered path, the image distance of a specular one), m."""
    acceleration_m_s2: np.ndarray | None = None
    """(N, 3) of the anchor (the image in a turning plane), from tau = 0, m/s^2: it is
    at ``anchor + velocity t + acceleration t^2 / 2`` (None: zero)."""

    def __post_init__(self) -> None:
        if self.acceleration_m_s2 is None:
            object.__setattr__(self, "acceleration_m_s2", np.zeros_like(self.anchor_m))

    def __len__(self) -> int:
        return self.strength.size

    @classmethod
    def from_traced(cls, paths: TracedPaths, emitter_m: np.ndarray) -> MovingPaths:
        """From :class:`~acousim.trace.paths.TracedPaths` traced with the emitter at
        `emitter_m` (all static)."""
        n = len(paths)
        mirror, first, unfolded = _static_legs(paths, emitter_m)
        two = np.flatnonzero((paths.kind == KIND["specular"]) & (paths.order == 2))
        if two.size:
            J, ok = _second_order_mirror(
                emitter_m, paths.departure[two], paths.position_m[two], paths.anchor_m[two]
            )
            mirror[two[ok]] = J[ok]
            first[two[ok]] = FirstLeg.fixed
        return cls(
            paths.anchor_m,
            paths.first_leg_m,
            paths.strength,
            paths.departure,
            paths.order,
            mirror,
            first,
            np.zeros((n, 3)),
            unfolded,
        )

    @classmethod
    def points(cls, positions_m, strength, velocity_m_s, emitter_m: np.ndarray) -> MovingPaths:
        """Point reflectors at `positions_m` (P, 3) at tau = 0, moving at
        `velocity_m_s` (P, 3): a_k / r_e at the emitter as the tracer's points."""
        pos = np.asarray(positions_m, float).reshape(-1, 3)
        r_e = np.linalg.norm(pos - emitter_m, axis=1)
        n = pos.shape[0]
        return cls(
            pos,
            r_e,
            np.asarray(strength, float) / r_e,
            (pos - emitter_m) / r_e[:, None],
            np.ones(n, int),
            np.zeros((n, 3, 3)),
            np.full(n, FirstLeg.exact),
            np.asarray(velocity_m_s, float).reshape(-1, 3),
            r_e,
        )

    @staticmethod
    def concatenate(parts: list[MovingPaths]) -> MovingPaths:
        return MovingPaths(
            *(np.concatenate([getattr(p, f.name) for p in parts]) for f in fields(MovingPaths))
        )

    def level_at(self, point: np.ndarray) -> np.ndarray:
        """Magnitude of the pressure gain (N,) of every path at one point (the array
        centre), its anchor where it is at the start of the emission."""
        return np.abs(self.strength) / np.maximum(row_norms(self.anchor_m - point), 1e-9)

    def select(self, keep) -> MovingPaths:
        """The paths where `keep` (a mask, indices or a slice) selects."""
        return MovingPaths(*(getattr(self, f.name)[keep] for f in fields(MovingPaths)))

    def moved(self, emitter0: np.ndarray, emitter1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Static paths after the emitter moved from `emitter0` to `emitter1` (3,):
        anchors (N, 3) and first legs (N,) (the law of the module docstring)."""
        de = emitter1 - emitter0
        anchor = self.anchor_m + self.mirror @ de
        along = self.departure @ de
        fermat = self.first_leg_m - along + (de @ de - along**2) / (2 * self.fermat_length_m)
        first = np.where(self.first_leg == FirstLeg.fermat, fermat, self.first_leg_m)
        exact = np.linalg.norm(anchor - emitter1, axis=1)
        first = np.where(self.first_leg == FirstLeg.exact, exact, first)
        return anchor, first


def _static_legs(paths: TracedPaths, emitter_m: np.ndarray):
    """:meth:`MovingPaths.from_traced` but the second-order mirrors: the mirrors
    (N, 3, 3) (the identity for the direct path, the reflection of a first-order
    specular one, zero else), the FirstLeg codes (N,) (fixed for those, exact for a
    point, Fermat else) and the Fermat lengths (N,) (the first leg, or an image
    source's distance from the emitter `emitter_m` (3,), at least 1e-6 m); compiled
    where numba is (:mod:`acousim.trace.motion._following_kernel`)."""
    n = len(paths)
    mirror = np.zeros((n, 3, 3))
    compiled = optional_kernel("acousim.trace.motion._following_kernel", "static_legs")
    if compiled is not None:
        first, unfolded = np.empty(n, np.int64), np.empty(n)
        anchor, e = np.asarray(paths.anchor_m, float), np.asarray(emitter_m, float)
        legs = np.asarray(paths.first_leg_m, float)
        compiled(paths.kind, paths.order, anchor, legs, e, mirror, first, unfolded)
        return mirror, first, unfolded
    first = np.full(n, FirstLeg.fermat)
    direct = paths.kind == KIND["direct"]
    mirror[direct] = np.eye(3)
    first[direct] = FirstLeg.fixed
    one = (paths.kind == KIND["specular"]) & (paths.order == 1)
    if one.any():
        normal = emitter_m - paths.anchor_m[one]
        normal /= row_norms(normal, keepdims=True)
        mirror[one] = np.eye(3) - 2 * normal[:, :, None] * normal[:, None, :]
        first[one] = FirstLeg.fixed
    first[paths.kind == KIND["point"]] = FirstLeg.exact
    # the first leg where there is one, else (an image source) its distance
    unfolded = np.array(paths.first_leg_m, float)
    image = np.flatnonzero(~(unfolded > 0))
    unfolded[image] = row_norms(paths.anchor_m[image] - emitter_m)
    return mirror, first, np.maximum(unfolded, 1e-6)


def _second_order_mirror(e, dep, x2, image):
    """The linear part J (S, 3, 3) of a second-order image source ``A = J e + b`` from
    the emitter e (3,), the departure (S, 3), the last reflection point x2 (S, 3) and
    the image (S, 3); and where it is valid (S,).

    The first reflection point is ``x1 = e + s dep`` with ``s + |x2 - x1| = |x2 - A|``
    (unfolded, the first image lies on the line x2 -> x1 at the distance of A from
    x2): ``s = (R^2 - |w|^2) / (2 (R - w.dep))``, w = x2 - e, R = |x2 - A|; the
    normals follow from the law of reflection at x1 and x2.
    """
    w = x2 - e
    R = row_norms(x2 - image)
    den = 2 * (R - np.einsum("si,si->s", w, dep))
    s = (R**2 - np.einsum("si,si->s", w, w)) / np.where(np.abs(den) > 1e-12, den, 1.0)
    x1 = e + s[:, None] * dep
    u = x2 - x1
    u /= np.maximum(row_norms(u, keepdims=True), 1e-12)
    out = x2 - image
    out /= np.maximum(row_norms(out, keepdims=True), 1e-12)
    n1, n2 = u - dep, out - u
    n1 /= np.maximum(row_norms(n1, keepdims=True), 1e-12)
    n2 /= np.maximum(row_norms(n2, keepdims=True), 1e-12)
    eye = np.eye(3)
    M1 = eye - 2 * n1[:, :, None] * n1[:, None, :]
    M2 = eye - 2 * n2[:, :, None] * n2[:, None, :]
    J = M2 @ M1
    # valid: a proper solution that maps the departure onto the last leg
    ok = (np.abs(den) > 1e-12) & (s > 0)
    ok &= row_norms(np.einsum("sij,sj->si", J, dep) - out) < 1e-6
    return J, ok
