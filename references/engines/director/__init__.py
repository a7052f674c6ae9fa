"""The suite's own integrator (:mod:`director_model`) as an engine: its home in the suite.

- :mod:`.adapter`: one body, each scheme an integrator;
- :mod:`.system`: systems of bodies with the joints as constraint rows.
"""
