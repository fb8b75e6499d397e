"""The gmsh session and tet10 output shared by the bundled-mesh generators (deterministic)."""

import contextlib

import gmsh


@contextlib.contextmanager
def gmsh_model(name: str):
    """A quiet, single-threaded, seeded gmsh session holding one model ``name``."""
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.option.setNumber("Mesh.RandomSeed", 1)
        gmsh.model.add(name)
        yield
    finally:
        gmsh.finalize()


def write_tet10(path, size: float) -> None:
    """Mesh the current model with straight-sided tet10 of edge length ``size``; write .msh 4.1 binary."""
    gmsh.option.setNumber("Mesh.MeshSizeMin", size)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)
    gmsh.option.setNumber("Mesh.ElementOrder", 2)
    gmsh.option.setNumber("Mesh.SecondOrderLinear", 1)
    gmsh.model.mesh.generate(3)
    gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
    gmsh.option.setNumber("Mesh.Binary", 1)
    gmsh.write(str(path))


def read_back(path):
    """The written mesh as sidprep reads it, with a one-line summary printed."""
    from sidprep.fe.mesh import read_mesh

    mesh = read_mesh(path)
    print(f"{path.name}: {mesh.n_nodes} nodes, {len(mesh.cells)} tet10, {mesh.n_dof} DOF")
    return mesh
