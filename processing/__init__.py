"""processing: one pipeline for simulated and real sonar recordings.

recording -> :func:`matched_filter` -> :func:`stft_snapshot` -> :func:`doa_spectrum`
-> :class:`Image` -> peaks and metrics; broadband energyscapes (:func:`energyscape`,
methods ``*-bb``) and wideband subspace methods (``*-wb``) give the same Image
through :func:`acoustic_images`.  Units are SI throughout (m, s, Hz, rad).
This package imports neither :mod:`acousim` nor :mod:`hardware`.
"""

from processing.base.api import KeywordError, check_keywords
from processing.base.errors import InputError, UnitsWarning
from processing.formats.chirp import count_chirp, is_chirp, read_chirp, write_chirp
from processing.formats.native import (
    GroundTruth,
    Recording,
    RecordingFileError,
    count_recordings,
    load_recording,
    load_recordings,
    save_recording,
    save_recordings,
)
from processing.imaging.broadband.energyscape import (
    BROADBAND_METHODS,
    Baseband,
    BroadbandSettings,
    Directions,
    Energyscape,
    energyscape,
    fan,
    sphere_partition,
)
from processing.imaging.doa import NARROWBAND_METHODS, SubspaceOptions, doa_spectra, doa_spectrum
from processing.imaging.image import (
    PEAK_THRESHOLD_DB,
    Image,
    Peaks,
    find_peaks,
    on_grid_edge,
    to_db,
)
from processing.imaging.matched_filter import matched_filter
from processing.imaging.methods import MethodSpec, parse_method
from processing.imaging.metrics import (
    SolidAngle3dB,
    angular_resolution,
    angular_resolution_detail,
    dynamic_range_db,
    max_attenuation,
    range_profile,
    range_resolution,
    solid_angle_3db,
    solid_angle_detail,
)
from processing.imaging.peak_table import PEAK_COLUMNS, PeakRow, PeakTable
from processing.imaging.pipeline import (
    METHODS,
    Method,
    ProcessingSettings,
    acoustic_image,
    acoustic_images,
    check_memory,
    check_method,
    estimate_memory_bytes,
    find_echo,
    front_end_bytes,
    recording_snapshot,
    requires_ura,
)
from processing.imaging.smoothing import covariance, smoothed_covariance
from processing.imaging.snapshot import PAPER_GATE, BinGate, Snapshot, Stft, stft_snapshot
from processing.imaging.steering import (
    GRID_AZIMUTH_DEG,
    GRID_ELEVATION_DEG,
    GRID_STEP_DEG,
    GratingLobeWarning,
    Grid,
    steering_matrix,
)
from processing.imaging.wideband import WIDEBAND_METHODS
from processing.sensor.arrays import (
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
from processing.sensor.calibration import (
    ArrayCalibration,
    CalibrationFit,
    apply_calibration,
    attach_calibration,
    fit_array_calibration,
)
from processing.sensor.calls import (
    CALLS,
    Waveform,
    hyperbolic_sweep,
    linear_chirp,
    named_call,
    paper_chirp,
    rtis_call,
)
from processing.sensor.pointcloud import PointCloud
from processing.sensor.provenance import Provenance, SensorMotion, SensorPose, provenance_metadata

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
    "doa_spectra",
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
    "SolidAngle3dB",
    "angular_resolution",
    "angular_resolution_detail",
    "dynamic_range_db",
    "max_attenuation",
    "range_profile",
    "range_resolution",
    "solid_angle_3db",
    "solid_angle_detail",
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
    "PAPER_GATE",
    "stft_snapshot",
    "Grid",
    "GRID_AZIMUTH_DEG",
    "GRID_ELEVATION_DEG",
    "GRID_STEP_DEG",
    "GratingLobeWarning",
    "UnitsWarning",
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

# the modules' names before the re-layout by concept keep importing, with a warning
# (processing.base.moved; CHANGELOG)
from processing.base.moved import alias_modules  # noqa: E402

alias_modules(
    {
        "processing._bbkernel": "processing.imaging.broadband.kernel",
        "processing._doakernel": "processing.imaging.doa_kernel",
        "processing.arrays": "processing.sensor.arrays",
        "processing.atomic": "processing.base.atomic",
        "processing.broadband": "processing.imaging.broadband.energyscape",
        "processing.broadband_engines": "processing.imaging.broadband.engines",
        "processing.calibration": "processing.sensor.calibration",
        "processing.chirp": "processing.formats.chirp",
        "processing.chirp_frames": "processing.base.frames",
        "processing.chirp_names": "processing.formats.chirp.names",
        "processing.chirp_read": "processing.formats.chirp.read",
        "processing.doa": "processing.imaging.doa",
        "processing.errors": "processing.base.errors",
        "processing.image": "processing.imaging.image",
        "processing.interrupt": "processing.base.interrupt",
        "processing.kernels": "processing.base.kernels",
        "processing.matched_filter": "processing.imaging.matched_filter",
        "processing.metadata": "processing.sensor.metadata",
        "processing.methods": "processing.imaging.methods",
        "processing.metrics": "processing.imaging.metrics",
        "processing.pipeline": "processing.imaging.pipeline",
        "processing.pointcloud": "processing.sensor.pointcloud",
        "processing.provenance": "processing.sensor.provenance",
        "processing.recording": "processing.formats.native",
        "processing.recording_schema": "processing.formats.native_schema",
        "processing.recording_types": "processing.sensor.recording",
        "processing.rtis": "processing.sensor.rtis",
        "processing.rtisdev": "processing.sensor.rtisdev",
        "processing.settings": "processing.base.settings",
        "processing.smoothing": "processing.imaging.smoothing",
        "processing.snapshot": "processing.imaging.snapshot",
        "processing.steering": "processing.imaging.steering",
        "processing.waveforms": "processing.sensor.calls",
        "processing.wideband": "processing.imaging.wideband",
    }
)

# every public constructor and function answers a misspelled keyword as a scene file does
check_keywords(globals(), __all__)
