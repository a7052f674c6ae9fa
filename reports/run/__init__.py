"""Stage 3: running scenarios on engines and storing what they did: the runner
(:mod:`.runner`), which hands each run to the stepper of its scene's kind (a single body,
:mod:`.body`; a system of bodies, :mod:`.system`; bodies in contact, :mod:`.contact`), the timing
pass (:mod:`.timing`), the serial and distributed mappers (:mod:`.parallel`), ensembles
(:mod:`.ensemble`) and the progress display (:mod:`.progress`).
"""
