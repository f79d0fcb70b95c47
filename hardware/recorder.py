"""Recording measurements from a sensor into Recordings, surviving what goes wrong.

Frames are validated (header, footer, length, index continuity).  A gap in the
indices is reported with the indices lost; a corrupt or short frame is reported and
dropped; a time-out is retried (a measurement is idempotent: asking again is safe);
a disconnect closes the device and reopens it when it returns, then reconfigures
it.  Nothing is hidden: every event is logged and counted in :class:`RecordStats`,
and the statistics go into each recording's metadata.

How gaps are found and kept from happening:

1. The measurement counter is set to 0 when the device is first configured, so a
   frame lost on the very first trigger shows as index 0 missing.
2. After a reconnect (a power-cycled sensor counts from 0 again) the counter is set
   to the next expected index; an index that still goes backwards is reported.
3. After a time-out the input is drained before the next trigger, so a late frame
   is never taken for the next trigger's (the drained measurement is reported lost).
4. When the device fails for good (every retry timed out, or it did not come back
   within the reconnect time-out), :meth:`Recorder.acquire` raises
   :class:`RecordingFailed` carrying every complete measurement taken before.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

import processing as P
from hardware.device import DeviceNotFound, DeviceSettings, RtisDevice
from hardware.pdm import DECIMATION, PDM_RATE_HZ, FilterName, decode
from hardware.protocol import FrameError
from processing.base.errors import InputError
from processing.base.settings import check, setting, settings_of, validate

__all__ = [
    "RecordStats",
    "Recorder",
    "RecordingInterrupted",
    "RecordingFailed",
    "decode_frame",
    "Acquisition",
    "check_acquisition",
]

log = logging.getLogger(__name__)


@dataclass
class RecordStats:
    """What a recording session met: frames kept, indices lost, corrupt frames,
    timeouts, reconnections, counter resets and the events noted (counts; no units)."""

    frames: int = 0
    lost_indices: list[int] = field(default_factory=list)
    corrupt: int = 0
    timeouts: int = 0
    reconnects: int = 0
    #: (expected index, received index) where the counter went backwards
    counter_resets: list[tuple[int, int]] = field(default_factory=list)
    events: list[str] = field(default_factory=list)

    def note(self, text: str) -> None:
        log.warning(text)
        self.events.append(text)


def decode_frame(
    ticks: np.ndarray,
    array: P.Array,
    call: P.Waveform,
    metadata: dict | None = None,
    fir: np.ndarray | FilterName = "equiripple",
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
        {**P.provenance_metadata("real"), "decimation_filter": name, **(metadata or {})},
    )


@dataclass(frozen=True)
class Acquisition:
    """What a recording run asks for (``acousim record``): exactly one of a count or a
    duration (:func:`check_acquisition`), at most `rate_hz` measurements a second."""

    count: int | None = setting(None, "", 1, 10**9, "number of measurements", kind="int")
    duration_s: float | None = setting(None, "s", 1e-3, 1e7, "seconds of recording", kind="float")
    rate_hz: float = setting(10.0, "Hz", 1e-3, 1e4, "measurements per second at most")

    def __post_init__(self) -> None:
        validate(self)


#: the command-line option of each field of :class:`Acquisition`
_OPTIONS = {"count": "--count", "duration_s": "--duration", "rate_hz": "--rate"}


def check_acquisition(count: int | None, duration_s: float | None, rate_hz: float | None) -> None:
    """Refuse a request that cannot record anything: exactly one of a count or a
    duration, each in its declared range (:class:`Acquisition`); a rate, when given
    (None: as fast as the sensor answers), in its range too.  Raises InputError naming
    the command-line option."""
    if (count is None) == (duration_s is None):
        raise InputError("give exactly one of a count or a duration", key="--count/--duration")
    declared = settings_of(Acquisition)
    for name, value in (("count", count), ("duration_s", duration_s), ("rate_hz", rate_hz)):
        if value is not None:
            check(declared[name], value, _OPTIONS[name])


#: the speed of sound (m/s) a real sensor's recordings carry unless told (the
#: recorder does not know the air)
NOMINAL_SPEED_OF_SOUND_M_S = 343.0


class Recorder:
    """Acquires measurements from an RtisDevice.

    `open_device` makes (and remakes, after a disconnect) the device.
    `speed_of_sound_m_s`: what the recordings carry; None (the default): the
    emulated sensor's air (that of the recordings it streams), else the nominal
    343 m/s.  Raises
    DeviceNotFound (also DeviceAccessDenied) when it cannot be opened and
    RecordingFailed when it is found but does not answer while being configured.
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
        speed_of_sound_m_s: float | None = None,
        fir: np.ndarray | FilterName = "equiripple",
    ) -> None:
        self.open_device = open_device
        self.settings = settings
        self.array, self.call = array, call
        self.retries = retries
        self.reconnect_timeout_s = reconnect_timeout_s
        self.fir = fir
        self.stats = RecordStats()
        self._expected = 0
        import usb.core

        try:
            self.device = self._connect()
            self.firmware = self.device.firmware_version()
        except (usb.core.USBError, FrameError) as exc:  # found, but not answering
            reason = f"the sensor did not answer while being configured: {exc}"
            raise RecordingFailed([], reason) from exc
        air = getattr(getattr(self.device.backend, "sensor", None), "speed_of_sound_m_s", None)
        self.c = next(
            c for c in (speed_of_sound_m_s, air, NOMINAL_SPEED_OF_SOUND_M_S) if c is not None
        )

    def _connect(self) -> RtisDevice:
        """Open and configure the device; its counter set to the next expected index."""
        dev = self.open_device()
        dev.configure(self.settings)
        dev.command("B", self._expected)
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
                    raise DeviceNotFound(
                        f"the sensor did not come back within {self.reconnect_timeout_s:g} s"
                    ) from None
                time.sleep(0.05)

    def measure(self) -> P.Recording | None:
        """One measurement, or None when its frame was corrupt (reported)."""
        import usb.core

        timeouts = 0  # in a row; a reconnect does not use up a retry
        while True:
            try:
                frame = self.device.measure()
                break
            except usb.core.USBTimeoutError:
                timeouts += 1
                self.stats.timeouts += 1
                self.stats.note(f"time-out waiting for a frame (attempt {timeouts})")
                self._drain()  # a late answer or frame must not be read as the next one
                if timeouts > self.retries:
                    raise TimeoutError(
                        f"no frame after {timeouts} attempts (all timed out)"
                    ) from None
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
        if frame.index > self._expected:
            lost = list(range(self._expected, frame.index))
            self.stats.lost_indices += lost
            self.stats.note(
                f"measurement index jumped from {self._expected - 1} to {frame.index}: lost {lost}"
            )
        elif frame.index < self._expected:
            self.stats.counter_resets.append((self._expected, frame.index))
            self.stats.note(
                f"measurement counter went back from {self._expected} to {frame.index} "
                "(the sensor was reset): indices in this file are not continuous"
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
            # the emulated sensor streams a simulation through the same driver
            **P.provenance_metadata("emulated" if self.device.emulated else "real"),
        }
        return decode_frame(
            frame.ticks, self.array, self.call, meta, self.fir, speed_of_sound_m_s=self.c
        )

    def _drain(self) -> None:
        """Discard what is left on the wire (a bad frame, a late answer or frame)."""
        import usb.core

        drained = 0
        try:
            while chunk := self.device.ep_in.read(1 << 16, 50):
                drained += len(chunk)
        except usb.core.USBError:
            pass
        if drained:
            self.stats.note(f"discarded {drained} bytes left on the wire")

    def acquire(
        self,
        count: int | None = None,
        duration_s: float | None = None,
        rate_hz: float | None = None,
        on_record: Callable[[P.Recording], None] | None = None,
        *,
        stop: Callable[[], bool] | None = None,
    ) -> list[P.Recording]:
        """Measurements until `count` are kept or `duration_s` has passed, at most
        `rate_hz` per second.

        KeyboardInterrupt, or `stop()` turning true (checked before every measurement
        and while waiting for the next, e.g. :func:`processing.base.interrupt.requested`),
        stops after the last complete one (:class:`RecordingInterrupted`);
        a device that fails for good raises :class:`RecordingFailed`; both carry every
        complete measurement.  Bad arguments raise InputError (:func:`check_acquisition`).
        """
        import usb.core

        check_acquisition(count, duration_s, rate_hz)
        out: list[P.Recording] = []
        start = time.monotonic()
        period = 1.0 / rate_hz if rate_hz else 0.0
        try:
            while (count is None or len(out) < count) and (
                duration_s is None or time.monotonic() - start < duration_s
            ):
                t0 = time.monotonic()
                if stop is not None and stop():
                    raise KeyboardInterrupt
                rec = self.measure()
                if rec is not None:
                    rec.metadata["record_stats"] = {"lost_so_far": len(self.stats.lost_indices)}
                    out.append(rec)
                    if on_record:
                        on_record(rec)
                _wait_until(t0 + period, stop)
        except KeyboardInterrupt:
            log.info("interrupted: keeping %d complete measurement(s)", len(out))
            raise RecordingInterrupted(out) from None
        except (TimeoutError, DeviceNotFound, usb.core.USBError) as exc:
            self.stats.note(f"the sensor failed: {exc}")
            raise RecordingFailed(out, str(exc)) from exc
        return out


def _wait_until(t_end: float, stop: Callable[[], bool] | None, step_s: float = 0.05) -> None:
    """Sleep until time.monotonic() reaches `t_end`, in steps, returning early (and
    raising KeyboardInterrupt) when `stop()` turns true."""
    while (left := t_end - time.monotonic()) > 0:
        if stop is not None and stop():
            raise KeyboardInterrupt
        time.sleep(min(left, step_s))


class RecordingInterrupted(KeyboardInterrupt):
    """Ctrl-C during acquisition; `recordings` holds every complete measurement."""

    def __init__(self, recordings: list[P.Recording]) -> None:
        super().__init__("interrupted")
        self.recordings = recordings


class RecordingFailed(RuntimeError):
    """The device failed for good; `recordings` holds every complete measurement."""

    def __init__(self, recordings: list[P.Recording], reason: str) -> None:
        super().__init__(f"the sensor failed after {len(recordings)} measurement(s): {reason}")
        self.recordings = recordings
        self.reason = reason
