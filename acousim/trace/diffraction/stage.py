"""The edge-diffraction stage: first-order BTM diffraction of every edge in view,
edge to edge where a pair of edges can reach the energy floor, and (as an option)
an edge with one specular reflection before or after it.

Input: the scene's diffracting geometry (:class:`DiffractingGeometry`: edges,
planes, materials), the ray caster, the emitter and the receiver (the array
centre).  Output: one point reflector per edge element (:mod:`acousim.trace.diffraction.btm`)
in the tracer's path form, so synthesis, air absorption, directivity and noise
apply unchanged.

Steps of :func:`diffract` (each in its own module):

1. Cull edges that cannot contribute within ``max_path_m`` (shortest path from the
   emitter over the edge's segment to the receiver is longer).
2. Keep the edges whose side holding the emitter and the receiver is a convex wedge
   (:meth:`Edges.oriented`) and that both see at one of five points along the edge
   (rays); their BTM elements for the emitter and the receiver, all edges in one
   vectorised pass (edge-element step ``step_m``), with the faces' reflection
   factors applied to the terms of their images (:mod:`.first_order`).
3. Visibility: an element is kept only if nothing lies between it and the emitter
   and between it and the receiver: one ray each way through the Embree scene,
   blocked if it meets a face before the element (by more than the caster's
   ``tolerance_m``: the element lies on its own faces).  Elements below the floor
   (``floor_db`` under the strongest one, or ``floor_level``) are dropped first.
4. ``order`` 2: edge to edge over pairs of edges that share a plane, each pair
   integrated only if a closed-form bound of its largest path reaches that floor
   (:mod:`.edge_to_edge`, :mod:`.pair_bound`, :mod:`.btm_pairs`).
5. ``reflections``: the same as 2-3 with the emitter replaced by its image in each
   planar face of the scene (a specular reflection before the edge) and the
   receiver by its image (a reflection after the edge) (:mod:`.edge_reflected`).

:func:`edge_diffraction` is the tracer's stage 3: :func:`diffract` on the
:class:`DiffractingGeometry` of a world (built once per world), its paths in the
tracer's form with kind ``"diffraction"``.

Valid where the edges are straight and their faces nearly rigid (BTM is exact for
an infinite rigid wedge; a finite edge is integrated over its length).  Not
modelled: edge to edge between edges that share no plane, third order, edge to
edge with reflections; diffraction of the diffuse and curved-surface parts.
"""

from __future__ import annotations

import numpy as np

from acousim.trace.diffraction.btm import DEFAULT_STEP_M
from acousim.trace.diffraction.edge_reflected import reflected_paths
from acousim.trace.diffraction.edge_to_edge import edge_to_edge
from acousim.trace.diffraction.first_order import edges_in_view, pose_edges, visible
from acousim.trace.diffraction.paths import DiffractedPaths, concatenate, element_paths, empty_paths
from acousim.trace.diffraction.setup import DiffractingGeometry, DiffractionOptions, StageContext
from acousim.trace.paths import KIND, TracedPaths

__all__ = [
    "DiffractedPaths",
    "DiffractingGeometry",
    "DiffractionOptions",
    "diffract",
    "edge_diffraction",
    "DEFAULT_STEP_M",
]


def diffract(
    geometry: DiffractingGeometry,
    caster,
    emitter: np.ndarray,
    receiver: np.ndarray,
    options: DiffractionOptions,
) -> DiffractedPaths:
    """The diffraction paths of one pose (see the module docstring).

    geometry: the world's edges, planes and materials; caster: the RayCaster (None:
    no occlusion); emitter, receiver (3,); options: step, order, reflections and
    floors (:class:`DiffractionOptions`).  Edge to edge needs ``geometry.face_plane``,
    the reflections ``geometry.planes``.
    """
    emitter, receiver = np.asarray(emitter, float), np.asarray(receiver, float)
    edges = geometry.edges
    if len(edges) == 0:
        return empty_paths()
    ctx = StageContext(geometry, caster, emitter, receiver, options)
    # 1-2. direct legs
    pose = pose_edges(ctx)
    if not (pose.convex_e.any() or options.reflections):
        # no edge is a convex wedge on the emitter's side (inside a box room, every
        # edge is a 90-degree corner): neither an edge alone nor edge to edge (its
        # first edge is one of these) diffracts; nothing asked of the caster
        return empty_paths()
    near = pose.dist_e + pose.dist_r
    el, owner, counts = edges_in_view(ctx, np.flatnonzero(near <= options.max_path_m))
    # 3. visibility both ways (of the elements above the floor)
    size = np.abs(el.amplitude)
    floor = max(size.max(initial=0.0) * 10 ** (options.floor_db / 20), options.floor_level)
    strong = size >= floor
    ok = strong.copy()
    pts = np.take(el.point_m, np.flatnonzero(strong), axis=0)
    ends = np.concatenate(
        [np.broadcast_to(emitter, pts.shape), np.broadcast_to(receiver, pts.shape)]
    )
    free = visible(caster, ends, np.concatenate([pts, pts]), ctx.tol)  # one batch
    ok[strong] = free[: len(pts)] & free[len(pts) :]
    out = [element_paths(el, owner, ok, emitter, counts)]
    # 4. edge to edge
    if options.order >= 2 and geometry.face_plane is not None:
        out.append(edge_to_edge(ctx, floor))
    # 5. one reflection before or after the edge
    if options.reflections and geometry.planes is not None:
        out.extend(reflected_paths(ctx, before, floor) for before in (True, False))
    return concatenate(out)


def edge_diffraction(
    geometry: DiffractingGeometry,
    caster,
    emitter: np.ndarray,
    receiver: np.ndarray,
    options: DiffractionOptions,
) -> TracedPaths:
    """Stage 3 of the tracer: :func:`diffract` as :class:`TracedPaths` of kind
    ``"diffraction"`` (order 1, or 2 with a reflection before or after the edge or
    with a second edge)."""
    d = diffract(geometry, caster, emitter, receiver, options)
    kind = np.full(len(d), KIND["diffraction"])
    return TracedPaths(
        d.anchor_m,
        d.first_leg_m,
        d.strength,
        d.position_m,
        d.order,
        kind,
        d.departure,
        interactions=d.counts,
    )
