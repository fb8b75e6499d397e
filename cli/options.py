"""Command-line options shared by the sub-commands that read an FE model (modes, reduce)."""

from __future__ import annotations

import contextlib
import os
import re
import sys


def add_model_arguments(parser, *, units_default: str | None) -> None:
    """Material (--E --nu --rho | --material), --units, and --size/--order for geometry files.

    ``units_default`` None lets a job file supply the unit system (``sidprep reduce job.toml``).
    """
    mat = parser.add_argument_group("material (default steel, E = 210 GPa, nu = 0.3, rho = 7850 kg/m^3)")
    mat.add_argument("--E", type=float, help="Young's modulus (Pa, or MPa with --units mm-t-s)")
    mat.add_argument("--nu", type=float, help="Poisson's ratio")
    mat.add_argument("--rho", type=float, help="density (kg/m^3, or t/mm^3 with --units mm-t-s)")
    mat.add_argument("--material", help="built-in material: steel, aluminium, titanium, cast_iron, ductile_iron")
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
