"""The ray-casting backend: Embree through embreex, behind one small interface.

Geometry is handed to Embree in float32 relative to a local origin (the centre of
the scene's bounding box), so that a scene 1 km from the world origin casts the
same rays as the same scene at the origin.  Exact path geometry (image sources,
reflection points, delays) is computed in float64 elsewhere; Embree only says which
face a ray meets first and roughly where.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from processing.base.kernels import optional_kernel

__all__ = ["RayCaster", "RAY_OFFSET", "DISTANCE_TOLERANCE"]

_MIN_CHUNK = 20000

#: a secondary ray starts this far off its surface (absolute m, relative to the
#: scene's size): enough for Embree's float32 not to hit the surface it leaves
RAY_OFFSET = (1e-7, 1e-6)
#: two distances along a ray agree within this (absolute m, relative to the scene's
#: size): Embree's float32 hit distances against float64 geometry
DISTANCE_TOLERANCE = (1e-6, 1e-4)


class RayCaster:
    """First-hit queries against a triangle soup, using both cores.

    Parameters
    ----------
    triangles : ndarray, shape (F, 3, 3)
        Triangle vertices in world metres (float64).
    threads : worker threads for large batches of rays.
    indexed : optional (vertices (V, 3), faces (F, 3)), the same triangles as a
        vertex table and indices (``vertices[faces] == triangles``): handed to Embree
        as its indexed mesh, no per-corner copy (the same hits, built faster); every
        vertex must be a corner of a face.
    """

    def __init__(
        self,
        triangles: np.ndarray,
        threads: int = 2,
        indexed: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        try:
            import embreex.mesh_construction as mc
            import embreex.rtcore_scene as rtcs
        except ImportError as exc:  # pragma: no cover - depends on the install
            raise ImportError(
                "ray tracing meshes needs embreex: pip install 'acousim[sim]'"
            ) from exc
        # every vertex of an indexed mesh is a corner of a face (World's contract)
        corners = np.asarray(triangles if indexed is None else indexed[0], dtype=np.float64)
        corners = corners.reshape(-1, 3)
        lo, hi = corners.min(axis=0), corners.max(axis=0)
        self.origin = (lo + hi) / 2
        self.scale = float(np.linalg.norm(hi - lo)) or 1.0
        self._scene = rtcs.EmbreeScene()
        local = (corners - self.origin).astype(np.float32)
        if indexed is None:
            self._mesh = mc.TriangleMesh(self._scene, local.reshape(-1, 3, 3))
        else:
            faces = np.ascontiguousarray(indexed[1], np.int32)
            self._mesh = mc.TriangleMesh(self._scene, local, faces)
        self.threads = max(1, int(threads))
        self._pools: dict[int, ThreadPoolExecutor] = {}  # by process id: see _pool
        self.rays_cast = 0
        #: offsets and tolerances scaled to this scene (m): see RAY_OFFSET and
        #: DISTANCE_TOLERANCE
        self.offset_m = RAY_OFFSET[0] + RAY_OFFSET[1] * self.scale
        self.tolerance_m = DISTANCE_TOLERANCE[0] + DISTANCE_TOLERANCE[1] * self.scale

    @property
    def _pool(self) -> ThreadPoolExecutor | None:
        """The caster's worker threads in this process (None: one thread), started on
        first use: a forked child (:meth:`commit`) has none of its parent's threads,
        so it starts its own."""
        if self.threads < 2:
            return None
        pid = os.getpid()
        if pid not in self._pools:
            self._pools[pid] = ThreadPoolExecutor(self.threads)
        return self._pools[pid]

    def commit(self) -> None:
        """Build Embree's acceleration structure now (embreex builds it at the first
        query, on Embree's own threads).  Before forking a process that casts rays: a
        forked child has none of the parent's threads, so it must only query a
        structure built in the parent, never build one."""
        if not self._scene.is_committed:
            self.first_hit(np.zeros((1, 3)) + self.origin, np.array([[0.0, 0.0, 1.0]]))
            self.rays_cast -= 1

    def map(self, fn, items: list) -> list:
        """``[fn(x) for x in items]`` on the caster's worker threads (in this thread
        when it has one): for work that releases the GIL, as Embree does."""
        pool = self._pool
        if pool is None or len(items) < 2:
            return [fn(x) for x in items]
        return list(pool.map(fn, items))

    def occluded(
        self, origins: np.ndarray, directions: np.ndarray, max_distance: np.ndarray | float
    ) -> np.ndarray:
        """(N,) True where a ray meets a face at a distance of at most `max_distance`
        (m, one or (N,); none where it is not positive) along its unit direction:
        Embree's occlusion query, which stops at any hit (about half the time of
        :meth:`first_hit` on the stage's visibility rays); the same answer as
        ``first_hit(origins, directions, d)[0] <= d`` but at hits within Embree's
        float32 rounding of `max_distance`.  `directions` need not be normalised."""
        o, d = self._rays(origins, directions)
        n = o.shape[0]
        self.rays_cast += n
        reach = np.broadcast_to(np.asarray(max_distance, float), (n,))
        ask = np.flatnonzero(reach > 0)  # Embree reads a negative reach as a hit
        out = np.zeros(n, bool)
        if ask.size == 0:
            return out

        def run(sl: slice) -> np.ndarray:
            at = ask[sl]
            ids = self._scene.run(
                np.ascontiguousarray(o[at]),
                np.ascontiguousarray(d[at]),
                dists=np.ascontiguousarray(reach[at], np.float32),
                query="OCCLUDED",
            )
            return np.asarray(ids) >= 0

        out[ask] = np.concatenate(self._in_parts(run, ask.size))
        return out

    def _in_parts(self, run, n: int) -> list:
        """`run` (a slice -> its rays' result) over n rays: at once, or in one slice
        per thread on the pool when there are enough rays (Embree releases the GIL)."""
        pool = self._pool if n >= 2 * _MIN_CHUNK else None
        if pool is None:
            return [run(slice(0, n))]
        bounds = np.linspace(0, n, self.threads + 1).astype(int)
        return list(pool.map(run, [slice(a, b) for a, b in zip(bounds[:-1], bounds[1:])]))

    def _rays(self, origins, directions) -> tuple[np.ndarray, np.ndarray]:
        """The rays as Embree takes them: origins (N, 3) relative to :attr:`origin`
        and unit directions (N, 3), float32 (compiled, :mod:`.embree_kernel`, or in
        numpy: the same numbers)."""
        o = np.asarray(origins, float)
        d = np.asarray(directions, float)
        kernel = optional_kernel("acousim.trace.world.embree_kernel", "prepare")
        if kernel is None or o.ndim != 2 or d.shape != o.shape or o.shape[-1] != 3:
            o = o - self.origin
            norm = np.sqrt(np.add.reduce(d * d, axis=1, keepdims=True))  # np.linalg.norm's
            d = d / np.where(norm > 0, norm, 1)
            return o.astype(np.float32), d.astype(np.float32)
        o32, d32 = np.empty(o.shape, np.float32), np.empty(o.shape, np.float32)
        kernel(o, d, self.origin, o32, d32)
        return o32, d32

    def first_hit(
        self,
        origins: np.ndarray,
        directions: np.ndarray,
        max_distance: np.ndarray | float | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Distance (N,) to the first face hit (inf: none) and its index (N,, -1: none).

        `directions` need not be normalised; distances are along unit directions.
        """
        o, d = self._rays(origins, directions)
        n = o.shape[0]
        self.rays_cast += n
        if n == 0:
            return np.zeros(0), np.zeros(0, int)
        dist = None
        if max_distance is not None:
            dist = np.broadcast_to(np.asarray(max_distance, np.float32), (n,)).copy()

        def run(sl: slice):
            res = self._scene.run(
                np.ascontiguousarray(o[sl], np.float32),
                np.ascontiguousarray(d[sl], np.float32),
                dists=None if dist is None else dist[sl],
                output=1,
            )
            return res["tfar"], res["primID"]

        parts = self._in_parts(run, n)
        if len(parts) == 1:
            t, face = parts[0][0].astype(float), parts[0][1].astype(int)
        else:
            t = np.concatenate([p[0] for p in parts]).astype(float)
            face = np.concatenate([p[1] for p in parts]).astype(int)
        miss = face < 0
        t[miss] = np.inf
        face[miss] = -1
        return t, face
