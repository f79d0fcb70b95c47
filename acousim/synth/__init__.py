"""The signal model: echoes of point reflectors and paths -> microphone signals."""

from .echoes import SPREADING, Echoes, PointReflectors, direct_path_echoes, point_echoes
from .model import simulate, simulate_points
from .noise import add_noise, noise_sigma, signal_power
from .render import DEFAULT_METHOD, METHODS, render

__all__ = [
    "SPREADING",
    "Echoes",
    "PointReflectors",
    "direct_path_echoes",
    "point_echoes",
    "simulate",
    "simulate_points",
    "add_noise",
    "noise_sigma",
    "signal_power",
    "DEFAULT_METHOD",
    "METHODS",
    "render",
]
