"""One grammar for every sub-command (docs/cli.md): each shared option, where a command has it,
means the same - the same spelling, kind, default and help text in every ``sidprep X --help``."""

import argparse
import contextlib
import io

import pytest

from sidprep.cli.main import build_parser, main
from sidprep.cli.options import COUNT_HELP, CSV_HELP, DEFAULT_COUNT, JSON_HELP, QUIET_HELP, MaterialList

#: every sub-command (a new one is added here and to docs/cli.md's table)
COMMANDS = ("animate", "batch", "beam", "check", "converge", "info", "linearize", "modes", "plot", "reduce",
            "simulate", "stress", "view")
#: the commands that write files: each has -o/--output
WRITERS = ("animate", "batch", "beam", "converge", "plot", "reduce", "simulate", "stress", "view")
#: the commands that print mode tables: each has --count N, default DEFAULT_COUNT
COUNTERS = ("linearize", "modes")
#: the commands that write SIDs: --sid-fem/--no-sid-fem and --obj/--no-obj, default on
SID_WRITERS = ("batch", "beam", "reduce")


def subcommands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))  # noqa: SLF001
    return dict(sub.choices)


def options(parser) -> dict[str, argparse.Action]:
    return {s: a for a in parser._actions for s in a.option_strings}  # noqa: SLF001


def help_text(command: str) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit):
        main([command, "--help"])
    return " ".join(out.getvalue().split())


def test_every_command_is_in_the_table():
    assert set(subcommands()) == set(COMMANDS)


@pytest.mark.parametrize("command", COMMANDS)
def test_shared_options_mean_the_same_in_every_command(command):
    opts = options(subcommands()[command])
    text = help_text(command)
    assert "-q" in opts and opts["-q"] is opts["--quiet"] and opts["-q"].help == QUIET_HELP
    assert " ".join(QUIET_HELP.split()) in text
    if command in WRITERS:
        assert "-o" in opts and opts["-o"] is opts["--output"] and opts["-o"].dest == "output"
        assert opts["-o"].nargs is None and opts["-o"].default is None        # one value; the default is derived
    else:
        assert "-o" not in opts
    if "--json" in opts:
        assert opts["--json"].help == JSON_HELP and opts["--json"].const is True
    if "--csv" in opts:
        assert opts["--csv"].help == CSV_HELP and opts["--csv"].const is True   # a flag, never a file
    assert ("--count" in opts) == (command in COUNTERS)
    if "--count" in opts:
        assert opts["--count"].default == DEFAULT_COUNT and opts["--count"].help == COUNT_HELP
    if "--material" in opts:
        assert isinstance(opts["--material"], MaterialList)
        assert {"--E", "--nu", "--rho"} <= set(opts)
        assert opts["--E"].help == options(subcommands()["reduce"])["--E"].help
    if "--units" in opts:
        assert opts["--units"].choices == ("si", "mm-t-s")
    if "--modes" in opts:
        assert "count" in opts["--modes"].help or "number" in opts["--modes"].help
    for flag in ("--sid-fem", "--obj"):
        assert (flag in opts) == (command in SID_WRITERS)
        if flag in opts:
            assert isinstance(opts[flag], argparse.BooleanOptionalAction) and "default on" in opts[flag].help
    assert "--outdir" not in opts


def test_beam_takes_a_count_of_modes_like_reduce(tmp_path, capsys):
    """--modes N: the N lowest eigenforms of every kind (a clamped-free beam: 2 x 2 bending, then more)."""
    out = tmp_path / "b.sid.h5"
    assert main(["beam", "--length", "1", "--section", "rectangle:0.02,0.01", "--bc", "clamped-free", "--modes", "3",
                 "-o", str(out), "-q"]) == 0
    files = capsys.readouterr().out.split()
    assert files == [str(out), str(tmp_path / "b.SID_FEM"), str(tmp_path / "b.obj")]   # companions as reduce
    from sidprep.sid.io import read_sid

    f = read_sid(out).frequencies_hz
    assert len(f) == 3 and list(f) == sorted(f)
