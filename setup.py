"""Builds the optional C kernel of the PDM decoder and puts the bundled scenes and
dataset specs into the package; everything else is in pyproject.toml.

Without a C compiler the build goes on (optional=True) and hardware.pdm falls back to
its numpy decoder, far slower (BENCHMARKS.md).

``scenes/`` and ``datasets/`` stay where they are in the source tree; a built wheel
carries copies of them as ``acousim/_data/scenes`` and ``acousim/_data/datasets``
(read through ``acousim.bundled``, which falls back to the source tree's folders).
"""

from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_py import build_py

DATA = ("scenes", "datasets")
SKIP = {".py", ".pyc"}


class BuildPyWithData(build_py):
    """build_py, then the data folders copied into build_lib/acousim/_data/."""

    def run(self) -> None:
        super().run()
        root = Path(__file__).resolve().parent
        for folder in DATA:
            for src in sorted((root / folder).rglob("*")):
                if not src.is_file() or src.suffix in SKIP or "__pycache__" in src.parts:
                    continue
                dst = Path(self.build_lib) / "acousim" / "_data" / src.relative_to(root)
                self.mkpath(str(dst.parent))
                self.copy_file(str(src), str(dst))


setup(
    cmdclass={"build_py": BuildPyWithData},
    ext_modules=[
        Extension(
            "hardware._pdm_kernel",
            ["hardware/_pdm_kernel.c"],
            extra_compile_args=["-O3"],
            optional=True,
        )
    ],
)
