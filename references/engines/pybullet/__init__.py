"""PyBullet: the engine's home in the suite.

- :mod:`.adapter`: one body, a multibody's base or a link on a spherical joint;
- :mod:`.system`: systems of bodies as btMultiBody trees, loops closed by point constraints.
"""
