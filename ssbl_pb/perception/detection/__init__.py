"""People in one camera frame: detectors (colour, HOG, SSD, MoveNet), ground position from a box (ground, ranging),
and which way a person faces (facing)."""
