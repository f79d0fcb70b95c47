"""Simulated versus real recordings of the same sensor."""
