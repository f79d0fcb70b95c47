"""Meshes that move during a measurement, and how paths follow the motion."""
