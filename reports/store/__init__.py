"""Stage 2: the results store of an output folder (:mod:`.results`: rows, identities,
trajectories on disk), its provenance record (:mod:`.provenance`) and the ensemble store
(:mod:`.ensemble`). Imports only :mod:`reports.metrics` of the stages.
"""
