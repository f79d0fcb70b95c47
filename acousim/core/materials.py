"""Frequency-dependent materials: a material's reflection and diffuse fraction as
tables over frequency, and the factor they put in a path's response.

A material table gives the pressure reflection coefficient R and the diffuse
fraction d at increasing frequencies f_1 < ... < f_J.  Between two table
frequencies each is interpolated linearly in frequency; below f_1 and above f_J it
holds the end value (``numpy.interp``).  A reflection splits into two interactions
with pressure gains

* specular: ``s(f) = R(f) sqrt(1 - d(f))`` (image sources, glints, the rays that
  continue), and
* diffuse: ``l(f) = R(f) sqrt(d(f))`` (the Lambert part).

The tracer works with one number per interaction, a reference gain (``s_ref``,
``l_ref``: the gains at the material's reference values, :func:`reference`), so that
a path's strength, its energy floor and its ground-truth level are those at the
reference; every path counts how many interactions of each kind it had with each
frequency-dependent material (an (N, K) integer array, K columns: see
:class:`MaterialSpectra`), and the renderer multiplies its response by
``prod_k (g_k(f) / g_k_ref) ** count_k``.  A scene whose materials are all single
numbers has K = 0: nothing changes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["MaterialSpectra", "interpolate", "gains", "reference", "MODES"]

#: the interactions of a reflection, in column order for each material
MODES = ("specular", "diffuse")


def interpolate(freqs_hz, table_hz, values) -> np.ndarray:
    """Linear interpolation of a table (J,) at frequencies (any shape), held constant
    outside the table's range."""
    return np.interp(np.asarray(freqs_hz, float), np.asarray(table_hz, float), values)


def gains(freqs_hz, table_hz, reflection, diffuse) -> tuple[np.ndarray, np.ndarray]:
    """Specular and diffuse pressure gains ``(s(f), l(f))`` of a material table (see
    the module docstring); `reflection` and `diffuse` are (J,) arrays or numbers."""
    R = interpolate(freqs_hz, table_hz, np.broadcast_to(reflection, np.shape(table_hz)))
    d = interpolate(freqs_hz, table_hz, np.broadcast_to(diffuse, np.shape(table_hz)))
    return R * np.sqrt(1 - d), R * np.sqrt(d)


def reference(table_hz, reflection, diffuse) -> tuple[float, float]:
    """The scalar reflection and diffuse fraction the tracer uses for a table: the
    largest reflection of the table (so the energy floor never drops a path that is
    loud somewhere in the table) and the mean diffuse fraction over the table's
    range (trapezoidal; positive whenever some frequency scatters, below 1 whenever
    some frequency reflects specularly)."""
    f = np.asarray(table_hz, float)
    R = np.broadcast_to(np.asarray(reflection, float), f.shape)
    d = np.broadcast_to(np.asarray(diffuse, float), f.shape)
    r_ref = float(R.max())
    d_ref = float(d[0]) if f.size < 2 else float(np.trapezoid(d, f) / (f[-1] - f[0]))
    return r_ref, min(max(d_ref, 0.0), 1.0)


@dataclass(frozen=True, eq=False)
class MaterialSpectra:
    """The frequency-dependent materials of a world, K = 2 J columns (J materials;
    column ``2 j`` the specular and ``2 j + 1`` the diffuse interaction of material
    j, :data:`MODES`).

    names : (J,) material names; tables_hz : J arrays of table frequencies (Hz);
    reflection, diffuse : J arrays of the same lengths; ref : (J, 2) the reference
    reflection and diffuse fraction the tracer used (:func:`reference`).
    """

    names: tuple[str, ...]
    tables_hz: tuple[np.ndarray, ...]
    reflection: tuple[np.ndarray, ...]
    diffuse: tuple[np.ndarray, ...]
    ref: np.ndarray

    @property
    def n_columns(self) -> int:
        return 2 * len(self.names)

    def ratios(self, freqs_hz: np.ndarray) -> np.ndarray:
        """(F, K): each interaction's gain at `freqs_hz` over its reference gain (0
        where the reference gain is 0: the path carries no energy of that kind)."""
        out = np.zeros((np.size(freqs_hz), self.n_columns))
        for j, (f, R, d) in enumerate(zip(self.tables_hz, self.reflection, self.diffuse)):
            s, l_ = gains(freqs_hz, f, R, d)
            r0, d0 = self.ref[j]
            for col, g, g0 in ((2 * j, s, r0 * np.sqrt(1 - d0)), (2 * j + 1, l_, r0 * np.sqrt(d0))):
                out[:, col] = g / g0 if g0 > 0 else 0.0
        return out

    def factor(self, freqs_hz: np.ndarray, counts: np.ndarray) -> np.ndarray:
        """(F, N): the response factor of N paths with interaction counts (N, K)."""
        ratio = self.ratios(freqs_hz)
        H = np.ones((np.size(freqs_hz), counts.shape[0]))
        for k in np.flatnonzero(counts.any(axis=0)):
            H *= ratio[:, k : k + 1] ** counts[None, :, k]
        return H
