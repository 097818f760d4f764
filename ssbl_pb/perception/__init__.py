"""Perception: the camera model (camera), people tracking (tracking/), the camera autoencoders (autoencoding/)."""
