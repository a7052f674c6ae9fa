"""Stage 4: the report, a function of an output folder: tables and text (:mod:`.summary`),
figures (:mod:`.plots`, :mod:`.system_plots`), the HTML and Markdown pages (:mod:`.build`) and
the JUnit file (:mod:`.junit`). Runs nothing.
"""
