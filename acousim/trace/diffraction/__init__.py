"""Edge diffraction (Biot-Tolstoy-Medwin): one entry, :func:`edge_diffraction` (:mod:`.stage`).

First order (:mod:`.first_order`, :mod:`.btm`), with a specular reflection before or after
the edge (:mod:`.edge_reflected`), edge to edge (:mod:`.edge_to_edge`, :mod:`.pairs`,
:mod:`.pair_geometry`, the compiled :mod:`.pair_kernel` driven by :mod:`.pairs_compiled`),
the bounds that choose which pairs matter (:mod:`.pair_bound`, compiled in
:mod:`.bound_kernel`); what the stage works with (:mod:`.setup`) and hands on (:mod:`.paths`)."""

from acousim.trace.diffraction.stage import (
    DiffractingGeometry,
    DiffractionOptions,
    edge_diffraction,
)

__all__ = ["edge_diffraction", "DiffractingGeometry", "DiffractionOptions"]
