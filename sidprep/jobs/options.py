"""Typed, frozen settings of the library's jobs; every default is defined here, once.

The names are those of the TOML job files and (with ``-`` for ``_``) of the command line.
Error messages name the option as a setting (``modes = 0``), never a command-line flag.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sidprep.errors import InputError
from sidprep.sid.io import HDF5_SUFFIXES


#: default number of elastic eigenmodes of interest of a reduction (8: with 6 the piston rod's axial
#: FRMs fall above the 5x cut-off and its static deflection misses the FEMBS 1 % promise: 5.8 % vs 0.48 %)
DEFAULT_MODES = 8
#: default number of elastic modes of a modal analysis
DEFAULT_MODAL_COUNT = 10
#: default modal damping ratio (typical of bolted steel parts)
DEFAULT_DAMPING = 0.02
#: FRM cut-off / highest frequency of interest (FEMBS default)
DEFAULT_CUTOFF_FACTOR = 5.0
#: the material used when none is given (sidprep.fe.material's table: E = 210 GPa, nu = 0.3, rho = 7850 kg/m^3)
DEFAULT_MATERIAL = "steel"
#: fewest fixed-interface modes of the Craig-Bampton step when ``modes`` is given
CB_MIN_MODES = 20


@dataclass(frozen=True)
class ModelOptions:
    """The FE model: geometry meshing, material (in ``units``) and the unit system of the inputs."""

    size: float | None = None
    order: int = 2
    E: float | None = None
    nu: float | None = None
    rho: float | None = None
    material: str | None = None
    units: str = "si"


@dataclass(frozen=True)
class ReduceOptions(ModelOptions):
    """A reduction (sidprep.jobs.reduce.reduce): the model plus interfaces, frame, modes and damping.

    interfaces : "NAME[:rbe2|rbe3]" strings or job-file tables; empty = every node set able to
    carry 6 DOF, as RBE2. frame : "free" or an interface name. modes / fmax (Hz): one of them
    (neither = ``DEFAULT_MODES``). damping : ratio in [0, 1), a per-mode tuple, or
    {"rayleigh": (alpha [1/s], beta [s])}. paths : "NAME:x0,y0,z0:x1,y1,z1[:...][:n]" (the
    curve through these points) or "NAME:nodes=SET:dir=x[:n]" (through a node set ordered along
    dir), stored with their interpolated mode shapes (sidprep.reduction.paths). stress : None,
    "surface" or "all": modal stresses at those nodes (sidprep.reduction.stress). matrices : a file of
    K and M written by another FE code (sidprep.fe.matrices: .sti, .eig, .mtx, .pch, .full) used instead of
    sidprep's own assembly; the mesh is then the deck they belong to (any solid elements). parts : reduce
    the model in that many parts (component mode synthesis, sidprep.jobs.parts; None = in one piece).
    """

    interfaces: tuple = ()
    frm_nodes: tuple[str, ...] = ()
    frame: str = "free"
    modes: int | None = None
    fmax: float | None = None
    frm: bool = True
    cutoff_factor: float = DEFAULT_CUTOFF_FACTOR
    damping: float | tuple | dict = DEFAULT_DAMPING
    stiffening: bool = False
    check_frequencies: bool = True
    paths: tuple[str, ...] = ()
    stress: str | None = None
    matrices: str | None = None
    parts: int | None = None


@dataclass(frozen=True)
class OutputOptions:
    """Files of a reduction: ``output`` the .sid.h5 (None = ./<mesh stem>.sid.h5), plus .SID_FEM and .obj."""

    output: str | None = None
    sid_fem: bool = True
    obj: bool = True


@dataclass(frozen=True)
class ModalOptions(ModelOptions):
    """A modal analysis (sidprep.jobs.modal.modal_analysis): ``count`` elastic modes or all up to
    ``fmax`` (Hz); ``clamp`` node sets fixed; ``backend`` auto | cholmod | superlu | lobpcg | dense."""

    count: int | None = None
    fmax: float | None = None
    clamp: tuple[str, ...] = ()
    backend: str = "auto"


def material_given(o: ModelOptions) -> bool:
    return o.material is not None or any(v is not None for v in (o.E, o.nu, o.rho))


def check_damping(damping) -> None:
    """Damping ratios must lie in [0, 1): below 0 adds energy, 1 and above is no longer a vibration."""
    if isinstance(damping, dict):
        from sidprep.reduction.modes import modal_damping  # deferred: 0.25 s import (scipy.linalg), Rayleigh only

        modal_damping(np.ones(1), damping)
        return
    values = np.atleast_1d(np.asarray(damping, dtype=float))
    bad = values[~((values >= 0) & (values < 1))]
    if len(bad):
        raise InputError(f"damping = {bad[0]:g}: a modal damping ratio must be >= 0 and < 1 (typical 0.01-0.05)")


def check_reduce_options(o: ReduceOptions) -> None:
    """One-line InputErrors for inconsistent reduction settings, before any work."""
    if o.modes is not None and o.fmax is not None:
        raise InputError("modes and fmax: give one of them, not both")
    if o.modes is not None and o.modes < 1:
        raise InputError(f"modes = {o.modes}: must be >= 1")
    if o.fmax is not None and not o.fmax > 0:
        raise InputError(f"fmax = {o.fmax}: must be > 0 Hz")
    if not o.cutoff_factor >= 1:
        raise InputError(f"cutoff_factor = {o.cutoff_factor}: must be >= 1 (FEMBS default {DEFAULT_CUTOFF_FACTOR:g})")
    check_damping(o.damping)
    if o.stress not in (None, "surface", "all"):
        raise InputError(f"stress = {o.stress!r}: use surface (the outer surface's nodes) or all (every node)")
    if o.matrices and o.stiffening:
        raise InputError(f"stiffening = true: the geometric stiffening needs sidprep's own elements (stresses), "
                         f"not imported matrices ({o.matrices}); drop stiffening or reduce a tetrahedral mesh")
    if o.parts is not None and o.parts < 2:
        raise InputError(f"parts = {o.parts}: must be >= 2 (or none, to reduce the model in one piece)")


def check_output(path) -> Path:
    """The HDF5 output path, checked before the work: a .sid.h5 / .h5 / .hdf5 file name, not a folder,
    in a folder that exists or can be created and is writable."""

    path = Path(path)
    if path.is_dir():
        raise InputError(f"output {path}: is a folder; give a file name such as {path / 'body.sid.h5'}")
    if not path.name.lower().endswith(HDF5_SUFFIXES):
        raise InputError(f"output {path}: unknown file type; the output must end in .sid.h5 (or .h5, .hdf5)")
    parent = path.resolve().parent
    while not parent.exists():
        parent = parent.parent
    try:                                                  # a real write: os.access says yes to root
        with tempfile.TemporaryFile(dir=parent):
            pass
    except OSError:
        raise InputError(f"output {path}: folder {parent} is not writable; choose a writable folder") from None
    return path
