"""People over time on the ground plane: the Kalman tracker, the video pipeline, threshold tuning, file runs."""
