"""User-facing errors: one line naming the file, the problem and the fix."""


class InputError(Exception):
    """Bad input (file, option, model).  The CLI prints ``sidprep: error: <message>`` and exits 2.

    The message must be one line that names the file or option, the problem and the fix,
    e.g. ``"rod.msh: 3 elements have negative volume (worst: element 1207); re-mesh or fix the node order"``.
    """

    exit_code = 2


class SimulationFailed(InputError):
    """A simulation stopped before t_end (Newton failure, divergence, max_steps); ``result``
    holds everything computed up to the last accepted step (``result.stats["failed"]`` says
    why), so that it can be written and inspected."""

    def __init__(self, message: str, result=None):
        super().__init__(message)
        self.result = result
