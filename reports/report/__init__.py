"""Stage 4: the report, a function of an output folder: what it says as data
(:mod:`.tables`; rows collapsed by :mod:`.groups`, named and ordered by :mod:`.labels`),
figures (:mod:`.plots`, :mod:`.system_plots`), the HTML and Markdown pages (:mod:`.build`),
``summary.json`` (:mod:`.summary_json`), the README block (:mod:`.readme`; both from the
command line :mod:`.summary`) and the JUnit file (:mod:`.junit`). Runs nothing.
"""
