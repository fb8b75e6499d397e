"""The ``sidprep`` command.  Each sub-command is one module here with ``register(subparsers)``."""
