"""Stage 5: judging one output folder against another by one comparison rule (:mod:`.rule`):
the regression gate against a baseline (:mod:`.check`) and the comparison of two folders
(:mod:`.compare`), with one table formatter for their outputs (:mod:`.format`).
"""
