"""Calibrating a scene to recordings of it: its materials' reflection and diffuse
fraction fitted to what was measured (:func:`calibrate`), the fitted scene written
back as the input file with only those values changed (:func:`write_scene`).

Modules, one job each: :mod:`.parameters` (what is fitted, the gain factor of a
group of paths and its derivatives), :mod:`.groups` (trace once, render each group of
paths once), :mod:`.features` (energy per band, direction and range bin, and why),
:mod:`.fit` (robust least squares with the exact Jacobian), :mod:`.diagnose` (what
the fit cannot determine: the report's warnings), :mod:`.run` (the library
call and its report), :mod:`.scenefile` (the text-preserving scene writer).
"""

from acousim.calibrate.diagnose import FitWarning
from acousim.calibrate.features import Directions, FeatureSpace
from acousim.calibrate.options import CalibrationSettings
from acousim.calibrate.run import Calibration, FittedParameter, Unexplained, calibrate
from acousim.calibrate.scenefile import write_scene

__all__ = [
    "calibrate",
    "write_scene",
    "Calibration",
    "CalibrationSettings",
    "FittedParameter",
    "FitWarning",
    "Unexplained",
    "Directions",
    "FeatureSpace",
]
