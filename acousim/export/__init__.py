"""Files other tools read: images and peaks as data (HDF5, CSV), ROS 2 bags (MCAP).

- :func:`write_image_data` : the images (range x elevation x azimuth, dB) in HDF5
  with dimension scales, readable with plain h5py, MATLAB or netCDF-4 tools;
- :func:`write_peaks_csv` : the image peaks, one row each, as CSV;
- :func:`write_rosbag` : a rosbag2 (MCAP) with the raw recordings, the peaks as
  ``sensor_msgs/PointCloud2``, the fan image as ``sensor_msgs/Image`` and the
  sensor pose as TF, the LiDAR scans as ``sensor_msgs/PointCloud2``
  (:mod:`acousim.export.lidar_cloud`; needs the ``rosbags`` package:
  ``pip install 'acousim[ros]'``);
- CHIRP files (Cosys-Lab's dataset format) are :func:`processing.write_chirp`.

The layouts are documented in ``docs/export.md``.
"""

from acousim.export.images import PEAK_COLUMNS, write_image_data, write_peaks_csv

__all__ = ["PEAK_COLUMNS", "write_image_data", "write_peaks_csv", "write_rosbag"]


def write_rosbag(*args, **kwargs):
    """See :func:`acousim.export.rosbag.write_rosbag` (imported on use: rosbags is an
    optional dependency)."""
    from acousim.export.rosbag import write_rosbag as _write

    return _write(*args, **kwargs)
