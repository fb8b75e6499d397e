"""Interconnected planar flexible beams in absolute nodal coordinates (Kisu Lee, seed 002): a
second formulation beside the floating frame, with its own model, kernels and scene tables."""

from sidprep.solver.absolute_nodal.beams import *  # noqa: F401,F403 - moved; split into modules next
