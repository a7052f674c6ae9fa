"""The rule that says whether a measured engine time can be trusted, shared by the stopwatch
that measures it (:mod:`references.engines.timing`) and the rows that store it
(:func:`reports.store.runs.starved`): kept here, outside ``references.engines``, so that
reading a results folder imports no engine code."""

#: a run is starved when its estimate's uncertainty exceeds this fraction of the estimate
STARVED = 0.1
