"""Stage 3: running scenarios on engines and storing what they did: the runner of one body
(:mod:`.runner`) and of systems (:mod:`.system`), the serial and distributed mappers
(:mod:`.parallel`), ensembles (:mod:`.ensemble`) and the progress display (:mod:`.progress`).
"""
