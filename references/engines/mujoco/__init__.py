"""MuJoCo (C library): the engine's home in the suite.

- :mod:`.adapter`: one body on a free or ball joint;
- :mod:`.system`: systems of bodies, loops closed by soft equality constraints.
"""
