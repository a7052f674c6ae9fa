"""Stage 5: judging one output folder against another: the regression gate against a baseline
(:mod:`.check`) and the comparison of two folders (:mod:`.compare`).
"""
