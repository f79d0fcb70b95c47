"""The names a CHIRP file's groups and our own schema go by, and its error (shared by
:mod:`processing.formats.chirp.write`, the writer, and :mod:`processing.formats.chirp.read`, the
reader)."""

from __future__ import annotations

from processing.sensor.recording import RecordingFileError

ACOUSTIC, TRANSMITTER = "acoustic_sensor_00", "acoustic_transmitter_00"
ODOMETRY, LIDAR = "odometry_00", "lidar_00"
OURS, OUR_SCHEMA, OUR_VERSION = "acousim", "acousim.chirp", 1


class ChirpFileError(RecordingFileError):
    """A CHIRP file that cannot be read or written as asked; names file and field."""
