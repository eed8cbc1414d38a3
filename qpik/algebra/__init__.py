"""The maths under the kinematics: one scalar algebra for numpy and CasADi, SO(3)/SE(3), Taylor models, the
general 6-R chain's elimination to one eigenproblem."""
