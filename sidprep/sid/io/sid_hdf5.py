"""SID in HDF5 (``.sid.h5``): canonical, versioned, with units and provenance.

The schema (sid-spec.md section 8, documented in docs/sid-hdf5.md):

* ``/`` attrs ``format = "sidprep-sid"``, ``version``, ``units``; ``/units`` attrs name the unit of
  length, mass, time, force, angle; every Taylor group carries ``unit`` (of M0) and ``unit_M1``.
* ``/refmod``: attrs ``mass``, ``nelastq``; datasets ``ielastq``, ``freq_hz``, ``mode_kind``.
* ``/frame/<i>``: attrs ``node_id``, ``name``, ``rframe``; Taylor groups origin, phi, psi, AP[, sigma].
* ``/modal/<member>``: Taylor groups (``M0`` (nrow, ncol), optional ``M1`` (nrow, nq, ncol), attrs
  ``order``, ``structure``, ``nq``, ``nqn``); J with ``component_order``, Oe with
  ``omega_hat_order``; Gr as canonical ``G0`` (nq, 3, 3) [+ ``G1`` (nq, nq, 3, 3)], Ge as
  canonical ``Ge`` (3, nq, nq) [+ ``Ge1`` (3, nq, nq, nq)].
* ``/geometric_stiffness/<key>``: the raw parts of ``SID.stiffening``.
* ``/fe/surface``: points, triangles, shapes, node_ids of ``SID.surface``.
* ``/paths/<name>`` (version 2): s, points, phi, psi of ``SID.paths[name]`` (moving loads).
* ``/stress`` (optional, its own attr ``version`` = STRESS_VERSION): node_ids, points, modes
  (ns, 6, nq) of ``SID.stress``, attrs ``component_order``, ``scope``, ``method``, ``unit``.
* ``/provenance`` attrs: ``metadata`` (JSON of ``SID.metadata``), writer and library versions;
  ``/checks`` attr ``json``: the model checks at write time (not part of the SID read back).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import h5py
import numpy as np

from sidprep import __version__
from sidprep.errors import InputError
from sidprep.sid.check import Check, checks_as_dicts
from sidprep.sid.checks import sid_checks
from sidprep.sid.io.atomic import atomic_hdf5
from sidprep.sid.io.hdf5 import open_hdf5
from sidprep.sid.model import (BodyPath, J_ORDER, OMEGA_HAT_ORDER, SID, SIDNode, SurfaceModes, Taylor,
    ge_tensor, gr_tensor)
from sidprep.sid.stress import STRESS_ORDER, StressModes

FORMAT = "sidprep-sid"
#: 2: adds the optional /paths group (version-1 files read as before)
VERSION = 2
NODE_MEMBERS = ("origin", "phi", "psi", "AP", "sigma")
#: BodyPath members (in its field order) and their units
PATH_MEMBERS = {"s": "m", "points": "m", "phi": "m/[q]", "psi": "rad/[q]"}
#: version of the optional /stress group (a group of its own version: files without it read as before)
STRESS_VERSION = 1
MODAL_MEMBERS = ("mdCM", "J", "Ct", "Cr", "Me", "Gr", "Ge", "Oe", "ksigma", "Ke", "De")
SI_UNITS = {"length": "m", "mass": "kg", "time": "s", "force": "N", "angle": "rad",
            "frequency": "Hz", "modal_coordinate": "[q] (phi in m per unit q)"}
#: SI unit of M0 of each member; M1 has the unit of M0 per [q] (sid-spec.md section 3)
MEMBER_UNITS = {
    "origin": "m", "phi": "m/[q]", "psi": "rad/[q]", "AP": "1", "sigma": "Pa",
    "mdCM": "kg m", "J": "kg m^2", "Ct": "kg m/[q]", "Cr": "kg m^2/[q]", "Me": "kg m^2/[q]^2",
    "Gr": "kg m^2/[q]", "Ge": "kg m^2/[q]^2", "Oe": "kg m^2/[q]", "ksigma": "N m/[q]",
    "Ke": "N m/[q]^2", "De": "N m s/[q]^2",
}


def _json_default(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (set, frozenset)):
        return sorted(value)
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"{type(value).__name__} is not JSON-serialisable")


def to_json(value) -> str:
    """JSON text of metadata / check results (numpy scalars and arrays become numbers/lists)."""
    return json.dumps(value, default=_json_default, sort_keys=True)


# ------------------------------------------------------------------------------------------------
# writer
# ------------------------------------------------------------------------------------------------

def _write_taylor(group: h5py.Group, T: Taylor, nq: int, unit: str, units_si: bool) -> None:
    group.create_dataset("M0", data=T.M0)
    if T.M1 is not None:
        group.create_dataset("M1", data=T.M1)
    group.attrs.update(order=T.order, structure=T.structure, nq=nq, nqn=0)
    if units_si:
        group.attrs.update(unit=unit, unit_M1=f"{unit}/[q]")


def _write_strings(group: h5py.Group, name: str, values) -> None:
    group.create_dataset(name, data=list(values), dtype=h5py.string_dtype())


def _library_versions() -> dict:
    return {"sidprep": __version__, "numpy": np.__version__, "h5py": h5py.__version__,
            "hdf5": h5py.version.hdf5_version, "python": sys.version.split()[0]}


def write_sid_hdf5(sid: SID, path, checks: dict | None = None) -> Path:
    """Write ``sid`` to ``path`` (.sid.h5) atomically; ``checks`` ({name: Check}, sid_checks result) default
    computed."""
    if checks is None:
        checks = sid_checks(sid)
    nq = sid.nq
    si = sid.units == "SI"
    with atomic_hdf5(path) as f:
        f.attrs.update(format=FORMAT, version=VERSION, units=sid.units)
        units = f.create_group("units")
        units.attrs.update(system=sid.units, **(SI_UNITS if si else {}))

        ref = f.create_group("refmod")
        ref.attrs.update(mass=sid.mass, nelastq=nq)
        _write_strings(ref, "ielastq", sid.labels)
        ref.create_dataset("freq_hz", data=np.asarray(sid.frequencies_hz, dtype=float))
        _write_strings(ref, "mode_kind", sid.mode_kinds)

        frame = f.create_group("frame")
        frame.attrs["count"] = len(sid.nodes)
        for i, node in enumerate(sid.nodes):
            g = frame.create_group(str(i))
            g.attrs.update(node_id=node.node_id, name=node.name, rframe="body ref")
            for member in NODE_MEMBERS:
                T = getattr(node, member)
                if T is not None:
                    _write_taylor(g.create_group(member), T, nq, MEMBER_UNITS[member], si)

        modal = f.create_group("modal")
        for member in MODAL_MEMBERS:
            T = getattr(sid, member)
            g = modal.create_group(member)
            g.attrs.update(order=T.order, structure=T.structure, nq=nq, nqn=0)
            if si:
                g.attrs.update(unit=MEMBER_UNITS[member], unit_M1=f"{MEMBER_UNITS[member]}/[q]")
            if member == "Gr":
                g.create_dataset("G0", data=gr_tensor(T.M0, nq))
                if T.M1 is not None:   # G1[k, j, i, a]: coefficient of q_j in Gr_k[i, a]
                    g.create_dataset("G1", data=T.M1.reshape(3, nq, 3, nq).transpose(3, 1, 0, 2))
                g.attrs.update(axes="G0[k, i, a]: coefficient of qdot_k omega_a in row i",
                               ascii_layout=_ascii_layout(sid, "Gr"))
            elif member == "Ge":
                g.create_dataset("Ge", data=ge_tensor(T.M0, nq))
                if T.M1 is not None:   # Ge1[a, k, l, j]: coefficient of q_j in Ge_a[k, l]
                    g.create_dataset("Ge1", data=T.M1.reshape(nq, nq, 3, nq).transpose(2, 0, 3, 1))
                g.attrs.update(axes="Ge[a, k, j]: coefficient of omega_a qdot_j in row k",
                               ascii_layout=_ascii_layout(sid, "Ge"))
            else:
                g.create_dataset("M0", data=T.M0)
                if T.M1 is not None:
                    g.create_dataset("M1", data=T.M1)
        modal["J"].attrs["component_order"] = ",".join(J_ORDER)
        modal["Oe"].attrs["omega_hat_order"] = ",".join(OMEGA_HAT_ORDER)

        geo = f.create_group("geometric_stiffness")
        geo.attrs["layout"] = "K[c, k, j]: load component c, row k, column j (sid-spec.md 6.3)"
        for key, value in sid.stiffening.items():
            geo.create_dataset(key, data=np.asarray(value, dtype=float))

        if sid.surface is not None:
            s = f.create_group("fe/surface")
            for name in ("points", "triangles", "shapes", "node_ids"):
                s.create_dataset(name, data=getattr(sid.surface, name))
            s.attrs["shapes_axes"] = "shapes[s, c, k]: displacement component c of surface node s per unit q_k"

        for name, path_ in sid.paths.items():
            g = f.create_group(f"paths/{name}")
            for member, unit in PATH_MEMBERS.items():
                g.create_dataset(member, data=np.asarray(getattr(path_, member), dtype=float)).attrs["unit"] = unit
            g.attrs["axes"] = "phi[i, c, k], psi[i, c, k]: component c at s[i] per unit q_k"

        if sid.stress is not None:
            write_stress(f.create_group("stress"), sid.stress)

        prov = f.create_group("provenance")
        prov.attrs.update(metadata=to_json(dict(sid.metadata)), libraries=to_json(_library_versions()))
        f.create_group("checks").attrs["json"] = to_json(checks_as_dicts(checks))
    return Path(path)


def write_stress(g: h5py.Group, stress: StressModes) -> None:
    """The /stress group of ``SID.stress`` (docs/sid-hdf5.md)."""
    g.attrs.update(version=STRESS_VERSION, component_order=",".join(STRESS_ORDER), scope=stress.scope,
                   method=stress.method, unit="Pa/[q]",
                   axes="modes[s, c, k]: stress component c at node s per unit q_k")
    g.create_dataset("node_ids", data=np.asarray(stress.node_ids, dtype=np.int64))
    g.create_dataset("points", data=np.asarray(stress.points, dtype=float)).attrs["unit"] = "m"
    g.create_dataset("modes", data=np.asarray(stress.modes, dtype=float)).attrs["unit"] = "Pa/[q]"


def read_stress(g: h5py.Group) -> StressModes:
    """SID.stress from a /stress group; a newer group version or another component order is refused."""
    version = schema_version(g.attrs.get("version", -1))
    if version not in range(1, STRESS_VERSION + 1):
        raise ValueError(f"/stress version {version} (this sidprep reads 1..{STRESS_VERSION}; upgrade sidprep)")
    order = tuple(str(g.attrs["component_order"]).split(","))
    if order != STRESS_ORDER:
        raise ValueError(f"/stress component_order {','.join(order)} (expected {','.join(STRESS_ORDER)})")
    return StressModes(g["node_ids"][()], g["points"][()], g["modes"][()], str(g.attrs["scope"]),
                       str(g.attrs["method"]))


def _ascii_layout(sid: SID, member: str) -> str:
    dialect = sid.metadata.get("sid_fem_dialect", {}) if isinstance(sid.metadata, dict) else {}
    return str(dialect.get(f"{member}_layout", "a-block"))


# ------------------------------------------------------------------------------------------------
# reader
# ------------------------------------------------------------------------------------------------

def _read_taylor(group: h5py.Group) -> Taylor:
    M1 = group["M1"][()] if "M1" in group else None
    return Taylor(group["M0"][()], M1, int(group.attrs["structure"]))


def _strings(dataset) -> tuple[str, ...]:
    return tuple(dataset.asstr()[()])


def _read(f: h5py.File) -> SID:
    nq = int(f["refmod"].attrs["nelastq"])
    nodes = []
    for i in range(int(f["frame"].attrs["count"])):
        g = f["frame"][str(i)]
        parts = {m: _read_taylor(g[m]) for m in NODE_MEMBERS if m in g}
        nodes.append(SIDNode(int(g.attrs["node_id"]), parts["origin"], parts["phi"], parts["psi"],
                             parts["AP"], parts.get("sigma"), str(g.attrs["name"])))
    members = {}
    for member in MODAL_MEMBERS:
        g = f["modal"][member]
        structure = int(g.attrs["structure"])
        if member == "Gr":
            G0 = g["G0"][()]
            M1 = g["G1"][()].transpose(2, 1, 3, 0).reshape(3, nq, 3 * nq) if "G1" in g else None
            members[member] = Taylor(G0.transpose(1, 2, 0).reshape(3, 3 * nq), M1, structure)
        elif member == "Ge":
            Ge = g["Ge"][()]
            M1 = g["Ge1"][()].transpose(1, 3, 0, 2).reshape(nq, nq, 3 * nq) if "Ge1" in g else None
            members[member] = Taylor(Ge.transpose(1, 0, 2).reshape(nq, 3 * nq), M1, structure)
        else:
            members[member] = _read_taylor(g)
    stiffening = {}
    f["geometric_stiffness"].visititems(
        lambda name, obj: stiffening.__setitem__(name, obj[()]) if isinstance(obj, h5py.Dataset) else None)
    surface = None
    if "fe/surface" in f:
        s = f["fe/surface"]
        surface = SurfaceModes(*(s[name][()] for name in ("points", "triangles", "shapes", "node_ids")))
    paths = {name: BodyPath(*(g[member][()] for member in PATH_MEMBERS)) for name, g in f.get("paths", {}).items()}
    return SID(
        mass=float(f["refmod"].attrs["mass"]), labels=_strings(f["refmod/ielastq"]),
        nodes=tuple(nodes), **members, frequencies_hz=f["refmod/freq_hz"][()],
        mode_kinds=_strings(f["refmod/mode_kind"]), units=str(f.attrs["units"]),
        stiffening=stiffening, metadata=json.loads(f["provenance"].attrs["metadata"]),
        surface=surface, paths=paths, stress=read_stress(f["stress"]) if "stress" in f else None)


def schema_version(value) -> int | None:
    """The integer schema version in a ``version`` attribute, or None (not a whole number)."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return int(number) if number.is_integer() else None


def read_sid_hdf5(path) -> SID:
    """Read a ``.sid.h5`` file written by ``write_sid_hdf5``; bad files raise InputError."""
    path = Path(path)
    with open_hdf5(path, "SID file", "give a .sid.h5 file written by sidprep") as f:
        if f.attrs.get("format") != FORMAT:
            raise InputError(f"{path}: HDF5 file is not a sidprep SID (attribute format != "
                             f"{FORMAT!r}); give a .sid.h5 file written by sidprep")
        version = f.attrs.get("version", -1)
        if schema_version(version) not in range(1, VERSION + 1):
            raise InputError(f"{path}: SID schema version {version} is not supported (this sidprep "
                             f"reads 1..{VERSION}); upgrade sidprep or re-export the file")
        try:
            return _read(f)
        except (KeyError, ValueError, TypeError, AttributeError, IndexError) as exc:   # a member missing,
            # of another kind (dataset for group) or shape: the file's structure is not a SID's
            raise InputError(f"{path}: incomplete SID HDF5 file ({exc}); re-export it") from None


def read_checks(path) -> dict:
    """The model checks stored in a ``.sid.h5`` file at write time, ``{name: Check}``."""
    with open_hdf5(path, "SID file", "give a .sid.h5 file written by sidprep") as f:
        stored = json.loads(f["checks"].attrs["json"]) if "checks" in f else {}
    return {name: Check.from_dict(entry) for name, entry in stored.items()}
