"""The scenario's reference solution as an engine, beside the others in every table.

- :mod:`.adapter`: one body: the closed form or high-accuracy numerical reference;
- :mod:`.system`: systems of bodies: exact motions and the reduced-coordinate reference.
"""
