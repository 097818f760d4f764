"""People tracking: detectors, Kalman tracker, video pipeline, PETS tools, sim evaluation, facing."""
