"""hardware: the real RTIS sensors over USB (pyusb), their 1-bit PDM frames, and an
emulated sensor that runs the same driver without hardware.  Depends on processing.

Its modules are attributes after ``import hardware``: ``device``, ``pdm``,
``protocol`` and ``recorder`` (imported with it) and ``emulator`` (imported on first
use, as ``hardware.emulator.emulated_device``)."""

from hardware.device import DeviceAccessDenied, DeviceNotFound, DeviceSettings, RtisDevice
from hardware.pdm import decode, encode
from hardware.protocol import Frame, FrameError, build_frame, parse_frame, read_ticks
from hardware.recorder import (
    Acquisition,
    Recorder,
    RecordingFailed,
    RecordingInterrupted,
    RecordStats,
    check_acquisition,
    decode_frame,
)

__all__ = [
    "DeviceNotFound",
    "DeviceAccessDenied",
    "DeviceSettings",
    "RtisDevice",
    "decode",
    "encode",
    "Frame",
    "FrameError",
    "build_frame",
    "parse_frame",
    "read_ticks",
    "Recorder",
    "RecordingInterrupted",
    "RecordingFailed",
    "Acquisition",
    "check_acquisition",
    "RecordStats",
    "decode_frame",
]

from processing.base.api import check_keywords  # noqa: E402

_LAZY_MODULES = ("emulator",)


def __getattr__(name: str):
    """``hardware.emulator``: the module, imported on first use."""
    if name in _LAZY_MODULES:
        import importlib

        return importlib.import_module(f"hardware.{name}")
    raise AttributeError(f"module 'hardware' has no attribute {name!r}")


# a misspelled keyword of a public constructor or function: the scene file's answer
check_keywords(globals(), __all__)
