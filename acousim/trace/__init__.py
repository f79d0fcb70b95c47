"""Ray tracing of mesh scenes into paths (Embree via embreex): see :mod:`.tracer`."""

from acousim.trace.options import TraceSettings
from acousim.trace.paths import KIND, TracedPaths
from acousim.trace.rays.shoot import cone_directions
from acousim.trace.tracer import Tracer, trace_pose

__all__ = ["KIND", "TracedPaths", "TraceSettings", "Tracer", "cone_directions", "trace_pose"]
