"""Tests of the benchmarks' own machinery (files and pictures; never their timings)."""
