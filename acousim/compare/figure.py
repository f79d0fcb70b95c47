"""The comparison's picture (:func:`comparison_figure`): per method the real and the
simulated fan on one scale, and the two range profiles with their noise floors."""

from __future__ import annotations

import numpy as np

from acousim.compare.account import floor_start, noise_floor
from acousim.compare.report import Comparison, ComparisonArrays

__all__ = ["COMPARISON_RANGE_DB", "comparison_figure"]

#: the dynamic range of the comparison's fans (dB)
COMPARISON_RANGE_DB = 30.0


def comparison_figure(report: Comparison, arrays: ComparisonArrays):
    """Per method, the real and the simulated fan on one scale (dB re the strongest
    cell of the two, each with its colour bar; the matched echoes numbered) and the
    two range profiles in dB re the real profile's strongest bin, with each profile's
    noise floor (:func:`acousim.compare.account.noise_floor`, the number the command
    prints) drawn and named.  Returns the matplotlib Figure."""
    import matplotlib.pyplot as plt

    from acousim.viz.fan import colorbar_label, common_extent, draw_fan

    methods = list(arrays.images_real)
    fig, axes = plt.subplots(
        len(methods), 3, figsize=(16, 4.6 * len(methods)), squeeze=False, layout="constrained"
    )
    for row, m in zip(axes, methods):
        pair = (arrays.images_real[m], arrays.images_sim[m])
        top = 1.05 * max([float(im.range_m.max()) for im in pair if im.range_m.size] or [1.0])
        extent = common_extent(pair, top, COMPARISON_RANGE_DB)
        ref = max([float(im.power.max()) for im in pair if im.power.size] or [1.0])
        for ax, img, name in ((row[0], pair[0], "real"), (row[1], pair[1], "simulated")):
            im = draw_fan(ax, img, top, COMPARISON_RANGE_DB, extent=extent, reference=ref)
            fig.colorbar(im, ax=ax, shrink=0.85, label=colorbar_label(COMPARISON_RANGE_DB, True))
            ax.set_title(f"{name}, {m}")
        for k, echo in enumerate(report.images[m].matched):
            for ax, p in ((row[0], echo.real), (row[1], echo.sim)):
                a = np.deg2rad(p.azimuth_deg)
                xy = (p.range_m * np.sin(a), p.range_m * np.cos(a))
                ax.plot(*xy, "o", mfc="none", mec="cyan", ms=10)
                ax.annotate(str(k), xy, color="cyan", fontsize=8)
        _profiles(row[2], report, arrays)
    fig.suptitle(
        "real and simulated (aligned, gain fitted): fans on one scale, cyan circles: "
        "matched echoes",
        fontsize=10,
    )
    return fig


def _profiles(ax, report: Comparison, arrays: ComparisonArrays) -> None:
    """The two range profiles in dB re the real one's strongest bin, and their floors."""
    centres = (arrays.edges_m[1:] + arrays.edges_m[:-1]) / 2
    ref = float(arrays.profile_real.max()) if arrays.profile_real.size else 0.0
    ref = ref if ref > 0 else 1.0

    def db(x):
        return 10 * np.log10(np.maximum(np.asarray(x, float) / ref, 1e-30))

    for prof, name, colour in (
        (arrays.profile_real, "real", "C0"),
        (arrays.profile_sim, "simulated (aligned)", "C1"),
    ):
        floor = float(db(noise_floor(prof)))  # the account's, as the command prints it
        ax.plot(centres, db(prof), color=colour, lw=1, label=name)
        ax.axhline(floor, color=colour, ls="--", lw=1, label=f"{name} noise floor: {floor:.1f} dB")
    ax.set_xlabel("range (m)")
    ax.set_ylabel("mean envelope power (dB re real strongest bin)")
    ax.legend(fontsize=8)
    al = report.alignment
    ax.set_title(
        f"range profiles ({report.range_bin_m * 100:g} cm bins); gain {al.gain:.3g}, "
        f"shift {al.emission_shift_samples:.2f} samples\nnoise floor: each profile's median "
        f"over {arrays.edges_m[floor_start(len(centres))]:.2f}-{arrays.edges_m[-1]:.2f} m",
        fontsize=9,
    )
