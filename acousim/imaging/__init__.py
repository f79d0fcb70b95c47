"""Imaging recordings and writing the pictures, image files and peak tables of ``acousim image``."""
