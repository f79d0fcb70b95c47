"""Imaging recordings and writing what ``acousim image`` writes: images, peaks matched to the
traced reflectors (:mod:`.matching`), the pictures (:mod:`.run`), the output folder's
bookkeeping (:mod:`.outputs`)."""

from acousim.imaging.run import (
    ImagingOptions,
    image_recordings,
    peak_positions,
    peaks_in_world,
    prepare_pictures,
    write_pictures,
)

__all__ = [
    "ImagingOptions",
    "image_recordings",
    "peak_positions",
    "peaks_in_world",
    "prepare_pictures",
    "write_pictures",
]
