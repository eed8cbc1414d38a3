"""Offline self-motion planning along an end-effector path."""
