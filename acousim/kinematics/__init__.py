"""The kinematics stage: when the sound leaves and arrives, for whatever moves.

Between the trace (paths at the pose of the start of the emission,
:mod:`acousim.trace`, with how they follow the motion:
:class:`acousim.trace.motion.following.MovingPaths`) and the renderer (:mod:`acousim.synth`):
where the sensor's emitter and microphones are during a measurement
(:class:`SensorKinematics`), the reception times of the call's samples per path and
microphone, solved from the retarded-time equation, and the Doppler factors
(:func:`arrivals`, a typed :class:`Arrivals`); the exact per-sample reference
(:func:`acousim.kinematics.reference.render_doppler_reference`).
"""

from acousim.kinematics.retarded import Arrivals, arrival_times, arrivals
from acousim.kinematics.sensor import TABLE_STEP_S, SensorKinematics

__all__ = ["Arrivals", "arrival_times", "arrivals", "SensorKinematics", "TABLE_STEP_S"]
