"""User-facing errors: one line naming the file, the problem and the fix."""


class InputError(Exception):
    """Bad input (file, option, model).  The CLI prints ``sidprep: error: <message>`` and exits 2.

    The message must be one line that names the file or option, the problem and the fix,
    e.g. ``"rod.msh: 3 elements have negative volume (worst: element 1207); re-mesh or fix the node order"``.
    """

    exit_code = 2
