"""The names a CHIRP file's groups and our own schema go by, and its error (shared by
:mod:`processing.formats.chirp.write`, the writer, and :mod:`processing.formats.chirp.read`, the
reader)."""

from __future__ import annotations

from processing.sensor.recording import RecordingFileError

ACOUSTIC, TRANSMITTER = "acoustic_sensor_00", "acoustic_transmitter_00"
ODOMETRY, LIDAR = "odometry_00", "lidar_00"
OURS, OUR_SCHEMA, OUR_VERSION = "acousim", "acousim.chirp", 1


def lidar_name(n: int) -> str:
    """LiDAR n's sensor group (``lidar_00``: the first, :data:`LIDAR`)."""
    return f"lidar_{n:02d}"


def our_lidar(n: int) -> str:
    """Our own group beside LiDAR n's (the rings and point times): ``acousim/lidar``
    for the first, ``acousim/lidar_01``, ... for a rig's others."""
    return f"{OURS}/lidar" if n == 0 else f"{OURS}/{lidar_name(n)}"


class ChirpFileError(RecordingFileError):
    """A CHIRP file that cannot be read or written as asked; names file and field."""
