"""Dataset generation: sharded, reproducible, resumable, local or on a Dask cluster."""

from .generation import generate, make_sample, sample_parameters
from .reader import DatasetReader, TorchAdapter
from .spec import DatasetSpec, SpecError, load_spec

__all__ = [
    "generate",
    "make_sample",
    "sample_parameters",
    "DatasetReader",
    "TorchAdapter",
    "DatasetSpec",
    "SpecError",
    "load_spec",
]
