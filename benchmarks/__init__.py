"""Benchmarks: run time against error.  ``python -m benchmarks`` rewrites BENCHMARKS.md."""
