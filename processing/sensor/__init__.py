"""What a sensor is and records: arrays, calls, array calibration, the Recording container and
its metadata."""
