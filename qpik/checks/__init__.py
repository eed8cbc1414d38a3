"""Checks across solvers: the closed form, the full-joint NLP and the QP controller on one pose."""
