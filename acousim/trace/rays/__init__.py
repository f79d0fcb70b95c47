"""Ray work: shooting, the ray budget, exact specular paths, glints, scattering and its
clustering."""
