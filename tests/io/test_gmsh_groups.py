"""Solver files per label and interface (issue 23 part 6): .msh with one named physical group
per label, per interface and per region, read back by gmsh's own reader and by meshio;
.vtu keeps both label arrays; Medit .mesh keeps the refs."""

from __future__ import annotations

import itertools
import warnings

import gmsh
import meshio
import numpy as np
import pytest
import pyvista as pv

import warpmesh as wm
from warpmesh.io.gmsh_groups import LABEL_ABOVE, physical_groups, uses_groups


@pytest.fixture(scope="module")
def three_labels() -> wm.Mesh:
    """Labels 1, 2, 5 in a background 0: two slabs side by side and one on top (junctions)."""
    vol = np.zeros((12, 12, 12), dtype=np.uint8)
    vol[2:10, 2:6, 2:6] = 1
    vol[2:10, 6:10, 2:6] = 2
    vol[2:10, 2:10, 6:10] = 5
    return wm.mesh_surface(vol, labels="all", interfaces="shared")


def _gmsh_groups(path) -> dict:
    """{name: (dim, [element node tuples (0-based)], [element tags])} read by gmsh itself."""
    gmsh.initialize(["-v", "0"])
    try:
        gmsh.open(str(path))
        out = {}
        for dim, tag in gmsh.model.getPhysicalGroups():
            name = gmsh.model.getPhysicalName(dim, tag)
            cells, numbers = [], []
            for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
                types, tags, nodes = gmsh.model.mesh.getElements(dim, ent)
                for t, et, nt in zip(types, tags, nodes):
                    k = gmsh.model.mesh.getElementProperties(t)[3]
                    cells += [tuple(int(v) - 1 for v in row) for row in np.asarray(nt).reshape(-1, k)]
                    numbers += [int(v) for v in et]
            out[name] = (dim, cells, numbers)
        return out
    finally:
        gmsh.finalize()


def _edges_closed(tris) -> bool:
    e = np.sort(np.array([[a, b] for t in tris for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return bool(np.all(counts == 2))


def test_label_above_is_the_surface_stage_name():
    from warpmesh.surface.multilabel import LABEL_ABOVE as surface_name

    assert LABEL_ABOVE == surface_name


def test_multi_label_surface_msh_has_a_group_per_label_and_per_interface(three_labels, tmp_path):
    m = three_labels
    lo = m.cell_refs["triangle"]
    hi = m.cell_data[LABEL_ABOVE]["triangle"]
    pairs = sorted({(int(a), int(b)) for a, b in zip(lo, hi)})
    assert (1, 2) in pairs and (2, 5) in pairs and (0, 5) in pairs  # a real junction case
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # refs and label_above are all the surface has: nothing dropped
        path = m.save(tmp_path / "labels.msh")
    groups = _gmsh_groups(path)
    labels = sorted({*lo.tolist(), *hi.tolist()})
    assert set(groups) == {f"interface_{a}_{b}" for a, b in pairs} | {f"label_{v}" for v in labels}
    tris = [tuple(t) for t in m.triangles.tolist()]
    for a, b in pairs:
        dim, cells, numbers = groups[f"interface_{a}_{b}"]
        want = [tris[i] for i in np.flatnonzero((lo == a) & (hi == b))]
        assert dim == 2 and sorted(cells) == sorted(want)  # the same triangles, same winding
        assert sorted(numbers) == [i + 1 for i in np.flatnonzero((lo == a) & (hi == b))]  # tags = positions
    for v in labels:
        dim, cells, _ = groups[f"label_{v}"]
        assert dim == 2 and len(cells) == int(np.sum((lo == v) | (hi == v)))
        assert _edges_closed(cells)  # each label's boundary is closed
    # meshio reads the groups as cell sets with their dimensions
    mm = meshio.read(path)
    assert {k: int(v[1]) for k, v in mm.field_data.items()} == {n: 2 for n in groups}
    assert sum(len(c.data) for c in mm.cells) == len(tris)
    # and warpmesh reads back the two labels (cells grouped by interface)
    back = wm.load(path)
    np.testing.assert_array_equal(back.points, m.points)
    got = sorted(zip(map(tuple, back.triangles.tolist()), back.cell_refs["triangle"].tolist(),
                     back.cell_data[LABEL_ABOVE]["triangle"].tolist()))
    assert got == sorted(zip(tris, lo.tolist(), hi.tolist()))


def test_interface_refs_mesh_gets_the_same_groups(three_labels, tmp_path):
    from warpmesh.surface.multilabel import interface_refs

    plain = [(g.dim, g.name, len(g.entities)) for g in physical_groups(three_labels)]
    one_ref = interface_refs(three_labels)
    assert [(g.dim, g.name, len(g.entities)) for g in physical_groups(one_ref)] == plain
    a = _gmsh_groups(three_labels.save(tmp_path / "a.msh"))
    with pytest.warns(UserWarning, match="label_below"):  # its copy of the lower label is not stored
        b = _gmsh_groups(one_ref.save(tmp_path / "b.msh"))
    assert {k: sorted(v[1]) for k, v in a.items()} == {k: sorted(v[1]) for k, v in b.items()}


def _kuhn_cube(origin) -> np.ndarray:
    """The 8 corners of a unit cube at ``origin`` and its 6 Kuhn tetrahedra (positive volume)."""
    corners = np.array(list(itertools.product([0, 1], repeat=3)), float) + origin
    index = {tuple(c.astype(int) - np.asarray(origin, int)): i for i, c in enumerate(corners)}
    tets = []
    for perm in itertools.permutations(range(3)):
        p = [0, 0, 0]
        path = [index[tuple(p)]]
        for axis in perm:
            p[axis] = 1
            path.append(index[tuple(p)])
        tets.append(path)
    tets = np.array(tets)
    vol = np.einsum("ij,ij->i", np.cross(corners[tets[:, 1]] - corners[tets[:, 0]], corners[tets[:, 2]] - corners[tets[:, 0]]),
                    corners[tets[:, 3]] - corners[tets[:, 0]])
    tets[vol < 0] = tets[vol < 0][:, [0, 2, 1, 3]]
    return corners, tets


def _two_regions(variant: str) -> wm.Mesh:
    """Two unit cubes stacked in z, 6 tets each, regions 1 (bottom) and 2 (top); the boundary
    and interface triangles with their label pairs, as label_above or as info["interfaces"]."""
    c0, t0 = _kuhn_cube((0, 0, 0))
    c1, t1 = _kuhn_cube((0, 0, 1))
    pts, inv = np.unique(np.concatenate([c0, c1]), axis=0, return_inverse=True)
    tets = np.concatenate([inv[t0], inv[t1 + 8]])
    region = np.repeat([1, 2], 6)
    faces = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 3, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 1]]])
    owner = np.tile(region, 4)
    key = np.sort(faces, axis=1)
    uniq, first, inverse, counts = np.unique(key, axis=0, return_index=True, return_inverse=True, return_counts=True)
    labels = [sorted({0, *owner[inverse.ravel() == k].tolist()} if counts[k] == 1 else owner[inverse.ravel() == k].tolist())
              for k in range(len(uniq))]
    keep = [k for k, lab in enumerate(labels) if lab[0] != lab[1]]  # boundary and the interface
    tris = faces[first[keep]]
    lo = np.array([labels[k][0] for k in keep])
    hi = np.array([labels[k][1] for k in keep])
    if variant == "label_above":
        return wm.Mesh(pts, {"tetra": tets, "triangle": tris}, cell_refs={"tetra": region, "triangle": lo},
                       cell_data={LABEL_ABOVE: {"tetra": region, "triangle": hi}}, info={"labels": [1, 2]})
    table = {1: (0, 1), 2: (0, 2), 3: (1, 2)}
    ref = np.array([{v: k for k, v in table.items()}[(a, b)] for a, b in zip(lo, hi)])
    return wm.Mesh(pts, {"tetra": tets, "triangle": tris}, cell_refs={"tetra": region, "triangle": ref},
                   info={"interfaces": table})


@pytest.mark.parametrize("variant", ["label_above", "interfaces"])
def test_two_region_tets_get_volume_groups_and_interface_surfaces(tmp_path, variant):
    m = _two_regions(variant)
    assert uses_groups(m)
    assert m.stats()["volume"] == pytest.approx(2.0)
    path = m.save(tmp_path / "regions.msh")
    groups = _gmsh_groups(path)
    volume = "label" if variant == "label_above" else "region"
    assert {k: (v[0], len(v[1])) for k, v in groups.items()} == {
        f"{volume}_1": (3, 6), f"{volume}_2": (3, 6),
        "interface_0_1": (2, 10), "interface_0_2": (2, 10), "interface_1_2": (2, 2),
    }
    tets = [tuple(t) for t in m.cells["tetra"].tolist()]
    assert sorted(groups[f"{volume}_1"][1]) == sorted(tets[:6]) and sorted(groups[f"{volume}_2"][1]) == sorted(tets[6:])
    z = m.points[:, 2]
    assert all(np.all(z[list(t)] == 1.0) for t in groups["interface_1_2"][1])  # the interface lies at z = 1
    # gmsh computes the region volumes from its own elements
    gmsh.initialize(["-v", "0"])
    try:
        gmsh.open(str(path))
        for dim, tag in gmsh.model.getPhysicalGroups(3):
            ents = gmsh.model.getEntitiesForPhysicalGroup(dim, tag)
            elems = [e for ent in ents for e in gmsh.model.mesh.getElements(3, ent)[1][0]]
            vols = [gmsh.model.mesh.getElementQualities([e], "volume")[0] for e in elems]
            assert len(elems) == 6 and np.all(np.asarray(vols) > 0)
    finally:
        gmsh.finalize()
    mm = meshio.read(path)
    assert {k: int(v[1]) for k, v in mm.field_data.items()} == {k: v[0] for k, v in groups.items()}
    back = wm.load(path)
    assert back.stats()["volume"] == pytest.approx(2.0)
    got = sorted(zip(map(tuple, back.cells["tetra"].tolist()), back.cell_refs["tetra"].tolist()))
    assert got == sorted(zip(tets, m.cell_refs["tetra"].tolist()))
    pair = {1: (0, 1), 2: (0, 2), 3: (1, 2)}
    want = sorted((tuple(t), *((int(r), int(a)) if variant == "label_above" else pair[int(r)]))
                  for t, r, a in zip(m.cells["triangle"].tolist(), m.cell_refs["triangle"],
                                     m.cell_data.get(LABEL_ABOVE, {"triangle": m.cell_refs["triangle"]})["triangle"]))
    got = sorted(zip(map(tuple, back.cells["triangle"].tolist()), back.cell_refs["triangle"].tolist(),
                     back.cell_data[LABEL_ABOVE]["triangle"].tolist()))
    assert got == want


def test_label_zero_as_a_region_gets_a_positive_tag(tmp_path):
    m = _two_regions("label_above")
    shifted = m.replace(cell_refs={t: r - 1 for t, r in m.cell_refs.items()},
                        cell_data={LABEL_ABOVE: {t: v - 1 for t, v in m.cell_data[LABEL_ABOVE].items()}})
    groups = physical_groups(shifted)
    assert {g.name for g in groups} >= {"label_0", "label_1", "interface_-1_0", "interface_0_1"}
    assert all(g.tag >= 1 for g in groups)
    back = wm.load(shifted.save(tmp_path / "z.msh"))
    assert sorted(set(back.cell_refs["tetra"].tolist())) == [0, 1]


def test_regions_with_plain_boundary_refs_are_named_groups_in_gmsh_22(tmp_path):
    """Tets with a region each and boundary triangles with plain refs: one physical group per
    ref and dimension (gmsh 2.2 keeps point data too), named."""
    m = _two_regions("interfaces")
    plain = wm.Mesh(m.points, dict(m.cells), cell_refs={"tetra": m.cell_refs["tetra"], "triangle": m.cell_refs["triangle"] + 10},
                    point_data={"temp": m.points[:, 2]})
    assert not uses_groups(plain)
    path = plain.save(tmp_path / "plain.msh")
    assert path.read_bytes().startswith(b"$MeshFormat\n2.2")
    groups = _gmsh_groups(path)
    assert {k: (v[0], len(v[1])) for k, v in groups.items()} == {
        "region_1": (3, 6), "region_2": (3, 6), "ref_11": (2, 10), "ref_12": (2, 10), "ref_13": (2, 2)}
    back = wm.load(path)
    np.testing.assert_array_equal(back.cell_refs["tetra"], plain.cell_refs["tetra"])
    np.testing.assert_array_equal(back.cell_refs["triangle"], plain.cell_refs["triangle"])
    np.testing.assert_array_equal(back.point_data["temp"], plain.point_data["temp"])


def test_plain_meshes_stay_gmsh_22(tmp_path):
    tm = wm.mesh_surface(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=12)
    assert not uses_groups(tm)
    path = tm.replace(cell_refs={"triangle": np.ones(tm.n_cells, dtype=int)}).save(tmp_path / "s.msh")
    assert path.read_bytes().startswith(b"$MeshFormat\n2.2")


def test_vtu_keeps_both_label_arrays_and_medit_the_refs(three_labels, tmp_path):
    m = three_labels
    path = m.save(tmp_path / "labels.vtu")
    grid = pv.read(path)  # VTK's own reader
    np.testing.assert_array_equal(grid.cell_data["medit:ref"], m.cell_refs["triangle"])
    np.testing.assert_array_equal(grid.cell_data[LABEL_ABOVE], m.cell_data[LABEL_ABOVE]["triangle"])
    back = wm.load(path)
    np.testing.assert_array_equal(back.cell_data[LABEL_ABOVE]["triangle"], m.cell_data[LABEL_ABOVE]["triangle"])
    with pytest.warns(UserWarning, match=LABEL_ABOVE):  # Medit stores one ref per cell
        path = m.save(tmp_path / "labels.mesh")
    np.testing.assert_array_equal(meshio.read(path).cell_data["medit:ref"][0], m.cell_refs["triangle"])
    tets = _two_regions("interfaces")
    back = wm.load(tets.save(tmp_path / "regions.mesh"))
    np.testing.assert_array_equal(back.cell_refs["tetra"], tets.cell_refs["tetra"])
    np.testing.assert_array_equal(back.cell_refs["triangle"], tets.cell_refs["triangle"])


def test_gmsh_fills_each_label_group_with_tetrahedra(three_labels, tmp_path):
    """A solver's use of the file: gmsh meshes the volume inside each label's surface group;
    each volume is the label's voxel volume (boxes: surface nets keep their faces)."""
    path = three_labels.save(tmp_path / "labels.msh")
    gmsh.initialize(["-v", "0"])
    try:
        gmsh.open(str(path))
        names = {gmsh.model.getPhysicalName(d, t): (d, t) for d, t in gmsh.model.getPhysicalGroups()}
        volumes = {}
        for label in (1, 2, 5):
            loop = gmsh.model.geo.addSurfaceLoop(list(gmsh.model.getEntitiesForPhysicalGroup(*names[f"label_{label}"])))
            volumes[label] = gmsh.model.geo.addVolume([loop])
        gmsh.model.geo.synchronize()
        gmsh.model.mesh.generate(3)
        for label, want in ((1, 8 * 4 * 4), (2, 8 * 4 * 4), (5, 8 * 8 * 4)):
            _, tags, _ = gmsh.model.mesh.getElements(3, volumes[label])
            sizes = gmsh.model.mesh.getElementQualities(tags[0], "volume")
            assert np.all(sizes > 0) and sizes.sum() == pytest.approx(want, rel=0.02)
    finally:
        gmsh.finalize()


def test_primitive_refs_are_named_after_their_primitives(tmp_path):
    """refs="primitives" (issue 24 part 4): each primitive's triangles are one named gmsh group."""
    shell = wm.sphere(1.0) - wm.sphere(0.5)
    m = wm.mesh_surface(shell, bounds=((-1.2,) * 3, (1.2,) * 3), resolution=24, refs="primitives")
    assert not uses_groups(m)
    groups = _gmsh_groups(m.save(tmp_path / "shell.msh"))
    refs = m.cell_refs["triangle"]
    assert {k: (v[0], len(v[1])) for k, v in groups.items()} == {
        f"ref_{r}_sphere": (2, int(np.sum(refs == r))) for r in m.info["primitives"]}
    outer = groups[f"ref_{min(m.info['primitives'])}_sphere"][1]
    radius = np.linalg.norm(m.points[np.array(outer)].reshape(-1, 3), axis=1)
    assert np.all(np.abs(radius - 1.0) < 0.05)  # the first primitive is the outer sphere


def test_mesh_domain_regions_go_to_volume_groups(tmp_path):
    """mesh_domain(volume, labels=...) (lattice cleaving): one physical volume per label with
    that label's tetrahedra, one physical surface per interface; gmsh's volumes per group
    equal warpmesh's region volumes."""
    vol = np.zeros((16, 16, 16), dtype=np.int16)
    vol[3:13, 3:13, 3:8] = 2
    vol[3:13, 3:13, 8:13] = 5
    m = wm.mesh_domain(vol, labels="all", size=2.0)
    path = m.save(tmp_path / "regions.msh")
    groups = _gmsh_groups(path)
    tet_refs = m.cell_refs["tetra"]
    lo, hi = m.cell_refs["triangle"], m.cell_data[LABEL_ABOVE]["triangle"]
    pairs = sorted({(int(a), int(b)) for a, b in zip(lo, hi)})
    assert {k: (v[0], len(v[1])) for k, v in groups.items()} == {
        **{f"label_{r}": (3, int(np.sum(tet_refs == r))) for r in (2, 5)},
        **{f"interface_{a}_{b}": (2, int(np.sum((lo == a) & (hi == b)))) for a, b in pairs}}
    assert (2, 5) in pairs
    tets = m.cells["tetra"]
    for r in (2, 5):
        assert sorted(groups[f"label_{r}"][1]) == sorted(map(tuple, tets[tet_refs == r].tolist()))
    gmsh.initialize(["-v", "0"])
    try:
        gmsh.open(str(path))
        for dim, tag in gmsh.model.getPhysicalGroups(3):
            r = int(gmsh.model.getPhysicalName(dim, tag).split("_")[1])
            elems = [e for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, tag)
                     for e in gmsh.model.mesh.getElements(3, ent)[1][0]]
            got = gmsh.model.mesh.getElementQualities(elems, "volume").sum()
            assert got == pytest.approx(m.info["region_volumes"][r]["volume"], rel=1e-9)
    finally:
        gmsh.finalize()
    back = wm.load(path)
    assert sorted(zip(map(tuple, back.cells["tetra"].tolist()), back.cell_refs["tetra"].tolist())) == \
        sorted(zip(map(tuple, tets.tolist()), tet_refs.tolist()))
    # saved again (a load / save round trip, as the CLI's renumber or refine does): the same
    # group names (the regions were renamed region_<r>)
    assert back.info["labels"] == [2, 5]
    again = _gmsh_groups(back.save(tmp_path / "again.msh"))
    assert {k: (v[0], len(v[1])) for k, v in again.items()} == {k: (v[0], len(v[1])) for k, v in groups.items()}


@pytest.mark.parametrize("rows", [1, 5, 64])
def test_msh41_written_in_chunks_is_the_same_file(tmp_path, monkeypatch, rows):
    # nodes and elements are written a chunk of rows at a time (no copy of the file in
    # memory); any chunk size gives the same bytes, which gmsh's reader (meshio) takes
    from warpmesh.io import gmsh_groups

    vol = np.zeros((10, 10, 10), np.int16)
    vol[2:8, 2:8, 2:5], vol[2:8, 2:8, 5:8], vol[4:6, 4:6, 3:7] = 1, 2, 3
    mesh = wm.mesh_domain(vol, size=2.0)
    whole = gmsh_groups.write_msh41(tmp_path / "whole.msh", mesh).read_bytes()
    monkeypatch.setattr(gmsh_groups, "_WRITE_ROWS", rows)
    assert gmsh_groups.write_msh41(tmp_path / "chunks.msh", mesh).read_bytes() == whole
    back = meshio.read(tmp_path / "chunks.msh")
    assert sum(len(c.data) for c in back.cells if c.type == "tetra") == len(mesh.cells["tetra"])
    np.testing.assert_array_equal(back.points, mesh.points)


@pytest.mark.parametrize("seed", range(4))
def test_entity_keys_by_counting_equal_the_sorted_unique_rows(seed):
    from warpmesh._util.arrays import unique_rows
    from warpmesh.io import gmsh_groups as gg

    rng = np.random.default_rng(seed)
    for keys in (rng.integers(0, 30, (5000, 2)), rng.integers(0, 7, (300, 1)), rng.integers(5, 9, (40, 2))):
        uniq, inverse = gg._small_unique_rows(keys)
        ref, _, ref_inverse, _ = unique_rows(keys)
        np.testing.assert_array_equal(uniq, ref)
        np.testing.assert_array_equal(inverse, ref_inverse)
    assert gg._small_unique_rows(np.array([[-1, 2], [3, 4]])) is None  # negative refs: sorted instead
    assert gg._small_unique_rows(np.array([[0, 0], [1 << 12, 1 << 11]])) is None  # range beyond the table


def test_entity_boxes_equal_the_boxes_of_the_runs():
    from warpmesh.io import gmsh_groups as gg

    rng = np.random.default_rng(5)
    pts = rng.normal(size=(200, 3))
    cells = rng.integers(0, 200, (1000, 4))
    firsts = np.array([0, 3, 4, 500, 999])
    lo, hi = gg._run_boxes(pts, cells, firsts)
    for k, (a, b) in enumerate(zip(firsts, [*firsts[1:], len(cells)])):
        corners = pts[cells[a:b].ravel()]
        np.testing.assert_array_equal(lo[k], corners.min(axis=0))
        np.testing.assert_array_equal(hi[k], corners.max(axis=0))


def test_a_region_physical_tag_is_its_label(tmp_path):
    """Solvers select materials by physical tag: the tetrahedra of label 5 carry tag 5 for
    meshio (not the group's rank); label 0 meshed as a region gets a tag above the others."""
    meshio = pytest.importorskip("meshio")
    vol = np.zeros((14, 14, 14), np.uint8)
    vol[2:7, 2:12, 2:12] = 5
    vol[7:12, 2:12, 2:12] = 7
    for labels, want in (("all", {"label_5": 5, "label_7": 7}), ([0, 5, 7], {"label_0": 8, "label_5": 5, "label_7": 7})):
        m = wm.mesh_domain(vol, labels=labels, size=2.0)
        raw = meshio.read(m.save(tmp_path / "r.msh"))
        assert {n: int(t[0]) for n, t in raw.field_data.items() if t[1] == 3} == want
        volume = {}  # the tetrahedra of each tag, as meshio reads them: each label's region volume
        for c, tag in zip(raw.cells, raw.cell_data["gmsh:physical"]):
            if c.type == "tetra":
                p = raw.points[c.data]
                v = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), p[:, 3] - p[:, 0]) / 6
                for t in np.unique(tag).tolist():
                    volume[t] = volume.get(t, 0.0) + v[tag == t].sum()
        for name, t in want.items():
            assert volume[t] == pytest.approx(m.info["region_volumes"][int(name.split("_")[1])]["volume"])
        back = wm.load(tmp_path / "r.msh")
        assert set(back.cell_refs["tetra"].tolist()) == {int(n.split("_")[1]) for n in want}
