"""The signal model: echoes of point reflectors and paths -> microphone signals."""

from acousim.core.air import absorption_db_per_m, speed_of_sound
from acousim.synth.noise import add_noise, noise_sigma, signal_power
from acousim.synth.options import Capture, Noise, RenderOptions
from acousim.synth.point_reflectors import (
    SPREADING,
    Echoes,
    PointReflectors,
    direct_path_echoes,
    point_echoes,
)
from acousim.synth.render import (
    DEFAULT_INTERPOLATOR,
    INTERPOLATORS,
    FractionalDelay,
    check_interpolator,
    render,
)
from acousim.synth.response import PathResponse, piston_directivity
from acousim.synth.signal_model import simulate, simulate_points

__all__ = [
    "SPREADING",
    "Echoes",
    "PointReflectors",
    "direct_path_echoes",
    "point_echoes",
    "simulate",
    "simulate_points",
    "Capture",
    "Noise",
    "RenderOptions",
    "add_noise",
    "noise_sigma",
    "signal_power",
    "absorption_db_per_m",
    "speed_of_sound",
    "PathResponse",
    "piston_directivity",
    "DEFAULT_INTERPOLATOR",
    "INTERPOLATORS",
    "FractionalDelay",
    "check_interpolator",
    "render",
]
