"""Floating-frame-of-reference (FFR) multibody integrator that consumes SID files.

Never imports sidprep's FE side (mesh, assemble, linalg, reduce, ...): its only inputs from
there are SID files, read through ``sidprep.sid`` and ``sidprep.io`` (numpy/h5py only).
"""
