"""Browser pages: a SID's modes and a simulation's bodies drawn from the one surface model of
``sidprep.sid.surface``. Imports sid/ and the solver's results."""
