"""DART (dartpy): the engine's home in the suite.

- :mod:`.adapter`: one body on a FreeJoint or BallJoint;
- :mod:`.system`: systems of bodies as one Skeleton, loops closed by joint constraints.
"""
