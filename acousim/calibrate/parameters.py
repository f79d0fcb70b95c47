"""What a calibration fits: every chosen material's reflection and diffuse fraction
(single numbers, or a table over frequency), as one parameter vector, and the
factor each group of paths gets from it in each frequency band, with its exact
derivatives.

A reflection off material j splits into a specular interaction of pressure gain
``a = R sqrt(1 - d)`` and a diffuse (Lambert) one of gain ``b = R sqrt(d)``
(:mod:`acousim.synth.materials`).  A path that met material j ``c_s`` times
specularly and ``c_l`` times diffusely carries ``a^c_s b^c_l``; the tracer traced it
at reference gains ``a_ref, b_ref``, so at parameters theta its gain is its traced
one times ``w(theta) = prod_j (a_j / a_ref)^c_s (b_j / b_ref)^c_l``: paths with the
same counts (a *signature*) share one factor, and

``d w / d theta = w sum_j c_s d log a_j / d theta + c_l d log b_j / d theta``

exactly.  The diffuse fraction is fitted through its amplitude ``u = sqrt(d)``
(``b = R u``, ``a = R sqrt(1 - u^2)``): a material may be perfectly specular
(``d = 0``, the bound, where ``b`` and the group of its diffuse paths vanish) and
every gain and derivative stays finite there.  In ``d`` itself ``log b`` would be
``-inf`` at 0 and ``d b / d d`` infinite, so ``d`` had to stop at a floor; the tail a
floor of 1e-4 leaves (40 dB under the specular echo) stands tens of dB above the
noise of a clean recording of a specular wall, and the fit lowered the reflection
to hide it.  A table of J points holds R and d at frequencies f_1 < ... < f_J, linear
between them and constant outside (as the renderer interpolates): at a band's centre
f_b, ``R(f_b) = sum_i phi_i(f_b) R_i`` with hat functions phi.  A single number is a
table of one point.  Parameters are ordered material by material, reflections first
(R_1..R_J, then the diffuse amplitudes u_1..u_J, ``d_i = u_i^2``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from acousim.scene.model import Material
from processing.base.errors import InputError

__all__ = [
    "MaterialFit",
    "ParameterSet",
    "hat_weights",
    "MIN_DIFFUSE",
    "MAX_DIFFUSE",
    "START_MIN_DIFFUSE",
]

#: bounds of a fitted diffuse fraction and reflection
MIN_DIFFUSE, MAX_DIFFUSE = 0.0, 0.999
MIN_REFLECTION, MAX_REFLECTION = 1e-3, 1.0
#: the least diffuse fraction a fit starts from: at ``d = 0`` the energy's slope in
#: ``u`` is only the coherent cross term of the diffuse and specular paths (of
#: either sign), which could hold the fit on the bound
START_MIN_DIFFUSE = 1e-4


def hat_weights(freqs_hz: np.ndarray, table_hz: np.ndarray) -> np.ndarray:
    """(F, J): the weights of linear interpolation in a table (J,) at `freqs_hz`
    (F,), held constant outside the table (``numpy.interp``'s rule)."""
    f = np.asarray(freqs_hz, float)
    t = np.asarray(table_hz, float)
    eye = np.eye(t.size)
    return np.stack([np.interp(f, t, eye[i]) for i in range(t.size)], axis=1)


@dataclass(frozen=True)
class MaterialFit:
    """One material to fit.

    name : the material's name in the scene; frequencies_hz : table frequencies (J,)
    (one frequency: a single number); reflection, diffuse : (J,) start values;
    fit_reflection, fit_diffuse : which of the two are free (the other held).
    """

    name: str
    frequencies_hz: tuple[float, ...]
    reflection: tuple[float, ...]
    diffuse: tuple[float, ...]
    fit_reflection: bool = True
    fit_diffuse: bool = True

    @property
    def n_points(self) -> int:
        return len(self.frequencies_hz)

    @property
    def is_table(self) -> bool:
        return self.n_points > 1

    @staticmethod
    def start(
        material: Material,
        table_khz: tuple[float, ...] | None = None,
        *,
        fit_reflection: bool = True,
        fit_diffuse: bool = True,
    ) -> MaterialFit:
        """The fit of `material` starting at its values; `table_khz`: fit it as a
        table at these frequencies (kHz, increasing; start values read from the
        material there), else as the material is (a table if it is one)."""
        if table_khz is not None:
            f = np.asarray(table_khz, float) * 1e3
            if f.size < 1 or np.any(np.diff(f) <= 0):
                raise InputError(
                    "table frequencies must increase strictly",
                    key=f"table[{material.name}]",
                    value=list(table_khz),
                )
        elif material.frequency_dependent:
            f = np.asarray(material.frequencies_khz, float) * 1e3
        else:
            f = np.array([0.0])
        R, d = material.at(f)
        return MaterialFit(
            material.name,
            tuple(float(v) for v in f),
            tuple(float(v) for v in np.clip(R, MIN_REFLECTION, MAX_REFLECTION)),
            tuple(float(v) for v in np.clip(d, MIN_DIFFUSE, MAX_DIFFUSE)),
            fit_reflection,
            fit_diffuse,
        )


@dataclass(frozen=True, eq=False)
class ParameterSet:
    """The fitted materials and the layout of the parameter vector.

    materials : the MaterialFit of each fitted material, in the column order of the
    groups' counts (material j: columns 2 j specular, 2 j + 1 diffuse);
    band_hz : (B,) band centres at which the factors are evaluated.
    """

    materials: tuple[MaterialFit, ...]
    band_hz: np.ndarray

    def __post_init__(self) -> None:
        hats = tuple(hat_weights(self.band_hz, m.frequencies_hz) for m in self.materials)
        object.__setattr__(self, "_hats", hats)

    @property
    def names(self) -> list[str]:
        """Parameter names: ``material.reflection`` or ``material.reflection@40kHz``."""
        out = []
        for m in self.materials:
            for key, free in (("reflection", m.fit_reflection), ("diffuse", m.fit_diffuse)):
                if not free:
                    continue
                for f in m.frequencies_hz:
                    out.append(f"{m.name}.{key}" + (f"@{f / 1e3:g}kHz" if m.is_table else ""))
        return out

    def layout(self) -> list[tuple[int, str, int]]:
        """(material index, 'reflection' or 'diffuse', table point) of each parameter."""
        out = []
        for j, m in enumerate(self.materials):
            for key, free in (("reflection", m.fit_reflection), ("diffuse", m.fit_diffuse)):
                if free:
                    out.extend((j, key, i) for i in range(m.n_points))
        return out

    def start(self) -> np.ndarray:
        """The start vector: reflections as they are, diffuse fractions as amplitudes
        ``sqrt(d)`` (d at least :data:`START_MIN_DIFFUSE`)."""
        out = []
        for j, k, i in self.layout():
            v = getattr(self.materials[j], k)[i]
            out.append(v if k == "reflection" else np.sqrt(max(v, START_MIN_DIFFUSE)))
        return np.array(out)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of the parameter vector (diffuse entries as amplitudes)."""
        lo = {"reflection": MIN_REFLECTION, "diffuse": np.sqrt(MIN_DIFFUSE)}
        hi = {"reflection": MAX_REFLECTION, "diffuse": np.sqrt(MAX_DIFFUSE)}
        lay = self.layout()
        return np.array([lo[k] for _, k, _ in lay]), np.array([hi[k] for _, k, _ in lay])

    def values(self, theta: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """(R (J,), d (J,)) of every material at parameters `theta`."""
        out = [[np.array(m.reflection), np.array(m.diffuse)] for m in self.materials]
        for x, (j, k, i) in zip(theta, self.layout()):
            out[j][0 if k == "reflection" else 1][i] = x if k == "reflection" else x**2
        return [(R, d) for R, d in out]

    def public(self, theta: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each parameter's value and one-sigma uncertainty as named (P,), (P,): a
        diffuse amplitude u +- s becomes ``d = u^2`` with the standard deviation of
        the square of a normal variable, ``sqrt(4 u^2 s^2 + 2 s^4)`` (not zero at
        ``u = 0``)."""
        theta, sigma = np.asarray(theta, float), np.asarray(sigma, float)
        amp = np.array([k == "diffuse" for _, k, _ in self.layout()], bool)
        value = np.where(amp, theta**2, theta)
        spread = np.sqrt(4 * theta**2 * sigma**2 + 2 * sigma**4)
        return value, np.where(amp, spread, sigma)

    def gains(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The pressure gains g (B, 2 J) of every interaction column in every band
        (``a = R sqrt(1 - d)``, ``b = R sqrt(d)``) and their derivatives (B, 2 J, P)
        with respect to the P parameters (diffuse ones: amplitudes u, ``d = u^2``
        at the table points, linear in d between them)."""
        B, J = self.band_hz.size, len(self.materials)
        g = np.zeros((B, 2 * J))
        grad = np.zeros((B, 2 * J, theta.size))
        index = {key: p for p, key in enumerate(self.layout())}
        for j, ((R_t, d_t), hat) in enumerate(zip(self.values(theta), self._hats)):
            R, d = hat @ R_t, hat @ d_t  # (B,) at the band centres
            sa, sb = np.sqrt(1 - d), np.sqrt(d)
            g[:, 2 * j], g[:, 2 * j + 1] = R * sa, R * sb
            for i in range(hat.shape[1]):
                p = index.get((j, "reflection", i))
                if p is not None:
                    grad[:, 2 * j, p] = hat[:, i] * sa
                    grad[:, 2 * j + 1, p] = hat[:, i] * sb
                p = index.get((j, "diffuse", i))
                if p is not None:
                    u = np.sqrt(d_t[i])
                    grad[:, 2 * j, p] = -R * hat[:, i] * u / sa
                    # d sqrt(d) / d u_i = h_i u_i / sqrt(d); at d = 0 (every u with
                    # weight here 0) the partial derivative along u_i is sqrt(h_i)
                    with np.errstate(invalid="ignore", divide="ignore"):
                        db = np.where(sb > 0, hat[:, i] * u / sb, np.sqrt(hat[:, i]))
                    grad[:, 2 * j + 1, p] = R * db
        return g, grad
