"""Stage 2: the results store of an output folder (:mod:`.results`: rows, identities,
trajectories on disk), its provenance record (:mod:`.provenance`), the ensemble store
(:mod:`.ensemble`), the one write-then-rename of every file written after the store
(:mod:`.atomic`) and how a stored value is written as text or JSON (:mod:`.format`). Imports
only :mod:`reports.metrics` of the stages.
"""
