"""Edge diffraction (BTM): first order, with a reflection, edge to edge; the bounds and the compiled kernels."""
