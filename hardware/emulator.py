"""An emulated RTIS sensor behind a pyusb backend, with faults on demand.

``EmulatedSensor`` answers the documented commands and streams measurement frames
made from recordings (simulated, or any Recording at 450 kHz) by sigma-delta (PDM)
modulation at 4.5 MHz.  ``EmulatorBackend`` is a pyusb backend (pyusb accepts
custom backends) under which the sensor enumerates like a CDC-ACM device, so the
real driver (:mod:`hardware.device`) runs unchanged against it:

    backend = EmulatorBackend(EmulatedSensor(source))
    dev = RtisDevice(backend=backend)

Faults (``sensor.inject(...)``): ``"drop"`` skips the next frame's index (a lost
frame), ``"corrupt"`` breaks the next frame's header, ``"stall"`` makes the next
read after the next command time out (what was to be read stays queued: a late
answer; one stall per command), ``"short"``
truncates the next frame, ``"disconnect"`` unplugs the sensor (reads and writes
fail, it does not enumerate) until ``reconnect()``, a power cycle that restarts
its measurement counter at 0.
"""

from __future__ import annotations

import array as _array
import errno
from collections import deque
from collections.abc import Callable
from types import SimpleNamespace

import numpy as np
import usb.backend
import usb.core

import processing as P
from hardware.device import RtisDevice
from hardware.pdm import PDM_RATE_HZ, encode
from hardware.protocol import COMMANDS, EMULATOR_PID, EMULATOR_VID, build_frame
from processing.base.errors import InputError
from processing.sensor.rtis import RTIS_SAMPLE_RATE_HZ

__all__ = [
    "EmulatedSensor",
    "EmulatorBackend",
    "EMULATOR_VID",
    "EMULATOR_PID",
    "recording_source",
    "emulated_device",
    "check_channels",
]

EP_OUT, EP_IN, EP_NOTIFY = 0x01, 0x82, 0x83


def check_channels(channels) -> np.ndarray:
    """The channels (C,) of an array as an int array; InputError when they do not fit
    the 32 bits of a tick word."""
    channels = np.asarray(channels)
    if channels.size > 32 or channels.size and (channels.min() < 0 or channels.max() > 31):
        raise InputError(
            "the RTIS link carries at most 32 microphones (channels 0..31, one bit of a "
            f"32-bit tick word each); this array has {channels.size}",
            key="channels",
            value=channels.tolist() if channels.size <= 8 else f"{channels.size} channels",
        )
    return channels


def recording_source(
    recordings,
    channels: np.ndarray,
    full_scale: float | None = None,
    *,
    repeat: Callable[[int, int], P.Recording] | None = None,
) -> Callable[[int, int], np.ndarray]:
    """A frame source cycling through K recordings: (index, n_ticks) -> tick words.

    Measurement `index` is recording ``k = index % K``; its first time round
    (``index < K``) the recording itself, then ``repeat(k, r)`` for repetition
    ``r = index // K`` (the same measurement with its own noise; None: the recording
    again, the same bits: the modulator is deterministic).

    The signals are scaled by one full-scale value for all recordings (default: twice
    the largest absolute sample of the K recordings, keeping the modulator within
    +-0.5) and PDM-encoded.
    A recording shorter than the frame is continued with silence *before* modulation,
    so the rest of the frame is the modulator's zero-signal stream (alternating bits,
    decoding to 0), as on the real sensor; a longer one is cut to the frame.

    Raises InputError when the channels do not fit the 32 bits of a tick word.
    """

    channels = check_channels(channels)
    recs = list(recordings)
    scale = full_scale or 2 * max(float(np.abs(r.samples).max()) for r in recs) or 1.0
    cache: dict[tuple[int, int], np.ndarray] = {}

    def ticks(r: P.Recording, n_ticks: int) -> np.ndarray:
        up = int(round(PDM_RATE_HZ / r.sample_rate_hz))
        n = -(-n_ticks // up)  # samples that cover the frame
        x = r.samples[..., :n]
        x = np.concatenate([x, np.zeros((*x.shape[:-1], n - x.shape[-1]))], axis=-1)
        return encode(x, channels, r.sample_rate_hz, scale)[:n_ticks]

    def source(index: int, n_ticks: int) -> np.ndarray:
        k, rep = index % len(recs), index // len(recs)
        if rep and repeat is not None:  # a new measurement each time: nothing to keep
            return ticks(repeat(k, rep), n_ticks)
        if (k, n_ticks) not in cache:
            cache[(k, n_ticks)] = ticks(recs[k], n_ticks)
        return cache[(k, n_ticks)]

    source.full_scale = scale  # type: ignore[attr-defined]
    return source


def _speed_of_sound(recordings) -> float:
    """The one speed of sound (m/s) of the recordings; InputError if they differ."""
    speeds = sorted({float(r.speed_of_sound_m_s) for r in recordings})
    if len(speeds) != 1:
        raise InputError(
            "the recordings an emulated sensor streams must share one air",
            key="speed_of_sound_m_s",
            value=speeds,
        )
    return speeds[0]


def emulated_device(
    recordings,
    channels: np.ndarray,
    *,
    serial: str | None = None,
    n_ticks: int = 163840,
    repeat: Callable[[int, int], P.Recording] | None = None,
):
    """The whole emulator stack for a list of recordings at 450 kHz: returns
    (open_device, sensor), where ``open_device()`` opens an RtisDevice on the emulated
    sensor through the real driver (what :class:`hardware.Recorder` takes; its
    recordings then carry the recordings' speed of sound).  `repeat`: the
    measurements after the first round (:func:`recording_source`).  Raises
    InputError for an array the link cannot carry (more than 32 microphones) or
    recordings of different speeds of sound."""

    recordings = list(recordings)
    source = recording_source(recordings, channels, repeat=repeat)
    sensor = EmulatedSensor(source, n_ticks=n_ticks, speed_of_sound_m_s=_speed_of_sound(recordings))
    backend = EmulatorBackend(sensor)

    def open_device() -> RtisDevice:
        return RtisDevice(backend.vid, backend.pid, serial=serial, backend=backend)

    return open_device, sensor


class EmulatedSensor:
    """The device's state machine: commands in, answers and frames out."""

    def __init__(
        self,
        source: Callable[[int, int], np.ndarray],
        *,
        serial: str = "EMU0001",
        firmware: int = 0x0002_0F01,
        n_ticks: int = 163840,
        speed_of_sound_m_s: float | None = None,
    ) -> None:
        """`speed_of_sound_m_s`: the air of what it streams (m/s), which a
        :class:`hardware.Recorder` gives its recordings (None: not known)."""
        self.source = source
        self.speed_of_sound_m_s = speed_of_sound_m_s
        self.serial = serial
        self.firmware = firmware
        self.settings = {
            "G": n_ticks,
            "F": 0,
            "D": int(RTIS_SAMPLE_RATE_HZ),
            "E": 1125,
            "I": 1,
            "H": 0,
            "J": 0,
            "K": 1,
            "B": 0,
        }
        self.dac = np.zeros(65536, np.uint16)
        self.counter = 0
        self.connected = True
        self.bus, self.address = 1, 7
        self._out = bytearray()
        self._faults: deque[str] = deque()
        self._stalled = False
        self.log: list[bytes] = []

    # -- faults ------------------------------------------------------------------
    def inject(self, *faults: str) -> None:
        for f in faults:
            if f not in ("drop", "corrupt", "stall", "short", "disconnect"):
                raise ValueError(f"unknown fault {f!r}")
            if f == "disconnect":
                self.connected = False
                self._out.clear()
            else:
                self._faults.append(f)

    def reconnect(self) -> None:
        """Plug the sensor back in: a power cycle (its counter starts at 0 again) and a
        new USB address."""
        self.connected = True
        self.counter = 0
        self.address += 1

    # -- the wire ----------------------------------------------------------------
    def write(self, data: bytes) -> int:
        self._check()
        self._stalled = False
        self.log.append(bytes(data))
        for line in bytes(data).split(b"\n"):
            if line:
                self._command(line.decode("ascii", "replace"))
        return len(data)

    def read(self, size: int) -> bytes:
        self._check()
        if self._faults and self._faults[0] == "stall" and not self._stalled:
            self._faults.popleft()
            self._stalled = True  # one stall per command: later reads get the late data
            raise usb.core.USBTimeoutError("Operation timed out", -7, errno.ETIMEDOUT)
        if not self._out:
            raise usb.core.USBTimeoutError("Operation timed out", -7, errno.ETIMEDOUT)
        chunk = bytes(self._out[:size])
        del self._out[:size]
        return chunk

    def _check(self) -> None:
        if not self.connected:
            raise usb.core.USBError(
                "No such device (it may have been disconnected)", -4, errno.ENODEV
            )

    def _command(self, line: str) -> None:
        if not (line.startswith("!") and len(line) >= 2 and line[1] in COMMANDS):
            self._answer(0xFFFFFFFF)
            return
        letter = line[1]
        try:
            args = [int(v) for v in line[3:].split(",")] if len(line) > 2 else []
        except ValueError:
            self._answer(0xFFFFFFFF)
            return
        args += [0] * (3 - len(args))
        if letter == "Y":
            self._answer(self.firmware)
        elif letter == "B":
            self.counter = args[0]
            self._answer(self.counter)
        elif letter == "C":
            self.dac[args[0] % self.dac.size] = args[1]
            self._answer(args[1])
        elif letter == "G":
            if args[0] <= 0 or args[0] % 32768:
                self._answer(0xFFFFFFFF)
                return
            self.settings["G"] = args[0]
            self._answer(args[0])
        elif letter == "A":
            self._answer(self.counter)
            self._frame()
        else:
            self.settings[letter] = args[0]
            self._answer(args[0])

    def _answer(self, value: int) -> None:
        self._out += int(value & 0xFFFFFFFF).to_bytes(4, "little")

    def _frame(self) -> None:
        n = self.settings["G"]
        index = self.counter
        self.counter += 1
        if self._faults and self._faults[0] == "drop":
            self._faults.popleft()
            index = self.counter  # the frame with `index` was lost on the way
            self.counter += 1
        data = bytearray(build_frame(index, self.source(index, n)))
        if self._faults and self._faults[0] == "corrupt":
            self._faults.popleft()
            data[0:4] = b"\xde\xad\xbe\xef"
        if self._faults and self._faults[0] == "short":
            self._faults.popleft()
            data = data[: len(data) // 2]
        self._out += data


def _desc(**kw) -> SimpleNamespace:
    kw.setdefault("extra_descriptors", [])
    return SimpleNamespace(**kw)


class EmulatorBackend(usb.backend.IBackend):
    """A pyusb backend under which an EmulatedSensor enumerates as a CDC-ACM device."""

    emulated = True  # recordings through it are labelled "emulated"

    def __init__(
        self,
        sensor: EmulatedSensor,
        vendor_id: int = EMULATOR_VID,
        product_id: int = EMULATOR_PID,
        *,
        deny_access: bool = False,
    ) -> None:
        """`deny_access`: opening fails as it does for a user without a udev rule."""
        self.sensor = sensor
        self.deny_access = deny_access
        self.vid, self.pid = vendor_id, product_id
        self.kernel_driver = {0: True, 1: True}  # cdc_acm binds to both, as on Linux
        self.strings = {1: "CoSys-Lab (emulated)", 2: "RTIS emulator", 3: sensor.serial}

    def enumerate_devices(self):
        if self.sensor.connected:
            yield self.sensor

    def get_device_descriptor(self, dev):
        s = self.sensor
        return _desc(
            bLength=18,
            bDescriptorType=1,
            bcdUSB=0x0200,
            bDeviceClass=0x02,
            bDeviceSubClass=0,
            bDeviceProtocol=0,
            bMaxPacketSize0=64,
            idVendor=self.vid,
            idProduct=self.pid,
            bcdDevice=0x0100,
            iManufacturer=1,
            iProduct=2,
            iSerialNumber=3,
            bNumConfigurations=1,
            address=s.address,
            bus=s.bus,
            port_number=1,
            port_numbers=(1,),
            speed=3,
        )

    def get_configuration_descriptor(self, dev, config):
        return _desc(
            bLength=9,
            bDescriptorType=2,
            wTotalLength=67,
            bNumInterfaces=2,
            bConfigurationValue=1,
            iConfiguration=0,
            bmAttributes=0x80,
            bMaxPower=250,
        )

    def get_interface_descriptor(self, dev, intf, alt, config):
        if alt != 0 or intf not in (0, 1):
            raise IndexError("no such interface or alternate setting")
        if intf == 0:  # CDC communication interface
            return _desc(
                bLength=9,
                bDescriptorType=4,
                bInterfaceNumber=0,
                bAlternateSetting=0,
                bNumEndpoints=1,
                bInterfaceClass=0x02,
                bInterfaceSubClass=0x02,
                bInterfaceProtocol=0x01,
                iInterface=0,
            )
        return _desc(
            bLength=9,
            bDescriptorType=4,
            bInterfaceNumber=1,
            bAlternateSetting=0,
            bNumEndpoints=2,
            bInterfaceClass=0x0A,
            bInterfaceSubClass=0,
            bInterfaceProtocol=0,
            iInterface=0,
        )

    def get_endpoint_descriptor(self, dev, ep, intf, alt, config):
        if intf == 0:
            return _desc(
                bLength=7,
                bDescriptorType=5,
                bEndpointAddress=EP_NOTIFY,
                bmAttributes=0x03,
                wMaxPacketSize=16,
                bInterval=16,
                bRefresh=0,
                bSynchAddress=0,
            )
        address = (EP_OUT, EP_IN)[ep]
        return _desc(
            bLength=7,
            bDescriptorType=5,
            bEndpointAddress=address,
            bmAttributes=0x02,
            wMaxPacketSize=512,
            bInterval=0,
            bRefresh=0,
            bSynchAddress=0,
        )

    def open_device(self, dev):
        self.sensor._check()
        if self.deny_access:
            raise usb.core.USBError("Access denied (insufficient permissions)", -3, errno.EACCES)
        return dev

    def close_device(self, dev_handle):
        pass

    def set_configuration(self, dev_handle, config_value):
        self.sensor._check()

    def get_configuration(self, dev_handle):
        return 1

    def claim_interface(self, dev_handle, intf):
        self.sensor._check()
        if self.kernel_driver.get(intf):
            raise usb.core.USBError("Resource busy", -6, errno.EBUSY)

    def release_interface(self, dev_handle, intf):
        pass

    def is_kernel_driver_active(self, dev_handle, intf):
        return self.kernel_driver.get(intf, False)

    def detach_kernel_driver(self, dev_handle, intf):
        self.kernel_driver[intf] = False

    def attach_kernel_driver(self, dev_handle, intf):
        self.kernel_driver[intf] = True

    def bulk_write(self, dev_handle, ep, intf, data, timeout):
        return self.sensor.write(bytes(data))

    def bulk_read(self, dev_handle, ep, intf, buff, timeout):
        data = self.sensor.read(len(buff))
        buff[: len(data)] = _array.array("B", data)
        return len(data)

    def ctrl_transfer(self, dev_handle, bmRequestType, bRequest, wValue, wIndex, data, timeout):
        if bRequest == 0x06 and (wValue >> 8) == 3:  # GET_DESCRIPTOR, string
            index = wValue & 0xFF
            if index == 0:
                payload = bytes([4, 3, 0x09, 0x04])
            else:
                text = self.strings.get(index, "").encode("utf-16-le")
                payload = bytes([2 + len(text), 3]) + text
            n = min(len(data), len(payload))
            data[:n] = _array.array("B", payload[:n])
            return n
        return 0

    def clear_halt(self, dev_handle, ep):
        pass

    def reset_device(self, dev_handle):
        pass
