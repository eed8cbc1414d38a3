"""Offscreen pictures of the arms through MuJoCo (outside the maths packages)."""
