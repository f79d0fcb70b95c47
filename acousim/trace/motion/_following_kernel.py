"""Compiled part of :meth:`acousim.trace.motion.following.MovingPaths.from_traced`
(numba; optional: without numba the same arithmetic runs on whole arrays in numpy
there): the mirrors and first-leg codes of the direct path, the first-order
specular paths and the rest, and the lengths of the Fermat terms, in one pass
over the paths where numpy takes a dozen small array operations."""

from __future__ import annotations

import math

from numba import njit

from acousim.trace.motion.following import FirstLeg
from acousim.trace.paths import PathKind

# the codes, read from their enums (constants of the compiled code)
_DIRECT, _SPECULAR, _POINT = int(PathKind.direct), int(PathKind.specular), int(PathKind.point)
_FIXED, _FERMAT, _EXACT = int(FirstLeg.fixed), int(FirstLeg.fermat), int(FirstLeg.exact)


@njit(cache=True, nogil=True)
def static_legs(kind, order, anchor, legs, emitter, mirror, first, unfolded):  # pragma: no cover
    """Into `mirror` (N, 3, 3), zeros on entry: the identity for the direct path,
    ``I - 2 n n^T`` for a first-order specular path (n the unit vector from its
    anchor to the `emitter` (3,)); into `first` (N,) the FirstLeg codes (fixed for
    those, exact for a point, Fermat else: second-order mirrors are the caller's);
    into `unfolded` (N,) the first legs `legs` (N,) where positive, else the
    anchor's distance from the emitter, at least 1e-6 m.  kind, order (N,) int;
    anchor (N, 3) m.  The operations of the array version, in its order."""
    for n in range(kind.size):
        k = kind[n]
        code = _FERMAT
        if k == _DIRECT:
            mirror[n, 0, 0] = mirror[n, 1, 1] = mirror[n, 2, 2] = 1.0
            code = _FIXED
        elif k == _SPECULAR and order[n] == 1:
            dx = emitter[0] - anchor[n, 0]
            dy = emitter[1] - anchor[n, 1]
            dz = emitter[2] - anchor[n, 2]
            norm = math.sqrt(dx * dx + dy * dy + dz * dz)
            u = (dx / norm, dy / norm, dz / norm)
            for i in range(3):
                for j in range(3):
                    mirror[n, i, j] = (1.0 if i == j else 0.0) - 2 * u[i] * u[j]
            code = _FIXED
        elif k == _POINT:
            code = _EXACT
        first[n] = code
        leg = legs[n]
        if not leg > 0:  # an image source (or NaN): its distance
            ax = anchor[n, 0] - emitter[0]
            ay = anchor[n, 1] - emitter[1]
            az = anchor[n, 2] - emitter[2]
            leg = math.sqrt(ax * ax + ay * ay + az * az)
        unfolded[n] = leg if not leg < 1e-6 else 1e-6  # (np.maximum: NaN stays)
