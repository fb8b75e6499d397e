"""The textbook 3D Euler-Bernoulli frame element (Przemieniecki, Theory of Matrix Structural Analysis,
1968, sections 5.6 and 11.4: stiffness and consistent mass), assembled independently of sidprep, and
the models it gives as Nastran decks (GRID, CBAR) with their K and M in a DMIG punch: what a Nastran
export of a CBAR model holds (6 DOFs per grid)."""

from pathlib import Path

import numpy as np
import scipy.sparse as sp
from hex_decks import write_punch

from sidprep.fe.matrices.record import FEMatrices

#: steel (Pa, -, kg/m^3)
E, NU, RHO = 210e9, 0.3, 7850.0


def bending_blocks(EI: float, m: float, L: float) -> tuple[np.ndarray, np.ndarray]:
    """(K, M) of the cubic Hermite beam in one plane, DOFs (v1, theta1, v2, theta2), theta = dv/dx;
    ``m`` the mass per length."""
    K = EI / L ** 3 * np.array([[12, 6 * L, -12, 6 * L], [6 * L, 4 * L ** 2, -6 * L, 2 * L ** 2],
                                [-12, -6 * L, 12, -6 * L], [6 * L, 2 * L ** 2, -6 * L, 4 * L ** 2]])
    M = m * L / 420 * np.array([[156, 22 * L, 54, -13 * L], [22 * L, 4 * L ** 2, 13 * L, -3 * L ** 2],
                                [54, 13 * L, 156, -22 * L], [-13 * L, -3 * L ** 2, -22 * L, 4 * L ** 2]])
    return K, M


def frame_element(L: float, A: float, Iy: float, Iz: float, J: float, Ip: float):
    """(K, M) 12 x 12 of the frame element along its local x axis, DOFs (u, v, w, rx, ry, rz) per
    node; steel; Ip the polar moment of the section (torsional mass rho Ip)."""
    G = E / (2 * (1 + NU))
    K, M = np.zeros((12, 12)), np.zeros((12, 12))
    bar = np.array([[1.0, -1.0], [-1.0, 1.0]])
    linear_pair = np.array([[2.0, 1.0], [1.0, 2.0]]) / 6
    for d, stiff, mass in ((0, E * A / L, RHO * A * L), (3, G * J / L, RHO * Ip * L)):
        idx = [d, 6 + d]
        K[np.ix_(idx, idx)] += stiff * bar
        M[np.ix_(idx, idx)] += mass * linear_pair
    for (v, r), EI, sign in (((1, 5), E * Iz, 1.0), ((2, 4), E * Iy, -1.0)):   # theta_y = -dw/dx
        Kb, Mb = bending_blocks(EI, RHO * A, L)
        D = np.diag([1.0, sign, 1.0, sign])
        idx = [v, r, 6 + v, 6 + r]
        K[np.ix_(idx, idx)] += D @ Kb @ D
        M[np.ix_(idx, idx)] += D @ Mb @ D
    return K, M


def axes(a: np.ndarray, b: np.ndarray, up: np.ndarray) -> np.ndarray:
    """3 x 3 rows: the element's local x (a -> b), y (in the plane of x and ``up``), z."""
    x = (b - a) / np.linalg.norm(b - a)
    z = np.cross(x, up)
    z /= np.linalg.norm(z)
    return np.vstack([x, np.cross(z, x), z])


def lumped_mass(L: float, A: float, Ip: float) -> np.ndarray:
    """12 x 12 lumped mass of the element: half its mass on each node's translations and half its
    torsional inertia rho Ip L on each node's rotation about the axis (no bending rotary inertia)."""
    return np.diag(np.tile([RHO * A * L / 2] * 3 + [RHO * Ip * L / 2, 0.0, 0.0], 2))


def frame_model(points: np.ndarray, elements: np.ndarray, section: dict, up=(0.0, 0.0, 1.0), lumped=True):
    """Global (6n, 6n) K and M (DOF 6 i + d) of frame elements (k, 2) on ``points`` (n, 3);
    ``section``: A, Iy, Iz, J, Ip (m^2, m^4); local y in the plane of the axis and ``up``; the lumped
    mass (:func:`lumped_mass`) or the consistent one."""
    n = len(points)
    K, M = sp.lil_matrix((6 * n, 6 * n)), sp.lil_matrix((6 * n, 6 * n))
    for a, b in elements:
        R = axes(points[a], points[b], np.asarray(up, float))
        T = np.kron(np.eye(4), R)
        L = float(np.linalg.norm(points[b] - points[a]))
        Ke, Me = frame_element(L, **section)
        Me = lumped_mass(L, section["A"], section["Ip"]) if lumped else Me
        idx = np.r_[6 * a + np.arange(6), 6 * b + np.arange(6)]
        K[np.ix_(idx, idx)] += T.T @ Ke @ T
        M[np.ix_(idx, idx)] += T.T @ Me @ T
    return K.tocsr(), M.tocsr()


def rectangle(b: float, h: float) -> dict:
    """Section of a b (local y) x h (local z) rectangle: A, Iy, Iz, J (Saint-Venant, Roark's series
    for a rectangle with b >= h), Ip."""
    w, t = max(b, h), min(b, h)
    J = w * t ** 3 * (1 / 3 - 0.21 * t / w * (1 - t ** 4 / (12 * w ** 4)))
    return {"A": b * h, "Iy": b * h ** 3 / 12, "Iz": h * b ** 3 / 12, "J": J, "Ip": b * h * (b * b + h * h) / 12}


def write_beam_export(folder: Path, name: str, points, elements, section, ids=None, cards=(), lumped=True):
    """``name``.bdf (GRID, CBAR, PBAR, MAT1 and ``cards``) and ``name``.pch (KAAX, MAAX of
    :func:`frame_model`, 6 DOFs per grid); returns the two paths."""
    ids = np.arange(1, len(points) + 1) if ids is None else np.asarray(ids)
    K, M = frame_model(points, elements, section, lumped=lumped)
    dofs = np.column_stack([np.repeat(ids, 6), np.tile(np.arange(1, 7), len(ids))])
    write_punch(folder / f"{name}.pch", FEMatrices(K, M, dofs, "", ""))
    s = section
    lines = ["SOL 103", "CEND", "BEGIN BULK", f"MAT1,1,{E:.6e},,{NU},{RHO}",
             f"PBAR,1,1,{s['A']:.9e},{s['Iz']:.9e},{s['Iy']:.9e},{s['J']:.9e}"]
    lines += [f"GRID,{i},,{x:.12e},{y:.12e},{z:.12e}" for i, (x, y, z) in zip(ids, points)]
    lines += [f"CBAR,{k + 1},1,{ids[a]},{ids[b]},0.,0.,1." for k, (a, b) in enumerate(elements)]
    (folder / f"{name}.bdf").write_text("\n".join(lines + list(cards) + ["ENDDATA"]) + "\n")
    return folder / f"{name}.bdf", folder / f"{name}.pch"
