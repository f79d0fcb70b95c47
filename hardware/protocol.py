"""The RTIS link protocol: commands, answers and measurement frames.

Commands are ASCII lines ``!X,a,b,c\\n``; each is answered by one little-endian
uint32.  A measurement frame is::

    header 0x51534E12 | measurement index | n_ticks tick words | footer 0x2F418672

(all little-endian uint32)

where bit k of a tick word is the 1-bit PDM sample of microphone channel k.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from processing.base.errors import InputError

__all__ = [
    "HEADER",
    "FOOTER",
    "COMMANDS",
    "encode_command",
    "decode_answer",
    "Frame",
    "FrameError",
    "parse_frame",
    "build_frame",
    "TICKS_MULTIPLE",
    "read_ticks",
]

#: pid.codes' test IDs, the emulator's (:mod:`hardware.emulator`) and the default
#: of :func:`hardware.device.find_ids`: the real sensor's IDs are not published
EMULATOR_VID = 0x1209
EMULATOR_PID = 0x0001
HEADER = 0x51534E12
FOOTER = 0x2F418672
TICKS_MULTIPLE = 32768

#: command letters and what they do
COMMANDS = {
    "A": "measure (argument: 1 active, 0 passive)",
    "B": "set the measurement counter",
    "C": "write DAC sample i = v (12-bit)",
    "D": "DAC sample rate (160 kHz .. 2 MHz)",
    "E": "DAC sample count (64 .. 65535)",
    "F": "microphone clock mode (0: 4.5 MHz, 1: 1.125 MHz)",
    "G": "number of microphone ticks (a multiple of 32768)",
    "H": "behaviour",
    "I": "emissions per measurement",
    "J": "external trigger on/off",
    "K": "high-voltage amplifier on/off",
    "L": "DAC pulse hash",
    "Y": "firmware version",
}


class FrameError(ValueError):
    """A frame that is not what it should be; the message says what and by how much."""


def encode_command(letter: str, *args: int) -> bytes:
    """``!X,a,b,c\\n`` as bytes (unused arguments are 0)."""
    if letter not in COMMANDS:
        raise ValueError(f"unknown command {letter!r}; known: {', '.join(sorted(COMMANDS))}")
    values = [int(a) for a in args] + [0] * (3 - len(args))
    if len(values) != 3:
        raise ValueError(f"command {letter!r} takes at most 3 arguments, got {len(args)}")
    return f"!{letter},{values[0]},{values[1]},{values[2]}\n".encode("ascii")


def decode_answer(data: bytes) -> int:
    if len(data) != 4:
        raise FrameError(f"an answer is 4 bytes, got {len(data)}")
    return int.from_bytes(data, "little")


@dataclass(frozen=True, eq=False)
class Frame:
    """One measurement: its index and its tick words (n_ticks,) uint32."""

    index: int
    ticks: np.ndarray


def frame_size(n_ticks: int) -> int:
    """Bytes in a frame of n_ticks tick words."""
    return 4 * (n_ticks + 3)


def build_frame(index: int, ticks: np.ndarray) -> bytes:
    """A frame's bytes: header, `index`, the tick words (n_ticks,) as little-endian
    uint32 and the footer (what the sensor sends; :func:`parse_frame` reads it)."""
    words = np.concatenate(
        [[HEADER, index & 0xFFFFFFFF], np.asarray(ticks, np.uint32), [FOOTER]]
    ).astype("<u4")
    return words.tobytes()


def parse_frame(data: bytes, n_ticks: int) -> Frame:
    """Validate and unpack a frame; raises FrameError naming what is wrong."""
    expected = frame_size(n_ticks)
    if len(data) != expected:
        raise FrameError(
            f"frame is {len(data)} bytes, expected {expected} "
            f"({n_ticks} ticks): a short or long read"
        )
    words = np.frombuffer(data, "<u4")
    if words[0] != HEADER:
        raise FrameError(f"bad header 0x{int(words[0]):08X}, expected 0x{HEADER:08X}")
    if words[-1] != FOOTER:
        raise FrameError(f"bad footer 0x{int(words[-1]):08X}, expected 0x{FOOTER:08X}")
    return Frame(int(words[1]), words[2:-1].copy())


def read_ticks(path: str | Path) -> np.ndarray:
    """The tick words (N,) uint32 of a raw measurement file: little-endian uint32
    words, one per PDM tick, with no header or footer (as the rtisdev wheel's
    ``simulate.bin``), N a positive multiple of 32768.

    Raises InputError naming the file and what is wrong with it (missing, empty, a
    size in bytes that is not a whole number of words, or of measurements).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError("no such file" if not path.exists() else "not a file", file=path)
    data = path.read_bytes()
    if not data or len(data) % 4:
        raise InputError(
            f"{len(data)} bytes, not a raw RTIS measurement: its size must be a positive "
            "multiple of 4 (one little-endian uint32 word per PDM tick)",
            file=path,
        )
    words = np.frombuffer(data, "<u4")
    if words.size % TICKS_MULTIPLE:
        raise InputError(
            f"{len(data)} bytes = {words.size} tick words, not a raw RTIS measurement: "
            f"the sensor sends a multiple of {TICKS_MULTIPLE} ticks",
            file=path,
        )
    return words.astype(np.uint32)
