"""Perception, below the env: the camera model (camera), detection/, tracking/, groups/, datasets/ and the camera
autoencoders (autoencoding/)."""
