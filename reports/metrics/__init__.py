"""Stage 1 of the suite's output side: what a trajectory is worth.

The metric catalog (:mod:`.catalog`: each metric declared once in
:mod:`scenarios.metric_catalog`, its function attached, every table derived), metrics of one
body (:mod:`.body`), of a system of bodies (:mod:`.system`) and of bodies in contact
(:mod:`.contact`), observables measured from a
trajectory (:mod:`.observables`), metrics streamed over long runs (:mod:`.streaming`) and the
verdict rules (:mod:`.verdicts`). Imports nothing of ``reports`` above it.
"""
