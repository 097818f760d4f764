"""Real recordings: PETS 2009 annotations and calibration (pets, tsai, xmlfile), tracking scores (scoring), and the
feet-hidden variant of a video (occlusion)."""
