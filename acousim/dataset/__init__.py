"""Dataset generation: sharded, reproducible, resumable, local or on a Dask cluster."""

from acousim.dataset.generation import generate, make_sample, sample_parameters
from acousim.dataset.reader import DatasetError, DatasetReader, TorchAdapter, TorchSamples
from acousim.dataset.spec import DatasetSpec, SpecError, load_spec

__all__ = [
    "generate",
    "make_sample",
    "sample_parameters",
    "DatasetReader",
    "DatasetError",
    "TorchAdapter",
    "TorchSamples",
    "DatasetSpec",
    "SpecError",
    "load_spec",
]

from processing.base.api import check_keywords  # noqa: E402

check_keywords(globals(), __all__)  # a misspelled keyword: the scene file's answer
