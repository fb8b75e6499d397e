"""Command-line options shared by the sub-commands: the model options (modes, reduce, beam), the
material list, the one convention for output places and names (README, "Where outputs go"), and
the set-up of a solver command's own process."""

from __future__ import annotations

import argparse
import contextlib
import gc
import os
import re
import sys
from pathlib import Path

#: the BLAS thread pools of a solver command's process, set before numpy loads (a limit set later does not
#: stop the pools from starting): numpy's and scipy's OpenBLAS each start a pool whose idle threads
#: spin after the start and after every call, while the solver's matrices are small (tens to a few
#: hundred rows).  Measured (docs/performance.md, "Fixed cost per process"): 0.16-0.22
#: CPU-s of imports, 0.04 s of the engine's post-processing, the integration unchanged.  A value the
#: user sets wins.
SOLVER_THREADS = {"OPENBLAS_NUM_THREADS": "1"}


def process_setup(args=None) -> None:
    """What a solver command (``simulate``, ``linearize``) changes about its process when it runs
    as one (not ``main`` called from Python), before the solver's imports: the BLAS thread limits
    of SOLVER_THREADS unless the environment sets them, and no cyclic garbage collection
    (reference counting frees as always).  The collector runs ~130 times while the solver's
    imports (numpy, scipy, h5py) create their objects and the run its own: 0.05-0.06 CPU-s of a
    simulate process (examples/flexible_pendulum, examples/beam_slider_crank; medians of 5), and a
    run leaves next to no cyclic garbage (examples/engine: peak memory 145 MB either way)."""
    for name, value in SOLVER_THREADS.items():
        os.environ.setdefault(name, value)
    gc.disable()


#: the double suffixes of sidprep's own files, removed whole when a name is derived from them
OWN_SUFFIXES = (".sid.h5", ".results.h5")


def output_stem(path) -> str:
    """The name an input lends to its outputs: ``piston_rod.msh`` -> ``piston_rod``,
    ``piston_rod.sid.h5`` -> ``piston_rod``, ``scene.results.h5`` -> ``scene``."""
    name = Path(path).name
    for suffix in OWN_SUFFIXES:
        if name.lower().endswith(suffix):
            return name[:-len(suffix)]
    return Path(name).stem


def default_output(input_path, suffix: str, given=None) -> Path:
    """The output of a command: ``given`` (its -o) when set, else ``./<input stem><suffix>`` in the
    current folder (the convention of every command; companion files go beside the main output)."""
    return Path(given) if given else Path(output_stem(input_path) + suffix)


#: the shared options' help texts: one meaning in every command (docs/cli.md; tests/test_cli_grammar.py)
QUIET_HELP = "print only errors, warnings and the requested output (the files written, or the --json object)"
JSON_HELP = "print one JSON object on stdout instead of the text (reports and progress go to stderr)"
CSV_HELP = "also write the tables as CSV beside the output (its stem, .csv)"
COUNT_HELP = "number of elastic modes (default 10; rigid-body modes are listed besides)"
#: the --count default of every command that lists modes
DEFAULT_COUNT = 10


def add_output(parser, metavar: str, default: str) -> None:
    """``-o/--output``: the command's main output (a file, or batch's folder); companions share its stem."""
    parser.add_argument("-o", "--output", metavar=metavar, help=f"output (default {default}); companion files go "
                                                                "beside it with its stem")


def add_quiet(parser) -> None:
    parser.add_argument("-q", "--quiet", action="store_true", help=QUIET_HELP)


def add_json(parser) -> None:
    parser.add_argument("--json", action="store_true", help=JSON_HELP)


def add_csv(parser) -> None:
    parser.add_argument("--csv", action="store_true", help=CSV_HELP)


def add_count(parser) -> None:
    parser.add_argument("--count", type=int, metavar="N", default=DEFAULT_COUNT, help=COUNT_HELP)


def add_sid_files(parser) -> None:
    """``--sid-fem/--no-sid-fem`` and ``--obj/--no-obj``: the companion files of a SID (default on)."""
    parser.add_argument("--sid-fem", action=argparse.BooleanOptionalAction, default=None,
                        help="also write <output stem>.SID_FEM (default on)")
    parser.add_argument("--obj", action=argparse.BooleanOptionalAction, default=None,
                        help="also write the surface <output stem>.obj (default on)")


class MaterialList(argparse.Action):
    """``--material NAME``; ``--material list`` prints the built-in materials and exits."""

    def __call__(self, parser, namespace, values, option_string=None):
        if values == "list":
            from sidprep.fe.material import BUILTIN

            print(f"{'name':<14s} {'E [GPa]':>8s} {'nu':>6s} {'rho [kg/m^3]':>13s}")
            for m in BUILTIN.values():
                print(f"{m.name:<14s} {m.E / 1e9:8.1f} {m.nu:6.3f} {m.rho:13.0f}")
            print("sources: sidprep/fe/material.py; any other material: --E --nu --rho")
            parser.exit(0)
        setattr(namespace, self.dest, values)


def add_material(parser) -> None:
    """--material NAME | list, or --E --nu --rho (in the --units of the command; SI when it has none)."""
    mat = parser.add_argument_group("material (default steel, E = 210 GPa, nu = 0.3, rho = 7850 kg/m^3)")
    mat.add_argument("--E", type=float, help="Young's modulus (Pa, or MPa with --units mm-t-s)")
    mat.add_argument("--nu", type=float, help="Poisson's ratio")
    mat.add_argument("--rho", type=float, help="density (kg/m^3, or t/mm^3 with --units mm-t-s)")
    mat.add_argument("--material", action=MaterialList,
                     help="built-in material: steel, aluminium, titanium, cast_iron, ductile_iron "
                          "('--material list' prints their E, nu, rho); the label of --E --nu --rho")


def add_model_arguments(parser, *, units_default: str | None) -> None:
    """Material (--E --nu --rho | --material), --units, and --size/--order for geometry files.

    ``units_default`` None lets a job file supply the unit system (``sidprep reduce job.toml``).
    """
    add_material(parser)
    parser.add_argument("--units", default=units_default, choices=("si", "mm-t-s"),
                        help="unit system of mesh coordinates and material values (default si); results are SI")
    geo = parser.add_argument_group("geometry files (.geo .step .brep): meshed with gmsh")
    geo.add_argument("--size", type=float, metavar="H", help="element size (in the geometry's length unit)")
    geo.add_argument("--order", type=int, choices=(1, 2), help="tet4 (1) or tet10 (2, default)")


@contextlib.contextmanager
def quiet_native_output():
    """Send what native libraries write to stdout (file descriptor 1, e.g. CHOLMOD warnings) to
    stderr while the block runs, so that stdout holds only results (``--json`` stays parseable)."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        os.dup2(2, 1)
        yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)


#: "key = value: ..." at the start of a library message (after an optional "file: ")
_SETTING = re.compile(r"^((?:\S+: )?)([a-z_]+) = (\S+?):")


@contextlib.contextmanager
def cli_flags(flags=("modes", "fmax", "count", "damping", "cutoff_factor", "frame", "output", "clamp",
                     "workers", "matrices")):
    """Name command-line flags in the library's setting errors: "modes = 0: ..." -> "--modes 0: ..."."""
    from sidprep.errors import InputError

    try:
        yield
    except InputError as exc:
        match = _SETTING.match(str(exc))
        if not match or match.group(2) not in flags or match.group(1):
            raise
        flag = "--" + match.group(2).replace("_", "-")
        raise InputError(f"{flag} {match.group(3).strip(chr(39))}:{str(exc)[match.end():]}") from None
