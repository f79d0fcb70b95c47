"""hardware: the real RTIS sensors over USB (pyusb), their 1-bit PDM frames, and an
emulated sensor that runs the same driver without hardware.  Depends on processing."""

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

# a misspelled keyword of a public constructor or function: the scene file's answer
check_keywords(globals(), __all__)
