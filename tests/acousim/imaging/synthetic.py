"""Synthetic images the picture tests draw: blobs where the test puts them."""

from __future__ import annotations

import numpy as np

import processing as P


def blob_image(sources, *, step_deg=2.0, ranges=None, method="das"):
    """A synthetic image: Gaussian blobs at (range_m, azimuth_deg, elevation_deg, dB)."""
    az = np.deg2rad(np.arange(-90, 90.1, step_deg))
    el = np.deg2rad(np.arange(-40, 40.1, step_deg))
    rng = np.arange(0.25, 3.0, 0.01) if ranges is None else ranges
    power = np.full((rng.size, el.size, az.size), 1e-9)
    R, E, A = np.meshgrid(rng, el, az, indexing="ij")
    for r, a, e, db in sources:
        power += 10 ** (db / 10) * np.exp(
            -(((R - r) / 0.02) ** 2)
            - ((A - np.deg2rad(a)) / np.deg2rad(4)) ** 2
            - ((E - np.deg2rad(e)) / np.deg2rad(4)) ** 2
        )
    return P.Image(power, rng, el, az, method, 40e3, bin_range_m=0.01)


def hot(pic):
    """Pixels (H, W) of the top of the inferno map (pale yellow: not white, not grey)."""
    return (pic[..., 0] > 0.9) & (pic[..., 1] > 0.8) & (pic[..., 2] < 0.75)
