"""The analytical Euler-Bernoulli Beam as a flexible body: its SID from closed-form eigenforms.

Seed 000 sections 2-3 (DLR FlexibleBodies "Beam"): a straight, homogeneous, isotropic beam along
the x-axis of its body frame K, from x = 0 to x = L, cross-section centroid on the axis.  The
eigenforms of the elastic deformation relative to K (boundary conditions at x = 0 and x = L) are
the closed-form Euler-Bernoulli bending forms (planes xz and xy), Saint-Venant torsion and axial
forms, each mass-normalised.  Rotary inertia and shear are neglected in the bending forms (as in
Euler-Bernoulli theory); the rigid-body inertia includes the cross-section's second moments.

Every SID invariant is then formed by ``sidprep.sid.model.sid_invariants`` from a point-mass
quadrature of the beam: composite Gauss-Legendre along x (breakpoints at the frames) times four
section points (0, +-ry, 0), (0, 0, +-rz) with ry = sqrt(2 Iz/A), rz = sqrt(2 Iy/A), which carry
the exact mass, first and second moments of the section.  Geometric stiffening (sid-spec.md 6):
each unit load case gives a normal force N(x) (support of all axial loads at x = 0, the body
frame; unified sign rule u_p = K^-1(-p)), and K0 = integral of N(x)/A sum_i du_i/dx du_i/dx dA dx
(the foreshortening of the forms).  Only numpy and sidprep.sid.model/material/errors are imported: the
solver may import this module.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace

import numpy as np

from sidprep.errors import InputError
from sidprep.fe.material import Material, builtin_material, material_from_options
from sidprep.sid.model import BodyPath, SID, SurfaceModes, eigen_label, sid_invariants
from sidprep.sid.stress import STRESS_ORDER, StressModes

BOUNDARY_CONDITIONS = ("free-free", "clamped-free", "pinned-pinned", "pinned-free",
                       "clamped-pinned", "clamped-clamped")
KINDS = ("xz", "xy", "torsion", "axial")
#: highest eigenform number of a kind: beyond, the half-wavelength falls far below any section
#: height (Euler-Bernoulli theory no longer holds) and the surface / path sampling grows with it
MAX_MODE_NUMBER = 100
PROFILES = {"general": ("A", "Iy", "Iz", "J"), "rectangle": ("b", "h"), "circle": ("d",),
            "tube": ("D", "d"), "rectangular_tube": ("b", "h", "t"), "I": ("b", "h", "tw", "tf"),
            "T": ("b", "h", "tw", "tf"), "U": ("b", "h", "tw", "tf")}
#: Gauss-Legendre points per quadrature segment along x
GAUSS_POINTS = 12
#: segments per radian of the largest wave number times L (keeps each segment below ~1 rad)
SEGMENTS_PER_RAD = 1.0
MIN_SEGMENTS = 16
#: samples of the axis path (SID.paths["axis"]) per half-wave of the shortest kept form: the
#: solver's cubic spline through them is exact to ~1e-7 of the form's amplitude
PATH_POINTS_PER_WAVE, PATH_MIN_POINTS = 32, 101
#: stations of the animation surface (SID.surface) per half-wave of the shortest form
SURFACE_STATIONS_PER_WAVE, SURFACE_MIN_STATIONS = 8, 21


# ------------------------------------------------------------------------------------------------
# Options
# ------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Section:
    """Cross-section: ``profile`` (a key of PROFILES) and its dimensions in m (general: A m^2,
    Iy, Iz, J m^4).  y is the width direction, z the height direction: Iy governs bending in the
    xz-plane (deflection along z)."""

    profile: str = "rectangle"
    dims: tuple[float, ...] = (0.01, 0.01)

    @property
    def properties(self) -> tuple[float, float, float, float]:
        """(A m^2, Iy m^4, Iz m^4, J m^4) of the section."""
        return section_properties(self.profile, self.dims)


@dataclass(frozen=True)
class BeamOptions:
    """Everything that defines a Beam body (SI units).

    modes : tuple of (kind, ordinal) with kind in KINDS, ordinal 1-based per kind.
    damping : one ratio for all kept modes, or one per mode.
    frames : relative positions xsi in [0, 1] of extra SID nodes (nodes at xsi = 0 and 1 always).
    """

    length: float = 1.0
    section: Section = Section()
    material: str | None = "steel"
    E: float | None = None
    nu: float | None = None
    rho: float | None = None
    bc: str = "free-free"
    modes: tuple[tuple[str, int], ...] = (("xz", 1), ("xy", 1))
    damping: tuple[float, ...] = (0.0,)
    frames: tuple[float, ...] = ()


def section_properties(profile: str, dims) -> tuple[float, float, float, float]:
    """(A, Iy, Iz, J) of a profile (thin-walled open sections: J = sum b t^3 / 3; rectangle: Roark)."""
    if profile not in PROFILES:
        raise InputError(f"section {profile!r}: unknown profile; use one of {', '.join(PROFILES)}")
    names = PROFILES[profile]
    if len(dims) != len(names) or not all(math.isfinite(v) and v > 0 for v in dims):
        raise InputError(f"section {profile}: give {len(names)} positive numbers "
                         f"{','.join(names)} (m), got {','.join(map(str, dims)) or 'none'}")
    p = dict(zip(names, map(float, dims)))
    if profile == "general":
        return p["A"], p["Iy"], p["Iz"], p["J"]
    if profile == "rectangle":
        b, h = p["b"], p["h"]
        a, c = max(b, h), min(b, h)
        J = a * c ** 3 * (1 / 3 - 0.21 * c / a * (1 - c ** 4 / (12 * a ** 4)))
        return b * h, b * h ** 3 / 12, h * b ** 3 / 12, J
    if profile == "circle":
        d = p["d"]
        return math.pi * d ** 2 / 4, math.pi * d ** 4 / 64, math.pi * d ** 4 / 64, math.pi * d ** 4 / 32
    if profile == "tube":
        D, d = p["D"], p["d"]
        if d >= D:
            raise InputError(f"section tube:{D},{d}: inner diameter must be below the outer one")
        I = math.pi * (D ** 4 - d ** 4) / 64
        return math.pi * (D ** 2 - d ** 2) / 4, I, I, 2 * I
    b, h = p["b"], p["h"]
    if profile == "rectangular_tube":
        t = p["t"]
        if 2 * t >= min(b, h):
            raise InputError(f"section rectangular_tube: wall t = {t} must be below half of b and h")
        bi, hi = b - 2 * t, h - 2 * t
        J = 2 * t * (b - t) ** 2 * (h - t) ** 2 / ((b - t) + (h - t))       # Bredt
        return b * h - bi * hi, (b * h ** 3 - bi * hi ** 3) / 12, (h * b ** 3 - hi * bi ** 3) / 12, J
    tw, tf = p["tw"], p["tf"]
    if tw >= b or 2 * tf >= h:
        raise InputError(f"section {profile}: need tw < b and 2 tf < h")
    if profile == "I":
        hw = h - 2 * tf
        return (2 * b * tf + hw * tw, (b * h ** 3 - (b - tw) * hw ** 3) / 12,
                2 * tf * b ** 3 / 12 + hw * tw ** 3 / 12, (2 * b * tf ** 3 + hw * tw ** 3) / 3)
    # T (flange on top, web below) and U (web along z, flanges along y), both about the centroid
    if profile == "T":
        rects = [(b, tf, 0.0, h - tf / 2), (tw, h - tf, 0.0, (h - tf) / 2)]
    else:
        rects = [(tw, h, tw / 2, h / 2), (b - tw, tf, tw + (b - tw) / 2, tf / 2),
                 (b - tw, tf, tw + (b - tw) / 2, h - tf / 2)]
    A = sum(w * t for w, t, _, _ in rects)
    yc = sum(w * t * y for w, t, y, _ in rects) / A
    zc = sum(w * t * z for w, t, _, z in rects) / A
    Iy = sum(w * t ** 3 / 12 + w * t * (z - zc) ** 2 for w, t, _, z in rects)
    Iz = sum(t * w ** 3 / 12 + w * t * (y - yc) ** 2 for w, t, y, _ in rects)
    J = sum(max(w, t) * min(w, t) ** 3 / 3 for w, t, _, _ in rects)
    return A, Iy, Iz, J


def beam_material(o: BeamOptions) -> Material:
    """The material of the options (a built-in name or E, nu, rho), SI."""
    if o.E is not None or o.nu is not None or o.rho is not None:
        return material_from_options(E=o.E, nu=o.nu, rho=o.rho,
                                     name=None if o.material in (None, "steel") else o.material)
    if not o.material:
        raise InputError("beam: no material; give a material name or E, nu, rho")
    return builtin_material(o.material)


def check_beam_options(o: BeamOptions) -> None:
    """Validate before any work; raises InputError naming the problem and the fix."""
    if not (math.isfinite(o.length) and o.length > 0):
        raise InputError(f"beam: length {o.length} must be a positive number of metres")
    if o.bc not in BOUNDARY_CONDITIONS:
        raise InputError(f"beam: boundary condition {o.bc!r} unknown; use one of {', '.join(BOUNDARY_CONDITIONS)}")
    if not o.modes:
        raise InputError("beam: no modes selected; give e.g. modes xz:1-3,xy:1")
    for kind, n in o.modes:
        if kind not in KINDS or not 1 <= int(n) <= MAX_MODE_NUMBER:
            raise InputError(f"beam: mode {kind}:{n} invalid; kinds are {', '.join(KINDS)}, ordinals from 1 "
                             f"to {MAX_MODE_NUMBER}")
    if len(set(o.modes)) != len(o.modes):
        raise InputError("beam: a mode is selected twice; list each kind:ordinal once")
    if len(o.damping) not in (1, len(o.modes)) or not all(0 <= z < 1 for z in o.damping):
        raise InputError(f"beam: damping needs one ratio in [0, 1) or one per mode ({len(o.modes)}), "
                         f"got {len(o.damping)}")
    if not all(0 <= x <= 1 for x in o.frames):
        raise InputError(f"beam: frame positions {o.frames} must be relative (0 <= xsi <= 1)")
    o.section.properties
    beam_material(o)


# ------------------------------------------------------------------------------------------------
# Eigenforms (closed form)
# ------------------------------------------------------------------------------------------------

def _ends(bc: str) -> tuple[str, str]:
    a, b = bc.split("-")
    return a, b


def bending_root(bc: str, n: int) -> float:
    """n-th elastic root beta_n L of the Euler-Bernoulli frequency equation (Blevins, table 8-1)."""
    if bc == "pinned-pinned":
        return n * math.pi
    if bc == "clamped-free":
        f, guess = (lambda b: math.cos(b) + 1 / math.cosh(b)), (n - 0.5) * math.pi
    elif bc in ("free-free", "clamped-clamped"):
        f, guess = (lambda b: math.cos(b) - 1 / math.cosh(b)), (n + 0.5) * math.pi
    else:                                        # pinned-free, clamped-pinned: tan b = tanh b
        f, guess = (lambda b: math.sin(b) - math.cos(b) * math.tanh(b)), (n + 0.25) * math.pi
    lo, hi = guess - 0.5, guess + 0.5
    flo = f(lo)
    for _ in range(200):                        # bisection to machine precision
        mid = 0.5 * (lo + hi)
        fm = f(mid)
        if (fm > 0) == (flo > 0):
            lo, flo = mid, fm
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _bending_basis(beta: float, L: float, x: np.ndarray, d: int) -> np.ndarray:
    """d-th x-derivative of the well-conditioned basis cos bx, sin bx, e^-bx, e^-b(L-x); (len(x), 4)."""
    b = beta
    c, s = np.cos(b * x), np.sin(b * x)
    e0, e1 = np.exp(-b * x), np.exp(-b * (L - x))
    trig = [(c, s), (-s, c), (-c, -s), (s, -c)][d]
    return b ** d * np.stack([trig[0], trig[1], (-1) ** d * e0, e1], axis=-1)


def bending_form(bc: str, n: int, L: float):
    """(omega-free factor beta_n, coefficient vector c (4,)) of the n-th bending form, unnormalised."""
    beta = bending_root(bc, n) / L
    conds = {"clamped": (0, 1), "pinned": (0, 2), "free": (2, 3)}
    rows = []
    for end, x in zip(_ends(bc), (0.0, L)):
        for d in conds[end]:
            rows.append(_bending_basis(beta, L, np.array([x]), d)[0] / beta ** d)
    _, _, vt = np.linalg.svd(np.array(rows))
    return beta, vt[-1]


def _bending_eval(beta: float, L: float, c: np.ndarray, d: int):
    """x (m) -> d-th derivative of the bending form with coefficients c."""
    return lambda x: _bending_basis(beta, L, np.asarray(x, float), d) @ c


def _axial_like(held: tuple[bool, bool], n: int, L: float):
    """Wave number and (shape, slope) callables of the n-th axial/torsion form (held = fixed ends)."""
    if held == (False, False):
        k = n * math.pi / L
        return k, (lambda x: np.cos(k * x)), (lambda x: -k * np.sin(k * x))
    k = (n if held[1] else n - 0.5) * math.pi / L
    return k, (lambda x: np.sin(k * x)), (lambda x: k * np.cos(k * x))


def _held(bc: str, kind: str) -> tuple[bool, bool]:
    """Ends held in torsion (clamped and pinned = fork bearing) or axially (pinned at L = roller)."""
    a, b = _ends(bc)
    if kind == "torsion":
        return a != "free", b != "free"
    return a != "free", b == "clamped"


@dataclass(frozen=True)
class Form:
    """One kept eigenform: kind, ordinal, circular frequency (rad/s), shape functions of x."""

    kind: str
    ordinal: int
    omega: float
    value: object          # x (m) -> amplitude (m or rad), mass-normalised
    slope: object          # x -> d/dx
    curvature_wave: float  # wave number (1/m), for the quadrature density
    curvature: object = None  # x -> d^2/dx^2 (bending forms), for the stress modes


def eigenforms(o: BeamOptions) -> list[Form]:
    """The kept forms, mass-normalised: int rho A w^2 dx = 1 (bending, axial), int rho Ip theta^2 = 1."""
    A, Iy, Iz, J = o.section.properties
    m = beam_material(o)
    L = o.length
    G = m.E / (2 * (1 + m.nu))
    forms = []
    for kind, n in o.modes:
        if kind in ("xz", "xy"):
            beta, c = bending_form(o.bc, n, L)
            I = Iy if kind == "xz" else Iz
            omega = beta ** 2 * math.sqrt(m.E * I / (m.rho * A))
            val = _bending_eval(beta, L, c, 0)
            xs, ws = gauss_line(L, [], beta)
            scale = 1 / math.sqrt(m.rho * A * ws @ val(xs) ** 2)
            forms.append(Form(kind, n, omega, _bending_eval(beta, L, c * scale, 0),
                              _bending_eval(beta, L, c * scale, 1), beta, _bending_eval(beta, L, c * scale, 2)))
            continue
        k, f, df = _axial_like(_held(o.bc, kind), n, L)
        inertia, stiffness = (m.rho * (Iy + Iz), G * J) if kind == "torsion" else (m.rho * A, m.E * A)
        scale = math.sqrt(2 / (inertia * L))
        forms.append(Form(kind, n, k * math.sqrt(stiffness / inertia),
                          (lambda f, s: lambda x: s * f(np.asarray(x, float)))(f, scale),
                          (lambda f, s: lambda x: s * f(np.asarray(x, float)))(df, scale), k))
    return forms


def gauss_line(L: float, breaks, wave: float) -> tuple[np.ndarray, np.ndarray]:
    """Composite Gauss-Legendre points and weights on [0, L] with the given breakpoints; m, m."""
    nseg = max(MIN_SEGMENTS, int(math.ceil(SEGMENTS_PER_RAD * wave * L)))
    edges = np.unique(np.concatenate([np.linspace(0, L, nseg + 1), np.asarray(breaks, float) * L]))
    g, w = np.polynomial.legendre.leggauss(GAUSS_POINTS)
    a, b = edges[:-1, None], edges[1:, None]
    return (0.5 * (a + b) + 0.5 * (b - a) * g).ravel(), (0.5 * (b - a) * w).ravel()


# ------------------------------------------------------------------------------------------------
# SID
# ------------------------------------------------------------------------------------------------

def _point_shapes(forms, x, ry, rz):
    """Displacements and their x-derivatives at the quadrature points; (n, 3, nq) each.

    Section points (y, z) in order (ry, 0), (-ry, 0), (0, rz), (0, -rz) per axial point."""
    ys = np.array([ry, -ry, 0.0, 0.0])
    zs = np.array([0.0, 0.0, rz, -rz])
    n, nq = len(x) * 4, len(forms)
    U, D = np.zeros((n, 3, nq)), np.zeros((n, 3, nq))
    y, z = np.tile(ys, len(x)), np.tile(zs, len(x))
    xx = np.repeat(x, 4)
    for k, f in enumerate(forms):
        v, s = f.value(xx), f.slope(xx)
        if f.kind == "xz":
            U[:, 2, k], D[:, 2, k] = v, s
        elif f.kind == "xy":
            U[:, 1, k], D[:, 1, k] = v, s
        elif f.kind == "torsion":
            U[:, 1, k], U[:, 2, k], D[:, 1, k], D[:, 2, k] = -z * v, y * v, -z * s, y * s
        else:
            U[:, 0, k], D[:, 0, k] = v, s
    return np.stack([xx, y, z], axis=1), U, D


def _node_shapes(forms, x):
    """(phi (3, nq), psi (3, nq)) at the beam axis point x."""
    phi, psi = np.zeros((3, len(forms))), np.zeros((3, len(forms)))
    for k, f in enumerate(forms):
        v, s = float(f.value(np.array([x]))[0]), float(f.slope(np.array([x]))[0])
        if f.kind == "xz":
            phi[2, k], psi[1, k] = v, -s
        elif f.kind == "xy":
            phi[1, k], psi[2, k] = v, s
        elif f.kind == "torsion":
            psi[0, k] = v
        else:
            phi[0, k] = v
    return phi, psi


def geometric_stiffness(N: np.ndarray, weights: np.ndarray, D: np.ndarray) -> np.ndarray:
    """K0 = sum_p w_p N(x_p) D_p^T D_p, the projected K_G of a normal force N (N) (sid-spec 6.5
    for a beam: integral of sigma_xx du/dx . du/dx dV); weights are the area fractions times dx."""
    return np.einsum("p,pik,pij->kj", weights * N, D, D)


def stiffening_cases(L: float, rhoA: float, x: np.ndarray, frame_x) -> dict[str, np.ndarray]:
    """Normal force N(x) (N, tension > 0) per unit load case under the sign rule u = K^-1(-p),
    axial loads supported at x = 0: {slot: (ncases, len(x))} (sid-spec 6.3)."""
    zero = np.zeros_like(x)
    cases = {"K0t": np.stack([-rhoA * (L - x), zero, zero]),
             "K0r": np.stack([zero, zero, zero]),
             # omega-hat order xx yy zz xy yz xz: only yy and zz load the beam axially (w = -x e_x)
             "K0omega": np.stack([zero, *(2 * [rhoA * (L ** 2 - x ** 2) / 2]), zero, zero, zero])}
    for i, xn in enumerate(frame_x):
        cases[f"K0F/{i}"] = np.stack([np.where(x < xn, -1.0, 0.0), zero, zero])
        cases[f"K0M/{i}"] = np.stack([zero, zero, zero])
    return cases


def beam_sid(options: BeamOptions) -> SID:
    """The SID of a Beam (Heckmann et al. 2006 section 3): every invariant of the FE route, with stiffening."""
    o = options
    check_beam_options(o)
    A, Iy, Iz, J = o.section.properties
    m = beam_material(o)
    L = o.length
    forms = eigenforms(o)
    xsi = (0.0, 1.0, *o.frames)
    x, w = gauss_line(L, xsi, max(f.curvature_wave for f in forms))
    X, U, D = _point_shapes(forms, x, math.sqrt(2 * Iz / A), math.sqrt(2 * Iy / A))
    weights = np.repeat(w, 4) / 4                                   # m, per section point
    Ms = np.diag(m.rho * A * weights)
    nq = len(forms)
    nodes = []
    for i, s in enumerate(xsi):
        phi, psi = _node_shapes(forms, s * L)
        nodes.append((i + 1, (s * L, 0.0, 0.0), phi, psi, f"xsi={s:g}"))
    cases = stiffening_cases(L, m.rho * A, np.repeat(x, 4), [s * L for s in xsi])
    stiff = {k: np.stack([geometric_stiffness(N, weights, D) for N in Ns]) for k, Ns in cases.items()}
    omega = np.array([f.omega for f in forms])
    f_hz = omega / (2 * np.pi)
    zeta = np.broadcast_to(np.asarray(o.damping, float), (nq,))
    labels = tuple(f"{eigen_label(k + 1, f)} {fm.kind} {fm.ordinal}" for k, (f, fm) in enumerate(zip(f_hz, forms)))
    meta = {"source": "sidprep beam (analytical Euler-Bernoulli)", "length_m": L, "bc": o.bc,
            "section": {"profile": o.section.profile, "dims_m": list(o.section.dims),
                        "A_m2": A, "Iy_m4": Iy, "Iz_m4": Iz, "J_m4": J},
            "material": m.as_dict(), "beam_modes": [f"{f.kind}:{f.ordinal}" for f in forms],
            "frames_xsi": list(xsi), "damping": zeta.tolist()}
    sid = sid_invariants(X, Ms, U.reshape(-1, nq), nodes, labels=labels, frequencies_hz=f_hz,
                         mode_kinds=("eigen",) * nq, Ke=np.diag(omega ** 2),
                         De=np.diag(2 * zeta * omega), stiffening=stiff, metadata=meta)
    depth_y, depth_z = math.sqrt(12 * Iz / A), math.sqrt(12 * Iy / A)
    return replace(sid, paths={"axis": axis_path(forms, L)}, surface=beam_surface(forms, L, depth_y, depth_z),
                   stress=beam_stress(forms, L, m.E, o.section))


def surface_stations(forms, L: float) -> np.ndarray:
    """Stations x (m) of the animation surface and the stress points: SURFACE_STATIONS_PER_WAVE per
    half-wave of the shortest form, at least SURFACE_MIN_STATIONS."""
    half_waves = max(f.curvature_wave for f in forms) * L / math.pi
    return np.linspace(0.0, L, max(SURFACE_MIN_STATIONS, int(math.ceil(SURFACE_STATIONS_PER_WAVE * half_waves)) + 1))


def section_stress_points(section: Section) -> np.ndarray:
    """Points (y, z) of the section's outline about its centroid, m; (m, 2).

    rectangle, rectangular_tube, I: the four corners (+-b/2, +-h/2), the extreme fibres of any
    bending; circle, tube: eight points on the outer circle every 45 deg (the largest bending stress
    is then missed by at most 1 - cos 22.5 deg = 7.6 %); general, T, U: the corners of the
    radius-of-gyration box +-sqrt(3 Iz / A), +-sqrt(3 Iy / A) (equal to the extreme fibres of a
    rectangle; not the outline of these sections).
    """
    A, Iy, Iz, _ = section.properties
    d = section.dims
    if section.profile in ("circle", "tube"):
        a = np.arange(8) * np.pi / 4
        return 0.5 * d[0] * np.stack([np.cos(a), np.sin(a)], axis=1)
    cy, cz = (0.5 * d[0], 0.5 * d[1]) if section.profile in ("rectangle", "rectangular_tube", "I") else \
        (math.sqrt(3 * Iz / A), math.sqrt(3 * Iy / A))
    return np.array([[-cy, -cz], [cy, -cz], [cy, cz], [-cy, cz]])


def beam_stress(forms, L: float, E: float, section: Section) -> StressModes:
    """Modal stresses of the Beam at its section's outline (section_stress_points) at the surface
    stations: the Euler-Bernoulli normal stress sigma_xx = E (u' - y v'' - z w'') per unit q_k
    (u axial, v along y, w along z); the shear stresses of torsion and transverse force are not
    included (zero)."""
    xs = surface_stations(forms, L)
    yz = section_stress_points(section)
    x = np.repeat(xs, len(yz))
    y, z = np.tile(yz[:, 0], len(xs)), np.tile(yz[:, 1], len(xs))
    modes = np.zeros((len(x), 6, len(forms)))
    xx = STRESS_ORDER.index("xx")
    for k, f in enumerate(forms):
        if f.kind == "axial":
            modes[:, xx, k] = E * f.slope(x)
        elif f.kind == "xy":
            modes[:, xx, k] = -E * y * f.curvature(x)
        elif f.kind == "xz":
            modes[:, xx, k] = -E * z * f.curvature(x)
    return StressModes(np.arange(1, len(x) + 1, dtype=np.int64), np.stack([x, y, z], axis=1), modes, "surface",
                       "Euler-Bernoulli sigma_xx = E (u' - y v'' - z w'') at the section outline; no shear")


def beam_surface(forms, L: float, depth_y: float, depth_z: float) -> SurfaceModes:
    """A box along the axis for the animation, the rectangle with the section's radii of gyration
    (depths sqrt(12 I / A)); its corners move with the forms as the section's rigid motion,
    u = phi(x) + psi(x) x (0, y, z)."""
    xs = surface_stations(forms, L)
    corners = 0.5 * np.array([[-depth_y, -depth_z], [depth_y, -depth_z], [depth_y, depth_z], [-depth_y, depth_z]])
    points = np.array([[x, y, z] for x in xs for y, z in corners])
    shapes = np.zeros((len(points), 3, len(forms)))
    for i, x in enumerate(xs):
        phi, psi = _node_shapes(forms, x)
        for c, (y, z) in enumerate(corners):
            shapes[4 * i + c] = phi + np.cross(psi.T, np.array([0.0, y, z])).T
    tri = []
    for i in range(len(xs) - 1):  # four sides of each segment, outward normals
        for c in range(4):
            a, b, a2, b2 = 4 * i + c, 4 * i + (c + 1) % 4, 4 * (i + 1) + c, 4 * (i + 1) + (c + 1) % 4
            tri += [(a, b, b2), (a, b2, a2)]
    last = 4 * (len(xs) - 1)
    tri += [(0, 2, 1), (0, 3, 2), (last, last + 1, last + 2), (last, last + 2, last + 3)]
    return SurfaceModes(points, np.array(tri, dtype=np.int64), shapes, np.arange(1, len(points) + 1))


def axis_path(forms, L: float) -> BodyPath:
    """The Beam's axis x = 0 .. L as a BodyPath: the exact eigenforms at PATH_POINTS_PER_WAVE
    points per half-wave of the shortest form (at least PATH_MIN_POINTS)."""
    half_waves = max(f.curvature_wave for f in forms) * L / math.pi
    s = np.linspace(0.0, L, max(PATH_MIN_POINTS, int(math.ceil(PATH_POINTS_PER_WAVE * half_waves)) + 1))
    shapes = [_node_shapes(forms, x) for x in s]
    points = np.stack([s, np.zeros_like(s), np.zeros_like(s)], axis=1)
    return BodyPath(s, points, np.array([p for p, _ in shapes]), np.array([q for _, q in shapes]))


# ------------------------------------------------------------------------------------------------
# Text specs (CLI and scene tables)
# ------------------------------------------------------------------------------------------------

def parse_modes(spec: str) -> tuple[tuple[str, int], ...]:
    """'xz:1-3,5,xy:1,torsion:1' -> (("xz", 1), ("xz", 2), ("xz", 3), ("xz", 5), ("xy", 1), ...)."""
    out, kind = [], None
    for tok in (t.strip() for t in str(spec).split(",") if t.strip()):
        if ":" in tok:
            kind, tok = (s.strip() for s in tok.split(":", 1))
        mt = re.fullmatch(r"(\d+)(?:-(\d+))?", tok)
        if kind not in KINDS or not mt:
            raise InputError(f"modes {spec!r}: expected e.g. xz:1-7,xy:1-2,torsion:1,axial:1 "
                             f"(kinds {', '.join(KINDS)})")
        a, b = int(mt[1]), int(mt[2] or mt[1])
        if not 1 <= a <= b <= MAX_MODE_NUMBER:
            raise InputError(f"modes {spec!r}: {kind}:{tok} is not a range 1 <= first <= last <= "
                             f"{MAX_MODE_NUMBER}; ask for the eigenforms of interest, e.g. {kind}:1-7")
        out += [(kind, n) for n in range(a, b + 1)]
    return tuple(out)


def parse_section(spec: str) -> Section:
    """'rectangle:0.02,0.01' / 'general:A,Iy,Iz,J' -> Section."""
    name, _, rest = str(spec).partition(":")
    try:
        dims = tuple(float(v) for v in rest.split(",") if v.strip())
    except ValueError:
        raise InputError(f"section {spec!r}: dimensions must be numbers, e.g. rectangle:0.02,0.01") from None
    sec = Section(name.strip(), dims)
    sec.properties
    return sec


def _floats(v) -> tuple[float, ...]:
    if isinstance(v, (int, float)):
        return (float(v),)
    if isinstance(v, str):
        return tuple(float(s) for s in v.split(",") if s.strip())
    return tuple(float(s) for s in v)


#: the keys of a scene's beam table that describe the beam (a scene passes the rest, e.g.
#: position, rotation, q0, to its body)
BEAM_TABLE_KEYS = tuple(BeamOptions.__dataclass_fields__)


def beam_options_from_table(table: dict, source: str) -> BeamOptions:
    """BeamOptions from a scene/TOML table {length, section, material | E nu rho, bc, modes,
    damping, frames} (BEAM_TABLE_KEYS, plus ``type``/``name``, which are ignored); section/modes
    as strings (see parse_section/parse_modes) or section = {profile = "...", dims = [...]}.
    Errors are one line starting with ``source``."""
    allowed = set(BEAM_TABLE_KEYS) | {"type", "name"}
    extra = set(table) - allowed
    try:
        if extra:
            raise InputError(f"unknown key(s) {', '.join(sorted(extra))}; allowed: {', '.join(sorted(allowed))}")
        kw = {}
        if "length" in table:
            kw["length"] = float(table["length"])
        if "section" in table:
            s = table["section"]
            kw["section"] = (Section(str(s["profile"]), _floats(s["dims"])) if isinstance(s, dict)
                             else parse_section(s))
        for k in ("E", "nu", "rho"):
            if k in table:
                kw[k] = float(table[k])
        if "material" in table or any(k in table for k in ("E", "nu", "rho")):
            kw["material"] = table.get("material")
        if "bc" in table:
            kw["bc"] = str(table["bc"])
        if "modes" in table:
            kw["modes"] = parse_modes(table["modes"])
        if "damping" in table:
            kw["damping"] = _floats(table["damping"])
        if "frames" in table:
            kw["frames"] = _floats(table["frames"])
        o = replace(BeamOptions(), **kw)
        check_beam_options(o)
        return o
    except (InputError, ValueError, TypeError, KeyError) as exc:
        raise InputError(f"{source}: {exc}") from None
