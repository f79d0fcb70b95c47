"""Recording measurements from a sensor into Recordings, surviving what goes wrong.

Frames are validated (header, footer, length, index continuity).  A gap in the
indices is reported with the indices lost; a corrupt or short frame is reported and
dropped; a time-out is retried (a measurement is idempotent: asking again is safe);
a disconnect closes the device and reopens it when it returns, then reconfigures
it.  Nothing is hidden: every event is logged and counted in :class:`RecordStats`,
and the statistics go into each recording's metadata.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

import processing as P

from .device import DeviceNotFound, DeviceSettings, RtisDevice
from .pdm import DECIMATION, PDM_RATE_HZ, decode
from .protocol import FrameError

__all__ = ["RecordStats", "Recorder", "RecordingInterrupted", "decode_frame"]

log = logging.getLogger(__name__)


@dataclass
class RecordStats:
    frames: int = 0
    lost_indices: list[int] = field(default_factory=list)
    corrupt: int = 0
    timeouts: int = 0
    reconnects: int = 0
    events: list[str] = field(default_factory=list)

    def note(self, text: str) -> None:
        log.warning(text)
        self.events.append(text)


def decode_frame(
    ticks: np.ndarray,
    array: P.Array,
    call: P.Waveform,
    metadata: dict | None = None,
    fir: np.ndarray | str = "equiripple",
    speed_of_sound_m_s: float = 343.0,
) -> P.Recording:
    """Tick words of one measurement -> a Recording at 450 kHz with the array's channel map.

    Sample 0 is the first tick: the emission starts there (emission_index 0).  `fir` is a
    decimation filter name (:data:`hardware.pdm.FILTERS`) or taps; the metadata records it
    as ``decimation_filter`` (the name, or the number of taps).
    """
    x = decode(ticks, array.channels, fir)
    name = fir if isinstance(fir, str) else f"{np.size(fir)} taps"
    return P.Recording(
        x,
        PDM_RATE_HZ / DECIMATION,
        array,
        call,
        speed_of_sound_m_s,
        0,
        {"simulated": False, "decimation_filter": name, **(metadata or {})},
    )


class Recorder:
    """Acquires measurements from an RtisDevice.

    `open_device` makes (and remakes, after a disconnect) the device.
    """

    def __init__(
        self,
        open_device: Callable[[], RtisDevice],
        settings: DeviceSettings,
        array: P.Array,
        call: P.Waveform,
        *,
        retries: int = 3,
        reconnect_timeout_s: float = 10.0,
        speed_of_sound_m_s: float = 343.0,
        fir: np.ndarray | str = "equiripple",
    ) -> None:
        self.open_device = open_device
        self.settings = settings
        self.array, self.call = array, call
        self.retries = retries
        self.reconnect_timeout_s = reconnect_timeout_s
        self.c = speed_of_sound_m_s
        self.fir = fir
        self.stats = RecordStats()
        self.device = self._connect()
        self.firmware = self.device.firmware_version()
        self._expected: int | None = None

    def _connect(self) -> RtisDevice:
        dev = self.open_device()
        dev.configure(self.settings)
        return dev

    def _reconnect(self) -> None:
        import usb.core

        self.stats.reconnects += 1
        self.stats.note("sensor disconnected: waiting for it to return")
        try:
            self.device.close()
        except usb.core.USBError:
            pass
        deadline = time.monotonic() + self.reconnect_timeout_s
        while True:
            try:
                self.device = self._connect()
                self.stats.note("sensor reconnected and reconfigured")
                return
            except (DeviceNotFound, usb.core.USBError):
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.05)

    def measure(self) -> P.Recording | None:
        """One measurement, or None when its frame was corrupt (reported)."""
        import usb.core

        for attempt in range(self.retries + 1):
            try:
                frame = self.device.measure()
                break
            except usb.core.USBTimeoutError:
                self.stats.timeouts += 1
                self.stats.note(f"time-out waiting for a frame (attempt {attempt + 1})")
            except FrameError as exc:
                self.stats.corrupt += 1
                self.stats.note(f"frame dropped: {exc}")
                self._drain()
                return None
            except usb.core.USBError as exc:
                if exc.errno in (19, 5) or "No such device" in str(exc):
                    self._reconnect()
                else:
                    raise
        else:
            raise TimeoutError(f"no frame after {self.retries + 1} attempts")
        if self._expected is not None and frame.index != self._expected:
            lost = list(range(self._expected, frame.index))
            self.stats.lost_indices += lost
            self.stats.note(
                f"measurement index jumped from {self._expected - 1} to {frame.index}: lost {lost}"
            )
        self._expected = frame.index + 1
        self.stats.frames += 1
        meta = {
            "device": {
                "vendor_id": self.device.vendor_id,
                "product_id": self.device.product_id,
                "firmware": self.firmware,
                "settings": self.settings.to_dict(),
            },
            "index": frame.index,
            "timestamp": time.time(),
        }
        return decode_frame(
            frame.ticks, self.array, self.call, meta, self.fir, speed_of_sound_m_s=self.c
        )

    def _drain(self) -> None:
        """Discard what is left of a bad frame on the wire."""
        import usb.core

        try:
            while self.device.ep_in.read(1 << 16, 50):
                pass
        except usb.core.USBError:
            pass

    def acquire(
        self,
        count: int | None = None,
        duration_s: float | None = None,
        rate_hz: float | None = None,
        on_record: Callable[[P.Recording], None] | None = None,
    ) -> list[P.Recording]:
        """Measurements until `count` are kept or `duration_s` has passed, at most
        `rate_hz` per second.  KeyboardInterrupt stops after the last complete one."""
        if count is None and duration_s is None:
            raise ValueError("give a count or a duration")
        out: list[P.Recording] = []
        start = time.monotonic()
        period = 1.0 / rate_hz if rate_hz else 0.0
        try:
            while (count is None or len(out) < count) and (
                duration_s is None or time.monotonic() - start < duration_s
            ):
                t0 = time.monotonic()
                rec = self.measure()
                if rec is not None:
                    rec.metadata["record_stats"] = {"lost_so_far": len(self.stats.lost_indices)}
                    out.append(rec)
                    if on_record:
                        on_record(rec)
                wait = period - (time.monotonic() - t0)
                if wait > 0:
                    time.sleep(wait)
        except KeyboardInterrupt:
            log.warning("interrupted: keeping %d complete measurement(s)", len(out))
            raise RecordingInterrupted(out) from None
        return out


class RecordingInterrupted(KeyboardInterrupt):
    """Ctrl-C during acquisition; `recordings` holds every complete measurement."""

    def __init__(self, recordings: list[P.Recording]) -> None:
        super().__init__("interrupted")
        self.recordings = recordings
