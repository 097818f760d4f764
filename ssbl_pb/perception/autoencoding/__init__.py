"""The camera autoencoders (conv, SAEV): training, frames, reports, keypoints, probe, benches."""
