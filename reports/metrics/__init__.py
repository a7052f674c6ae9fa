"""Stage 1 of the suite's output side: what a trajectory is worth.

Metrics of one body (:mod:`.body`) and of a system of bodies (:mod:`.system`), observables
measured from a trajectory (:mod:`.observables`), metrics streamed over long runs
(:mod:`.streaming`) and the verdict rules and default tolerances (:mod:`.verdicts`). Imports
nothing of ``reports`` above it.
"""
