"""Where the first run's compilation goes: one `sidprep` CLI command in this process, numba's
`numba:compile` events timed per function (CPU s, exclusive of the callees' own compilation).

Run it with an empty kernel cache to see a first run after install::

    NUMBA_CACHE_DIR=$(mktemp -d) python benchmarks/compile_profile.py simulate examples/flexible_pendulum/scene.toml

Prints the whole process's CPU seconds, the number of compile events and the most expensive
functions on stderr (docs/performance.md, "First run: kernel compilation").
"""

from __future__ import annotations

import collections
import sys
import time

from numba.core import event

from sidprep.cli.main import main as cli

#: functions listed
TOP = 45


class CompileTimes(event.Listener):
    """Exclusive CPU seconds and counts of numba's compilations, per function name."""

    def __init__(self):
        self.seconds = collections.Counter()
        self.counts = collections.Counter()
        self.stack: list[list] = []

    def on_start(self, ev):
        self.stack.append([ev.data["dispatcher"].py_func.__qualname__, time.process_time(), 0.0])

    def on_end(self, ev):
        name, started, children = self.stack.pop()
        spent = time.process_time() - started
        self.seconds[name] += spent - children
        self.counts[name] += 1
        if self.stack:
            self.stack[-1][2] += spent


def main(argv=None) -> None:
    times = CompileTimes()
    with event.install_listener("numba:compile", times):
        try:
            cli(argv if argv is not None else sys.argv[1:])
        except SystemExit:
            pass
    print(f"whole process {time.process_time():.1f} CPU s; compilation {sum(times.seconds.values()):.1f} s in "
          f"{sum(times.counts.values())} events", file=sys.stderr)
    for name, seconds in times.seconds.most_common(TOP):
        print(f"{seconds:7.2f} s  {times.counts[name]:3d}x  {name}", file=sys.stderr)


if __name__ == "__main__":
    main()
