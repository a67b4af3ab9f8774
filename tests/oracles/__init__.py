"""Readable numpy implementations of the tracker's stages, kept as independent checks of its kernels."""
