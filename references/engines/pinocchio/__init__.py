"""Pinocchio: the engine's home in the suite.

- :mod:`.adapter`: one body on a FreeFlyer or Spherical joint;
- :mod:`.system`: systems of bodies, loops closed by rigid constraint models.
"""
