"""Stage 4 of the tracer: scattering from curved and rough surfaces towards the receiver.

Every hit on a curved face, or on a face whose material has a diffuse part, re-radiates
the ray's power towards the receiver (the array centre):

1. Select the hits on scattering faces.
2. Connect each to the receiver: it must face the receiver and the whole path must fit
   in ``max_path_m``.
3. A shadow ray from the hit to the receiver checks the view.
4. Intensity at the receiver: power x pattern / r^2, with the pattern a Gaussian lobe
   of width ``lobe_deg`` around the mirror direction (curved faces, from the second
   reflection on: the first-order glints are exact, :mod:`.glints`; weight
   ``(1 - diffuse) R^2``, normalised over the hemisphere for small lobes) plus a
   Lambert lobe (weight ``diffuse R^2``).  The Gaussian lobe is a sampling kernel: as
   rays are added, the energy of a glint converges to geometric optics whatever its
   width, but the lobe spreads that energy over nearby points, so its delay spread
   grows with the width (about ``sigma^2 r / 4`` of path along a pipe's axis).
5. With frequency-dependent materials, the lobe part and the Lambert part of a hit
   on such a material are separate contributions (a specular and a diffuse
   interaction: :mod:`acousim.core.materials`), each carrying the ray's earlier
   interactions plus its own.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from acousim.trace.rays.shoot import Hits
from acousim.trace.world.build import World
from acousim.trace.world.embree import RayCaster
from processing.base.kernels import optional_kernel

__all__ = ["Contributions", "scatter", "scatter_rows", "take"]


@dataclass(frozen=True, eq=False)
class Contributions:
    """Scattered contributions at the receiver.  K contributions."""

    point_m: np.ndarray
    """(K, 3) where they scatter, m."""
    intensity: np.ndarray
    """(K,) at the receiver, 1/m^2 for a unit-power emitter."""
    first_leg_m: np.ndarray
    """(K,) path length emitter -> point, m."""
    last_leg_m: np.ndarray
    """(K,) path length point -> receiver, m."""
    departure: np.ndarray
    """(K, 3) unit direction leaving the emitter."""
    surface: np.ndarray
    """(K,) int, :attr:`World.surface` id."""
    order: np.ndarray
    """(K,) int, reflections including the scattering one."""
    lambert: np.ndarray
    """(K,) bool, a Lambert part only (a planar face, or a curved face at the first
    reflection, whose glint is :mod:`.glints`'s)."""
    interactions: np.ndarray | None = None
    """(K, C) int, frequency-dependent material interactions (C =
    ``World.n_interactions``)."""

    def __len__(self) -> int:
        return self.intensity.size


def scatter(
    world: World, caster: RayCaster, hits: Hits, receiver: np.ndarray, max_path_m: float
) -> Contributions:
    """What the hits of `hits` scatter to `receiver` (3,)."""
    return scatter_rows(world, caster, hits, receiver, max_path_m)[0]


def scatter_rows(
    world: World, caster: RayCaster, hits: Hits, receiver: np.ndarray, max_path_m: float
) -> tuple[Contributions, np.ndarray]:
    """:func:`scatter`'s contributions and the hit (an index into `hits`) of each
    (K,): its order, the order of the hits that make them (so the contributions
    of some of the hits are those of these hits alone, in order: :func:`take`)."""
    diffuse = world.face_values("diffuse")
    # 1. hits on scattering faces
    sc = world.curved[hits.face] | (diffuse[hits.face] > 0)
    source = np.flatnonzero(sc)
    # (np.take: rows of (K, 3) arrays several times faster than a[sc])
    x, normal, mirror = (
        np.take(a, source, axis=0) for a in (hits.point_m, hits.normal, hits.mirror)
    )
    power, length, f = hits.power[sc], hits.length_m[sc], hits.face[sc]
    # 2. towards the receiver, facing it, within the path budget
    eps = caster.offset_m
    v, r2, u, cos_s, ok, start = _towards(x, normal, length, receiver, max_path_m, eps)
    # 3. shadow ray towards the receiver
    idx = np.flatnonzero(ok)
    t, hit = caster.first_hit(np.take(start, idx, axis=0), np.take(v, idx, axis=0))
    ok[idx[(hit >= 0) & (t < r2[idx] - eps)]] = False
    # 4. the scattering pattern
    order = hits.order[sc]
    lobe_part, lambert_part = _pattern(world, u, mirror, cos_s, f, order)
    lambert = ~world.curved[f] | (order == 1)
    history = np.take(hits.interactions, source, axis=0)

    def at_receiver(pattern):
        return np.where(ok, power * pattern / np.maximum(r2, 1e-12) ** 2, 0.0)

    if world.spectra is None:
        parts = [(at_receiver(lobe_part + lambert_part), history)]
    else:  # 5. the two interactions apart, each with its own count
        parts = []
        for mode, part in enumerate((lobe_part, lambert_part)):
            counts = history.copy()
            c = world.face_interactions(mode)[f]
            counts[np.flatnonzero(c >= 0), c[c >= 0]] += 1
            parts.append((at_receiver(part), counts))
    rows = [source[intensity > 0] for intensity, _ in parts]
    geometry = (x, length, r2, order, lambert, world.surface[f])
    out = [_kept(geometry, hits.departure, source, *part) for part in parts]
    if len(out) == 1:
        return out[0], rows[0]
    both = Contributions(
        *(np.concatenate([getattr(c, k.name) for c in out]) for k in fields(Contributions))
    )
    return both, np.concatenate(rows)


def _kept(geometry: tuple, departure, source, intensity, counts) -> Contributions:
    """The contributions of the scattering hits `source` (K,) (indices of the hits;
    their departures among all (H, 3)) whose `intensity` (K,) is positive; geometry:
    their points (K, 3), path lengths, last legs, orders, Lambert flags and surfaces
    (K,); counts: their interactions (K, C)."""
    x, length, r2, order, lambert, surface = geometry
    keep = np.flatnonzero(intensity > 0)
    return Contributions(
        np.take(x, keep, axis=0),
        intensity[keep],
        length[keep],
        r2[keep],
        np.take(departure, source[keep], axis=0),
        surface[keep],
        order[keep],
        lambert[keep],
        np.take(counts, keep, axis=0),
    )


def take(c: Contributions, mask: np.ndarray | slice) -> Contributions:
    """The contributions `c` where `mask` (K,) holds, in their order (a slice: views)."""
    return Contributions(
        *(None if (v := getattr(c, k.name)) is None else v[mask] for k in fields(Contributions))
    )


def _towards(x, normal, length, receiver, max_path_m, eps) -> tuple:
    """Steps 2 and 3 before the shadow rays, for hits x (K, 3) with `normal` (K, 3)
    at path `length` (K,): the vectors to the receiver (K, 3), their lengths (K,),
    unit directions (K, 3), the cosines to the normal (K,), whether facing the
    receiver within `max_path_m` (K,), and the shadow rays' starts (K, 3), x moved
    `eps` along the normal (compiled, :func:`.bounce_kernel.towards`, or in numpy:
    the same numbers)."""
    kernel = optional_kernel("acousim.trace.rays.bounce_kernel", "towards")
    if kernel is None:
        v = receiver - x
        r2 = np.linalg.norm(v, axis=1)
        u = v / np.maximum(r2, 1e-12)[:, None]
        cos_s = np.einsum("ij,ij->i", u, normal)
        ok = (cos_s > 0) & (length + r2 <= max_path_m)
        return v, r2, u, cos_s, ok, x + eps * normal
    K = len(x)
    v, u, start = np.empty((3, K, 3))
    r2, cos_s, ok = np.empty(K), np.empty(K), np.empty(K, bool)
    receiver = np.asarray(receiver, float)
    kernel(x, normal, length, receiver, float(max_path_m), eps, v, r2, u, cos_s, ok, start)
    return v, r2, u, cos_s, ok, start


def _pattern(world: World, u, mirror, cos_s, f, order) -> tuple[np.ndarray, np.ndarray]:
    """The scattering pattern towards the unit directions `u` (N, 3) of hits on faces
    `f` (N,) of reflection `order` (N,): the specular lobe of a curved face (about
    the mirror direction (N, 3); first order is the glints' business) and the Lambert
    part (``cos_s`` (N,) the cosine to the face normal)."""
    diffuse = world.face_values("diffuse")
    R2 = world.face_values("reflection")[f] ** 2
    sig = np.deg2rad(world.face_values("lobe_deg"))[f]
    psi = np.arccos(np.clip(np.einsum("ij,ij->i", u, mirror), -1, 1))
    spec = np.where(world.curved[f] & (order > 1), (1 - diffuse[f]) * R2, 0.0)
    lobe_part = spec * np.exp(-0.5 * (psi / sig) ** 2) / (2 * np.pi * sig**2)
    return lobe_part, diffuse[f] * R2 * cos_s / np.pi
