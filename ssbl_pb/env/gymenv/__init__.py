"""The Gymnasium face: the env (approach), observation modes and action stages, encoded camera modes."""
