"""What the edge-diffraction stage works with: the world's diffracting geometry
(built once per world), the options of a pose's stage, and both with the pose's
emitter and receiver (:class:`StageContext`, passed to each of its steps)."""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

import numpy as np

from acousim.scene.model import Diffraction
from acousim.trace.world.build import World
from acousim.trace.world.edges import Edges, merge_collinear, world_edges
from acousim.trace.world.embree import DISTANCE_TOLERANCE, RAY_OFFSET

__all__ = ["DiffractingGeometry", "DiffractionOptions", "StageContext"]


@dataclass(frozen=True, eq=False)
class DiffractingGeometry:
    """What the stage needs of a world, built once per world (not per pose).

    edges: its diffracting edges (:func:`~acousim.trace.world.edges.world_edges`, collinear
    pieces joined by :func:`~acousim.trace.world.edges.merge_collinear`); face_reflection (F,):
    pressure
    reflection factor per face; planes: (normal (P, 3), offset (P,), reflection (P,))
    of every plane, for the reflections before or after an edge (None: none);
    face_plane (F,): the plane id of each face (which edges share a plane, for edge
    to edge; None: no edge to edge); face_column (F,), plane_column (P,): the
    specular interaction column of each face's and plane's frequency-dependent
    material (-1: single numbers; None: a world without tables).
    """

    edges: Edges
    face_reflection: np.ndarray
    planes: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    face_plane: np.ndarray | None = None
    face_column: np.ndarray | None = None
    plane_column: np.ndarray | None = None
    #: what the stage keeps between poses (edge to edge's pair table, replaced when
    #: its caster or tolerance changes; per-edge constants: :meth:`kept`); guarded
    #: by `memo_lock`; a geometry made from another (dataclasses.replace) starts
    #: with its own
    memo: dict = field(default_factory=dict, init=False, repr=False, compare=False)
    memo_lock: threading.Lock = field(
        default_factory=threading.Lock, init=False, repr=False, compare=False
    )

    def kept(self, key: str, build):
        """``memo[key]``, built by ``build()`` on first use: for what depends on the
        geometry alone (not on the caster or the pose).  Built outside `memo_lock`
        (a build may ask for another entry); two threads that build one at once
        keep the first (builds are deterministic)."""
        with self.memo_lock:
            value = self.memo.get(key)
        if value is None:
            value = build()
            with self.memo_lock:
                value = self.memo.setdefault(key, value)
        return value

    @classmethod
    def of(cls, world: World) -> DiffractingGeometry:
        refl = world.face_values("reflection")
        first = world.plane_first
        planes = (world.normals[first], world.offsets[first], refl[first])
        column = world.face_interactions(0)
        key = world.plane * (int(world.material.max(initial=0)) + 1) + world.material
        return cls(
            merge_collinear(world_edges(world), key),
            refl,
            planes,
            world.plane,
            column,
            None if column is None else column[first],
        )


@dataclass(frozen=True)
class DiffractionOptions:
    """How one pose's stage runs (SI units).

    settings: the scene's :class:`~acousim.scene.model.Diffraction` (order, element
    step, reflections), passed whole; max_path_m: longest path kept; floor_db:
    elements weaker than this (dB, negative) relative to the strongest first-order one
    are dropped before their visibility is checked (pass the tracer's energy floor: its
    strongest echo is at least as strong, so nothing it would keep is lost);
    floor_level: elements (and edge pairs whose bound is) weaker than this gain at the
    receiver are dropped too (the tracer passes its energy floor under the strongest
    echo found before this stage); select_pairs: False integrates every edge pair in
    full (to measure what the selection skips); pair_step_m: the element step of edge
    to edge (excess path length, m; None: the settings' step); its bins stay
    ``step_m / 4`` wide.  Order 2 adds edge to edge over the pairs of edges that share a
    plane whose closed-form bound reaches the floor (:mod:`acousim.trace.diffraction.pair_bound`).
    min_path_m: the paths shorter than this (m, at the receiver) are not asked for
    (the tracer drops them after the stage: a call heard late in another sonar's
    window, :func:`acousim.trace.paths.reaching`); an edge or a pair of edges whose
    every path is shorter is integrated only if its bound reaches the strongest
    echo found before the stage (:meth:`needed`).
    """

    max_path_m: float
    settings: Diffraction = Diffraction()
    floor_db: float = -np.inf
    floor_level: float = 0.0
    select_pairs: bool = True
    pair_step_m: float | None = None
    min_path_m: float = 0.0

    def needed(self, floor: float, longest_m: np.ndarray) -> np.ndarray | float:
        """The gain at the receiver (per item) that the bound of an edge or of a pair
        of edges whose paths are at most `longest_m` long (m, (N,)) must reach for
        it to be integrated: `floor`; where every path is shorter than
        ``min_path_m``, also the strongest echo found before the stage (the
        reference of ``floor_level``): its paths are dropped after the trace, and
        one weaker than that echo changes neither the floors nor the strongest
        echo (the trace's other paths are those of the stage run in full)."""
        top = self.lead(floor)
        if top is None:
            return floor
        return np.where(np.asarray(longest_m) < self.min_path_m, top, floor)

    def lead(self, floor: float) -> float | None:
        """With ``min_path_m``: the gain at the receiver under which a path shorter
        than ``min_path_m`` may be left out (:meth:`needed`): the strongest echo
        found before the stage, at least `floor`; None: no path may be (no
        ``min_path_m``, no floor)."""
        if self.min_path_m <= 0 or self.floor_level <= 0 or not np.isfinite(self.floor_db):
            return None
        return max(floor, self.floor_level / 10 ** (self.floor_db / 20))

    @property
    def step_m(self) -> float:
        """The edge-element step (excess path length, m) of the settings."""
        return self.settings.step_m

    @property
    def order(self) -> int:
        """1: each edge alone; 2: also edge to edge."""
        return self.settings.order

    @property
    def reflections(self) -> bool:
        """Also edge + one specular reflection."""
        return self.settings.reflections


@dataclass(frozen=True, eq=False)
class StageContext:
    """One pose's stage: the geometry, the ray caster (None: no occlusion), the
    emitter and receiver (3,), the options, and the caster's distance tolerance and
    ray offset (m).  `cache`: what the pose's steps find once and share (the edges
    oriented for the emitter and the receiver, their distances, which probe points
    each sees: :func:`acousim.trace.diffraction.first_order.pose_edges`)."""

    geometry: DiffractingGeometry
    caster: object
    emitter: np.ndarray
    receiver: np.ndarray
    options: DiffractionOptions
    cache: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def tol(self) -> float:
        """Distances along a ray agree within this (m)."""
        return self.caster.tolerance_m if self.caster is not None else sum(DISTANCE_TOLERANCE)

    @property
    def nudge(self) -> float:
        """A ray leaves a surface this far off it (m)."""
        return self.caster.offset_m if self.caster is not None else sum(RAY_OFFSET)
