"""The RTIS sensor over USB (pyusb): find it, claim its CDC data interface, talk.

The sensor enumerates as a USB CDC-ACM device; its vendor and product IDs are not
published, so they are parameters (``RTIS_VID``/``RTIS_PID`` environment variables
or the constructor).  The driver detaches a kernel driver (cdc_acm) where one is
bound, claims the data interface (class 0x0A) and uses its two bulk endpoints.
"""

from __future__ import annotations

import errno
import logging
import os
from dataclasses import dataclass

import numpy as np

from hardware.protocol import (
    EMULATOR_PID,
    EMULATOR_VID,
    Frame,
    decode_answer,
    encode_command,
    frame_size,
    parse_frame,
)
from processing.base.errors import InputError
from processing.sensor.rtis import RTIS_SAMPLE_RATE_HZ

__all__ = [
    "DeviceSettings",
    "RtisDevice",
    "DeviceNotFound",
    "DeviceAccessDenied",
    "find_ids",
    "parse_usb_id",
]

log = logging.getLogger(__name__)


class DeviceNotFound(RuntimeError):
    """No sensor matches the requested IDs, serial number or bus/address."""


class DeviceAccessDenied(DeviceNotFound):
    """The sensor is there but this user may not open it (no udev rule, see
    docs/setup.md)."""


def _hex_id(text: str, key: str) -> int:
    try:
        value = int(text, 16)
    except ValueError:
        value = -1
    if not 0 <= value <= 0xFFFF:
        raise InputError("expected a USB ID: 1 to 4 hex digits", key=key, value=text)
    return value


def parse_usb_id(text: str, key: str = "--device") -> tuple[int, int]:
    """``"VID:PID"`` in hex -> (vendor, product); InputError naming `key` otherwise."""
    vid, sep, pid = text.partition(":")
    if not sep:
        raise InputError("expected VID:PID in hex, e.g. 1209:0001", key=key, value=text)
    return _hex_id(vid, key), _hex_id(pid, key)


def find_ids() -> tuple[int, int]:
    """(vendor, product) IDs from RTIS_VID/RTIS_PID (hex), default: the emulator's.
    A malformed variable raises InputError naming it."""
    return (
        _hex_id(os.environ.get("RTIS_VID", f"{EMULATOR_VID:x}"), "RTIS_VID"),
        _hex_id(os.environ.get("RTIS_PID", f"{EMULATOR_PID:x}"), "RTIS_PID"),
    )


@dataclass(frozen=True)
class DeviceSettings:
    """What a measurement is: ticks (a multiple of 32768), microphone clock mode, the
    call (DAC samples at dac_rate_hz), emissions, behaviour, trigger, amplifier."""

    n_ticks: int = 163840
    clock_mode: int = 0  # 0: 4.5 MHz, 1: 1.125 MHz
    dac_rate_hz: int = int(RTIS_SAMPLE_RATE_HZ)
    call: np.ndarray | None = None  # samples in [-1, 1]
    emissions: int = 1
    behaviour: int = 0
    external_trigger: bool = False
    amplifier: bool = True

    def to_dict(self) -> dict:
        return {
            "n_ticks": self.n_ticks,
            "clock_mode": self.clock_mode,
            "dac_rate_hz": self.dac_rate_hz,
            "emissions": self.emissions,
            "behaviour": self.behaviour,
            "external_trigger": self.external_trigger,
            "amplifier": self.amplifier,
            "call_samples": 0 if self.call is None else int(len(self.call)),
        }


class RtisDevice:
    """One sensor.  `backend` is a pyusb backend (default: libusb; the emulator's
    :class:`hardware.emulator.EmulatorBackend` in tests)."""

    def __init__(
        self,
        vendor_id: int | None = None,
        product_id: int | None = None,
        *,
        serial: str | None = None,
        bus: int | None = None,
        address: int | None = None,
        backend=None,
        timeout_ms: int = 2000,
    ) -> None:
        if vendor_id is None or product_id is None:
            vid, pid = find_ids()
            vendor_id = vid if vendor_id is None else vendor_id
            product_id = pid if product_id is None else product_id
        self.vendor_id, self.product_id = vendor_id, product_id
        self.serial, self.bus, self.address = serial, bus, address
        self.backend = backend
        #: True when the backend is the emulated sensor (its recordings are emulated)
        self.emulated = bool(getattr(backend, "emulated", False))
        self.timeout_ms = timeout_ms
        self.dev = None
        self.settings = DeviceSettings()
        self.open()

    def open(self) -> None:
        """Find the sensor and claim its data interface."""
        import usb.core
        import usb.util

        dev = self._find()
        try:
            self._claim(dev)
        except usb.core.USBError as exc:
            if exc.errno != errno.EACCES and "Access denied" not in str(exc):
                raise
            raise DeviceAccessDenied(
                f"the RTIS sensor {self.vendor_id:04x}:{self.product_id:04x} on bus "
                f"{dev.bus} address {dev.address} cannot be opened by this user ({exc}): "
                "install the udev rule of docs/setup.md, then replug the sensor"
            ) from None
        cfg = dev.get_active_configuration()
        data = usb.util.find_descriptor(cfg, bInterfaceClass=0x0A)
        self.ep_out = usb.util.find_descriptor(
            data,
            custom_match=lambda e: (
                usb.util.endpoint_direction(e.bEndpointAddress) == usb.util.ENDPOINT_OUT
            ),
        )
        self.ep_in = usb.util.find_descriptor(
            data,
            custom_match=lambda e: (
                usb.util.endpoint_direction(e.bEndpointAddress) == usb.util.ENDPOINT_IN
            ),
        )
        self.dev = dev
        self.bus, self.address = dev.bus, dev.address
        log.info(
            "sensor %04x:%04x on bus %s address %s",
            self.vendor_id,
            self.product_id,
            dev.bus,
            dev.address,
        )

    def _find(self):
        """The first USB device matching the sensor's ID (and bus, address, serial
        when given); DeviceNotFound when there is none or no USB backend."""
        import usb.core
        import usb.util

        def match(d) -> bool:
            if self.bus is not None and d.bus != self.bus:
                return False
            if self.address is not None and d.address != self.address:
                return False
            if self.serial is not None:
                try:
                    return usb.util.get_string(d, d.iSerialNumber) == self.serial
                except (usb.core.USBError, ValueError):
                    return False
            return True

        try:
            found = list(
                usb.core.find(
                    find_all=True,
                    idVendor=self.vendor_id,
                    idProduct=self.product_id,
                    backend=self.backend,
                    custom_match=match,
                )
            )
        except usb.core.NoBackendError:
            raise DeviceNotFound(
                "pyusb found no USB backend: install libusb-1.0 "
                "(Debian: apt-get install libusb-1.0-0)"
            ) from None
        if not found:
            raise DeviceNotFound(
                f"no RTIS sensor with USB ID {self.vendor_id:04x}:{self.product_id:04x}"
                + (f", serial {self.serial!r}" if self.serial else "")
                + (f", bus {self.bus}" if self.bus is not None else "")
                + (f", address {self.address}" if self.address is not None else "")
            )
        return found[0]

    @staticmethod
    def _claim(dev) -> None:
        """Configure the device, detach kernel drivers, claim the CDC data interface."""
        import usb.util

        dev.set_configuration()
        cfg = dev.get_active_configuration()
        data = usb.util.find_descriptor(cfg, bInterfaceClass=0x0A)
        if data is None:
            raise DeviceNotFound("the device has no CDC data interface")
        for intf in range(cfg.bNumInterfaces):
            if dev.is_kernel_driver_active(intf):
                log.debug("detaching the kernel driver from interface %d", intf)
                dev.detach_kernel_driver(intf)
        usb.util.claim_interface(dev, data.bInterfaceNumber)

    def close(self) -> None:
        if self.dev is not None:
            import usb.util

            usb.util.dispose_resources(self.dev)
            self.dev = None

    # -- commands ----------------------------------------------------------------
    def command(self, letter: str, *args: int) -> int:
        """Send ``!X,a,b,c`` and return the device's 4-byte answer."""
        self.ep_out.write(encode_command(letter, *args), self.timeout_ms)
        return decode_answer(self._read_exact(4))

    def firmware_version(self) -> int:
        return self.command("Y")

    def configure(self, settings: DeviceSettings) -> None:
        if settings.n_ticks <= 0 or settings.n_ticks % 32768:
            raise ValueError(
                f"n_ticks must be a positive multiple of 32768, got {settings.n_ticks}"
            )
        self.command("G", settings.n_ticks)
        self.command("F", settings.clock_mode)
        if settings.call is not None:
            call = np.clip(np.asarray(settings.call, float), -1, 1)
            self.command("D", settings.dac_rate_hz)
            self.command("E", len(call))
            for i, v in enumerate(np.floor(2047 * call).astype(int) + 2048):
                self.command("C", i, int(v))
        self.command("I", settings.emissions)
        self.command("H", settings.behaviour)
        self.command("J", int(settings.external_trigger))
        self.command("K", int(settings.amplifier))
        self.settings = settings

    def measure(self) -> Frame:
        """Trigger one active measurement and read its frame (validated)."""
        self.command("A", 1)
        n = self.settings.n_ticks
        return parse_frame(self._read_exact(frame_size(n)), n)

    def _read_exact(self, size: int) -> bytes:
        """Read `size` bytes; a time-out after part of them returns the part (the
        caller's validation reports the short read), before any re-raises."""
        import usb.core

        out = bytearray()
        while len(out) < size:
            try:
                chunk = self.ep_in.read(size - len(out), self.timeout_ms)
            except usb.core.USBTimeoutError:
                if out:
                    break
                raise
            if len(chunk) == 0:
                break
            out += bytes(chunk)
        return bytes(out)
