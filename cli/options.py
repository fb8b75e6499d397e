"""Command-line options shared by the sub-commands that read an FE model (modes, reduce)."""

from __future__ import annotations


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
