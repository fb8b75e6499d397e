"""sidprep: tetrahedral FE models to reduced flexible bodies (SID, Wallrapp 1994).

Data flows one way: mesh -> model -> reduction -> SID -> files.  Importing this package
is cheap; the FE modules (mesh, assemble, linalg, reduce, ...) are imported on use.
`sidprep.sid` and `sidprep.io` depend on numpy and h5py only, so the solver can read SID
files without pulling in the FE side.
"""

__version__ = "0.1.0"
