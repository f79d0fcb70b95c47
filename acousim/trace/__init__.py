"""Ray tracing of mesh scenes into paths (Embree via embreex)."""

from .tracer import KIND, TracedPaths, Tracer, cone_directions

__all__ = ["KIND", "TracedPaths", "Tracer", "cone_directions"]
