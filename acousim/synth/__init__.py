"""The signal model: echoes of point reflectors and paths -> microphone signals."""

from acousim.core.air import absorption_db_per_m, speed_of_sound

from .echoes import SPREADING, Echoes, PointReflectors, direct_path_echoes, point_echoes
from .model import simulate, simulate_points
from .noise import add_noise, noise_sigma, signal_power
from .options import Capture, Noise, RenderOptions
from .render import (
    DEFAULT_INTERPOLATOR,
    INTERPOLATORS,
    FractionalDelay,
    check_interpolator,
    render,
)
from .response import PathResponse, piston_directivity

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
