"""How the physics compares with the measurements and where it fails: the analyses a diagnosis composes."""
