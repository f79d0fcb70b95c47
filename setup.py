"""Builds the optional C kernel of the PDM decoder; everything else is in pyproject.toml.

Without a C compiler the build goes on (optional=True) and hardware.pdm falls back to
its numpy decoder, far slower (BENCHMARKS.md).
"""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "hardware._pdm_kernel",
            ["hardware/_pdm_kernel.c"],
            extra_compile_args=["-O3"],
            optional=True,
        )
    ]
)
