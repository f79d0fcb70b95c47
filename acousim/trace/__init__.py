"""Ray tracing of mesh scenes into paths (Embree via embreex): see :mod:`.tracer`."""

from .paths import KIND, TracedPaths
from .settings import TraceSettings
from .shoot import cone_directions
from .tracer import Tracer, trace_pose

__all__ = ["KIND", "TracedPaths", "TraceSettings", "Tracer", "cone_directions", "trace_pose"]
