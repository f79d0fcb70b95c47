"""CHIRP files: Cosys-Lab's HDF5 format for in-air sonar datasets, written and read."""
