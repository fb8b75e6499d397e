"""Mesh import: node order per format, groups by name, the input checks, surface topology."""


import meshio
import numpy as np
import pytest

from sidprep.errors import InputError
from sidprep.fe.mesh import read_mesh
from sidprep.fe.topology import TET10_EDGES, boundary_faces, cell_volumes, connected_parts, surface_node_indices

#: mid-edge nodes of straight edges must sit at the midpoint to this fraction of the box size
#: (formats that print coordinates with 8 significant digits limit it)
MIDPOINT_RTOL = 1e-6
#: closed-form areas / volumes of the unit cube, to round-off
GEOMETRY_RTOL = 1e-12


def _gmsh_cube(path, *, order=2, msh_version=4.1, binary=True, size=0.5):
    """Unit cube meshed by gmsh with straight edges; groups ``x0`` (face x=0), ``solid``."""
    import gmsh

    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
        gmsh.model.occ.synchronize()
        x0 = [t for _, t in gmsh.model.getEntitiesInBoundingBox(-0.1, -0.1, -0.1, 0.1, 1.1, 1.1, 2)]
        gmsh.model.addPhysicalGroup(2, x0, name="x0")
        gmsh.model.addPhysicalGroup(3, [1], name="solid")
        gmsh.option.setNumber("Mesh.MeshSizeMax", size)
        gmsh.option.setNumber("Mesh.ElementOrder", order)
        gmsh.option.setNumber("Mesh.MshFileVersion", msh_version)
        gmsh.option.setNumber("Mesh.Binary", int(binary))
        gmsh.model.mesh.generate(3)
        gmsh.write(str(path))
    finally:
        gmsh.finalize()
    return path


@pytest.fixture(scope="module")
def cube(tmp_path_factory):
    """The tet10 unit cube as read from gmsh 4.1 binary (the canonical reference)."""
    return read_mesh(_gmsh_cube(tmp_path_factory.mktemp("cube") / "cube.msh"))


def _midpoint_error(mesh):
    p, c = mesh.points, mesh.cells
    return max(np.abs(p[c[:, 4 + k]] - (p[c[:, a]] + p[c[:, b]]) / 2).max() for k, (a, b) in enumerate(TET10_EDGES))


@pytest.mark.parametrize("version,binary", [(2.2, False), (2.2, True), (4.1, False), (4.1, True)])
def test_gmsh_msh_tet10_midnodes_and_groups(tmp_path, version, binary):
    mesh = read_mesh(_gmsh_cube(tmp_path / "c.msh", msh_version=version, binary=binary))
    assert mesh.order == 2
    assert _midpoint_error(mesh) < MIDPOINT_RTOL
    assert (cell_volumes(mesh.points, mesh.cells) > 0).all()
    assert np.isclose(cell_volumes(mesh.points, mesh.cells).sum(), 1.0, rtol=GEOMETRY_RTOL)
    x0 = mesh.node_sets["x0"]
    assert np.array_equal(x0, np.flatnonzero(np.abs(mesh.points[:, 0]) < 1e-12))
    assert np.array_equal(mesh.cell_sets["solid"], np.arange(len(mesh.cells)))
    assert mesh.notes == ()


@pytest.mark.parametrize("suffix", [".inp", ".vtu", ".bdf", ".med", ".vtk", ".msh"])
def test_meshio_formats_keep_tet10_node_order(tmp_path, cube, suffix):
    """Written by meshio in each format (its own tet10 permutation) and read back."""
    path = tmp_path / f"cube{suffix}"
    kwargs = {"file_format": "gmsh22", "binary": False} if suffix == ".msh" else {}
    meshio.write_points_cells(path, cube.points, [("tetra10", cube.cells)], **kwargs)
    mesh = read_mesh(path)
    assert mesh.cells.shape == cube.cells.shape
    assert _midpoint_error(mesh) < MIDPOINT_RTOL
    assert np.isclose(cell_volumes(mesh.points, mesh.cells).sum(), 1.0, rtol=MIDPOINT_RTOL)


def test_abaqus_sets_by_name(tmp_path, cube):
    """*NSET -> node set, *ELSET of tets -> cell set, *ELSET of surface elements -> node set;
    the surface elements themselves are dropped."""
    path = tmp_path / "cube.inp"
    x0 = cube.node_sets["x0"]
    half = np.arange(len(cube.cells) // 2)
    faces = boundary_faces(cube)
    on_x0 = faces[np.isin(faces, x0).all(axis=1)]
    meshio.write_points_cells(
        path,
        cube.points,
        [("tetra10", cube.cells), ("triangle", on_x0)],
        point_sets={"X0": x0},
        cell_sets={"HALF": [half, []], "X0_FACES": [[], np.arange(len(on_x0))]},
    )
    mesh = read_mesh(path)
    assert np.array_equal(mesh.node_sets["X0"], x0)
    assert np.array_equal(mesh.cell_sets["HALF"], half)
    corners_on_x0 = np.intersect1d(x0, np.unique(cube.cells[:, :4]))
    assert np.array_equal(mesh.node_sets["X0_FACES"], corners_on_x0)
    assert mesh.cells.shape == cube.cells.shape


def test_wrong_tet10_order_is_detected(tmp_path, cube):
    """gmsh's tet10 order written into a VTK file (last two edge nodes swapped)."""
    path = tmp_path / "swapped.vtu"
    meshio.write_points_cells(path, cube.points, [("tetra10", cube.cells[:, [0, 1, 2, 3, 4, 5, 6, 7, 9, 8]])])
    with pytest.raises(InputError, match="mid-edge nodes on the wrong edges"):
        read_mesh(path)


def test_tet4_and_geo_file(tmp_path):
    mesh = read_mesh(_gmsh_cube(tmp_path / "c.msh", order=1))
    assert mesh.order == 1 and mesh.cells.shape[1] == 4
    geo = tmp_path / "box.geo"
    geo.write_text(
        'SetFactory("OpenCASCADE");\nBox(1) = {0, 0, 0, 2, 1, 1};\n'
        'Physical Surface("bottom") = {5};\nPhysical Volume("body") = {1};\n'
        'Physical Curve("edge") = {1};\nPhysical Point("corner") = {1};\n'
    )
    coarse, fine = read_mesh(geo, size=0.5, order=2), read_mesh(geo, size=0.25, order=1)
    assert coarse.order == 2 and fine.order == 1 and len(fine.cells) > len(coarse.cells)
    assert _midpoint_error(coarse) < MIDPOINT_RTOL
    assert np.isclose(cell_volumes(fine.points, fine.cells).sum(), 2.0, rtol=GEOMETRY_RTOL)
    assert np.allclose(coarse.points[coarse.node_sets["bottom"], 2], 0.0)
    assert len(coarse.cell_sets["body"]) == len(coarse.cells)
    with pytest.raises(InputError, match="--size -1"):
        read_mesh(geo, size=-1)
    assert np.array_equal(coarse.points[coarse.node_sets["corner"]], [[0, 0, 1]])  # OCC point 1
    edge = coarse.points[coarse.node_sets["edge"]]  # OCC box curve 1: x = y = 0, z in [0, 1]
    assert len(edge) == 5 and np.allclose(edge[:, :2], 0) and np.ptp(edge[:, 2]) == 1


def test_boundary_faces_are_outward_and_closed(cube):
    faces = boundary_faces(cube)
    x = cube.points[faces]
    area_vectors = np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]) / 2
    assert np.isclose(np.linalg.norm(area_vectors, axis=1).sum(), 6.0, rtol=GEOMETRY_RTOL)
    assert np.abs(area_vectors.sum(axis=0)).max() < GEOMETRY_RTOL  # closed surface
    enclosed = np.einsum("ij,ij->i", x[:, 0], area_vectors).sum() / 3  # divergence theorem
    assert np.isclose(enclosed, 1.0, rtol=GEOMETRY_RTOL)
    on_box = np.flatnonzero((np.abs(cube.points - 0.5) > 0.5 - 1e-12).any(axis=1))
    assert np.array_equal(surface_node_indices(cube), on_box)
    assert connected_parts(cube)[0] == 1


# --- bad input ------------------------------------------------------------------------------
def _two_tets():
    """Two positively oriented tetrahedra sharing the face (1, 2, 3)."""
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1.0]])
    return p, np.array([[0, 1, 2, 3], [1, 4, 2, 3]])


def _write(path, points, cells, kind="tetra"):
    meshio.write_points_cells(path, points, [(kind, cells)], **(
        {"file_format": "gmsh22", "binary": False} if path.suffix == ".msh" else {}
    ))
    return path


def test_missing_unknown_truncated_garbage(tmp_path):
    with pytest.raises(InputError, match="file not found"):
        read_mesh(tmp_path / "nope.msh")
    (tmp_path / "m.xyz").write_text("1 2 3\n")
    with pytest.raises(InputError, match="unknown mesh file extension"):
        read_mesh(tmp_path / "m.xyz")
    whole = _gmsh_cube(tmp_path / "c.msh").read_bytes()
    for name, data in [("cut.msh", whole[: len(whole) // 2]), ("junk.msh", b"not a mesh\n")]:
        (tmp_path / name).write_bytes(data)
        with pytest.raises(InputError, match=name):
            read_mesh(tmp_path / name)
    whole = _write(tmp_path / "c.vtu", *_two_tets()).read_bytes()
    (tmp_path / "cut.vtu").write_bytes(whole[: len(whole) // 2])
    with pytest.raises(InputError, match="cut.vtu.*could not read"):
        read_mesh(tmp_path / "cut.vtu")


def test_gmsh_is_silent(tmp_path, capfd):
    good = _gmsh_cube(tmp_path / "c.msh")
    capfd.readouterr()
    read_mesh(good)
    (tmp_path / "junk.msh").write_text("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 2")
    with pytest.raises(InputError):
        read_mesh(tmp_path / "junk.msh")
    assert capfd.readouterr() == ("", "")


def test_nan_coordinate(tmp_path):
    p, c = _two_tets()
    p[4, 1] = np.nan
    with pytest.raises(InputError, match="1 nodes have NaN, infinite or larger than 1e\\+12 coordinates.*node 5"):
        read_mesh(_write(tmp_path / "nan.vtu", p, c))


def test_flat_element(tmp_path):
    p, c = _two_tets()
    p[4] = (p[1] + p[2] + p[3]) / 3  # on the shared face: element 2 is flat
    with pytest.raises(InputError, match="1 elements have zero or near-zero volume.*element 2"):
        read_mesh(_write(tmp_path / "flat.msh", p, c))


def test_inverted_elements_are_reordered_and_noted(tmp_path):
    p, c = _two_tets()
    mesh = read_mesh(_write(tmp_path / "inv.msh", p, c[:, [0, 2, 1, 3]]))
    assert (cell_volumes(mesh.points, mesh.cells) > 0).all()
    assert any("2 of 2 elements had negative volume" in n for n in mesh.notes)


def test_tet10_reordering_keeps_midnodes(tmp_path, cube):
    """Every cell written with the other orientation (vertices 1, 2 and their edges swapped)."""
    flipped = cube.cells[:, [0, 2, 1, 3, 6, 5, 4, 7, 9, 8]]
    mesh = read_mesh(_write(tmp_path / "flip.vtu", cube.points, flipped, "tetra10"))
    assert (cell_volumes(mesh.points, mesh.cells) > 0).all()
    assert _midpoint_error(mesh) < MIDPOINT_RTOL
    assert any("negative volume" in n for n in mesh.notes)


def test_tangled_elements(tmp_path):
    """Node 4 pushed through the shared face: element 2 overlaps element 1."""
    p, c = _two_tets()
    p[4] = [0.1, 0.1, 0.1]
    with pytest.raises(InputError, match="overlapping or inverted"):
        read_mesh(_write(tmp_path / "tangled.msh", p, c))


def test_other_volume_elements_and_mixed_orders(tmp_path):
    p, c = _two_tets()
    hexa = np.arange(8)[None]
    path = tmp_path / "hex.vtu"
    meshio.write_points_cells(path, np.vstack([p, np.ones((3, 3))]), [("tetra", c), ("hexahedron", hexa)])
    with pytest.raises(InputError, match="other than tetrahedra \\(hexahedron\\)"):
        read_mesh(path)
    p10 = np.vstack([p, np.zeros((10, 3))])
    meshio.write_points_cells(path, p10, [("tetra", c), ("tetra10", np.arange(5, 15)[None])])
    with pytest.raises(InputError, match="mixes tet4 and tet10"):
        read_mesh(path)


def test_no_tetrahedra(tmp_path):
    p, _ = _two_tets()
    with pytest.raises(InputError, match="contains no tetrahedra"):
        read_mesh(_write(tmp_path / "tri.msh", p, np.array([[0, 1, 2], [1, 2, 3]]), "triangle"))


def test_duplicate_and_unreferenced_nodes(tmp_path):
    p, c = _two_tets()
    # element 2 uses copies of the shared-face nodes; two more nodes are used by no element
    p = np.vstack([p, p[[1, 2, 3]] + 1e-13, [[5, 5, 5], [6, 6, 6]]])
    c = np.array([[0, 1, 2, 3], [5, 4, 6, 7]])
    mesh = read_mesh(_write(tmp_path / "dup.vtu", p, c))  # gmsh drops unused nodes itself
    assert mesh.n_nodes == 5 and connected_parts(mesh)[0] == 1
    assert any("2 nodes not used" in n for n in mesh.notes)
    assert any("3 duplicate nodes" in n for n in mesh.notes)
    assert np.isclose(cell_volumes(mesh.points, mesh.cells).sum(), 0.5)


def test_disconnected_parts(tmp_path):
    p, c = _two_tets()
    mesh = read_mesh(_write(tmp_path / "two.msh", np.vstack([p, p + 3.0]), np.vstack([c, c + 5])))
    n_parts, labels = connected_parts(mesh)
    assert n_parts == 2 and np.array_equal(labels, np.repeat([0, 1], 5))
    assert any("2 disconnected parts; each adds 6 rigid-body modes" in n for n in mesh.notes)


def test_abaqus_numbers_and_sets_from_a_hand_written_deck(tmp_path):
    """File numbers (not 1..n) reach node_ids and the messages; a continued element line."""
    nodes = "\n".join(f"{100 + k}, {x}, {y}, {z}" for k, (x, y, z) in enumerate(_two_tets()[0], 1))
    (tmp_path / "nodes.inp").write_text(f"*NODE\n{nodes}\n106, 9.0, 9.0, 9.0\n")  # 106: unused
    deck = tmp_path / "deck.inp"
    deck.write_text(
        "** two tets, element 9 in the other orientation\n*INCLUDE, INPUT=nodes.inp\n"
        "*ELEMENT, TYPE=C3D4, ELSET=ALL\n7, 101, 102, 103,\n 104\n9, 102, 103, 105, 104\n"
        "*NSET, NSET=TIP\n105, 106\n*ELSET, ELSET=SECOND\n9\n"
    )
    mesh = read_mesh(deck)
    assert any("1 nodes not used by any tetrahedron" in n for n in mesh.notes)
    assert any("node set 'TIP': 1 of its 2 nodes are on no tetrahedron" in n for n in mesh.notes)
    assert np.array_equal(mesh.node_ids, [101, 102, 103, 104, 105])
    assert np.array_equal(mesh.node_sets["TIP"], [4])
    assert np.array_equal(mesh.cell_sets["SECOND"], [1])
    assert any("1 of 2 elements had negative volume (worst: element 9)" in n for n in mesh.notes)


def test_calculix_deck_with_include(tmp_path, validation_dir):
    """The validation deck (written by its own gmsh -> C3D10 converter) *INCLUDEs its mesh."""
    deck = read_mesh(validation_dir / "decks" / "cantilever_bar_h0.02.inp")
    mesh = read_mesh(validation_dir / "meshes" / "bar_h0.02_mesh.inp")
    assert np.array_equal(deck.points, mesh.points) and np.array_equal(deck.cells, mesh.cells)
    assert deck.n_dof == 17058 and _midpoint_error(deck) < MIDPOINT_RTOL
    assert len(deck.node_sets["NX0"]) == 79 and np.allclose(deck.points[deck.node_sets["NX0"], 0], 0)
    (tmp_path / "bad.inp").write_text("*INCLUDE, INPUT=missing.inp\n")
    with pytest.raises(InputError, match="INCLUDE file .*missing.inp not found"):
        read_mesh(tmp_path / "bad.inp")


def test_step_and_brep_are_meshed_in_metres(tmp_path):
    """gmsh writes STEP in millimetres; sidprep reads STEP in metres, BREP as is."""
    import gmsh

    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.occ.addBox(0, 0, 0, 10, 20, 30)
        gmsh.model.occ.synchronize()
        gmsh.write(str(tmp_path / "box.step"))
        gmsh.write(str(tmp_path / "box.brep"))
    finally:
        gmsh.finalize()
    step = read_mesh(tmp_path / "box.step", size=0.01, order=1)
    brep = read_mesh(tmp_path / "box.brep", size=10.0, order=2)
    assert np.allclose(step.points.max(axis=0), [0.01, 0.02, 0.03])
    assert np.isclose(cell_volumes(step.points, step.cells).sum(), 6e-6, rtol=GEOMETRY_RTOL)
    assert brep.order == 2 and np.allclose(brep.points.max(axis=0), [10, 20, 30])
    # --units mm-t-s scales a BREP (no unit in the file) but must not scale the STEP a second time
    assert np.allclose(brep.in_metres(1e-3, "mm-t-s").points.max(axis=0), [0.01, 0.02, 0.03])
    step_mm = step.in_metres(1e-3, "mm-t-s")
    assert np.array_equal(step_mm.points, step.points) and "file's own unit" in step_mm.notes[-1]


def test_caller_gmsh_session_is_left_as_it_was(tmp_path):
    import gmsh

    path = _gmsh_cube(tmp_path / "c.msh")
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("Mesh.ElementOrder", 3)
        gmsh.model.add("mine")
        gmsh.model.occ.addSphere(0, 0, 0, 1)
        gmsh.model.occ.synchronize()
        assert read_mesh(path).order == 2
        assert gmsh.model.getCurrent() == "mine" and gmsh.model.getEntities(3) == [(3, 1)]
        assert gmsh.option.getNumber("Mesh.ElementOrder") == 3
    finally:
        gmsh.finalize()


def test_undefined_node(tmp_path):
    path = tmp_path / "undefined.msh"
    path.write_text(
        "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n3\n1 0 0 0\n2 1 0 0\n3 0 1 0\n$EndNodes\n"
        "$Elements\n1\n1 4 2 0 1 1 2 3 99\n$EndElements\n"
    )
    with pytest.raises(InputError, match="undefined.msh"):
        read_mesh(path)


def test_close_pairs_are_the_search_tree_pairs():
    """The grid search for duplicate nodes finds exactly the pairs scipy's k-d tree finds."""
    from scipy.spatial import cKDTree

    from sidprep.fe.validation import close_pairs

    rng = np.random.default_rng(0)
    p = rng.random((20000, 3)) * [1.0, 0.05, 0.08]
    p = np.vstack([p, p[:300] + rng.normal(scale=3e-10, size=(300, 3)), p[:30] + 0.9e-9, p[:5]])
    tol = 1e-9
    expected = cKDTree(p).query_pairs(tol, output_type="ndarray")
    np.testing.assert_array_equal(close_pairs(p, tol), expected[np.lexsort(expected.T[::-1])])
