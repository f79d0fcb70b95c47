"""File formats of recordings, one module (or folder) per format."""
