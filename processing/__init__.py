"""processing: one pipeline for simulated and real sonar recordings.

recording -> :func:`matched_filter` -> :func:`stft_snapshot` -> :func:`doa_spectrum`
-> :class:`Image` -> peaks and metrics; broadband energyscapes (:func:`energyscape`,
methods ``*-bb``) and wideband subspace methods (``*-wb``) give the same Image
through :func:`acoustic_images`.  Units are SI throughout (m, s, Hz, rad).
This package imports neither :mod:`acousim` nor :mod:`hardware`.
"""

from .api import KeywordError, check_keywords
from .arrays import (
    PRESETS,
    Array,
    ertis_v3d1,
    from_coordinates,
    from_coordinates_file,
    paper_8x8,
    preset,
    ura,
    urtis_v1,
)
from .broadband import (
    BROADBAND_METHODS,
    Baseband,
    BroadbandSettings,
    Directions,
    Energyscape,
    energyscape,
    fan,
    sphere_partition,
)
from .calibration import (
    ArrayCalibration,
    CalibrationFit,
    apply_calibration,
    attach_calibration,
    find_echo,
    fit_array_calibration,
)
from .chirp import count_chirp, is_chirp, read_chirp, write_chirp
from .doa import NARROWBAND_METHODS, SubspaceOptions, doa_spectrum
from .errors import InputError
from .image import PEAK_THRESHOLD_DB, Image, Peaks, find_peaks, on_grid_edge, to_db
from .matched_filter import matched_filter
from .methods import MethodSpec, parse_method
from .metrics import (
    angular_resolution,
    dynamic_range_db,
    max_attenuation,
    range_profile,
    range_resolution,
    solid_angle_3db,
)
from .peak_table import PEAK_COLUMNS, PeakRow, PeakTable
from .pipeline import (
    METHODS,
    Method,
    ProcessingSettings,
    acoustic_image,
    acoustic_images,
    check_memory,
    check_method,
    estimate_memory_bytes,
    front_end_bytes,
    recording_snapshot,
    requires_ura,
)
from .pointcloud import PointCloud
from .provenance import Provenance, SensorMotion, SensorPose, provenance_metadata
from .recording import (
    GroundTruth,
    Recording,
    RecordingFileError,
    count_recordings,
    load_recording,
    load_recordings,
    save_recording,
    save_recordings,
)
from .smoothing import covariance, smoothed_covariance
from .snapshot import BinGate, Snapshot, Stft, stft_snapshot
from .steering import GRID_AZIMUTH_DEG, GRID_ELEVATION_DEG, GRID_STEP_DEG, Grid, steering_matrix
from .waveforms import (
    CALLS,
    Waveform,
    hyperbolic_sweep,
    linear_chirp,
    named_call,
    paper_chirp,
    rtis_call,
)
from .wideband import WIDEBAND_METHODS

__all__ = [
    "PRESETS",
    "Array",
    "ertis_v3d1",
    "from_coordinates",
    "from_coordinates_file",
    "paper_8x8",
    "preset",
    "ura",
    "urtis_v1",
    "METHODS",
    "Method",
    "check_method",
    "parse_method",
    "MethodSpec",
    "requires_ura",
    "check_memory",
    "estimate_memory_bytes",
    "front_end_bytes",
    "NARROWBAND_METHODS",
    "BROADBAND_METHODS",
    "WIDEBAND_METHODS",
    "BroadbandSettings",
    "Baseband",
    "Directions",
    "Energyscape",
    "energyscape",
    "fan",
    "sphere_partition",
    "doa_spectrum",
    "SubspaceOptions",
    "InputError",
    "KeywordError",
    "Image",
    "Peaks",
    "PeakRow",
    "PeakTable",
    "PEAK_COLUMNS",
    "PEAK_THRESHOLD_DB",
    "find_peaks",
    "on_grid_edge",
    "to_db",
    "matched_filter",
    "angular_resolution",
    "dynamic_range_db",
    "max_attenuation",
    "range_profile",
    "range_resolution",
    "solid_angle_3db",
    "ProcessingSettings",
    "acoustic_image",
    "acoustic_images",
    "recording_snapshot",
    "Recording",
    "Provenance",
    "SensorPose",
    "SensorMotion",
    "provenance_metadata",
    "RecordingFileError",
    "GroundTruth",
    "count_recordings",
    "write_chirp",
    "read_chirp",
    "is_chirp",
    "count_chirp",
    "PointCloud",
    "load_recording",
    "load_recordings",
    "save_recording",
    "save_recordings",
    "covariance",
    "smoothed_covariance",
    "Snapshot",
    "Stft",
    "BinGate",
    "stft_snapshot",
    "Grid",
    "GRID_AZIMUTH_DEG",
    "GRID_ELEVATION_DEG",
    "GRID_STEP_DEG",
    "steering_matrix",
    "Waveform",
    "hyperbolic_sweep",
    "linear_chirp",
    "paper_chirp",
    "rtis_call",
    "CALLS",
    "named_call",
    "ArrayCalibration",
    "CalibrationFit",
    "apply_calibration",
    "attach_calibration",
    "find_echo",
    "fit_array_calibration",
]

# every public constructor and function answers a misspelled keyword as a scene file does
check_keywords(globals(), __all__)
