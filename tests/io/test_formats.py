"""Every meshio format that works here, round-tripped through ``save``/``load``; the list
of what works is measured (:mod:`warpmesh.io.formats`), and checked not to be empty of
the formats solvers read."""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.io.files import FILE_FORMATS, file_formats
from warpmesh.io.formats import PROBE_CELLS, format_support, meshio_extensions


def _mesh_of(cell_type: str) -> wm.Mesh:
    """Two cells of one type side by side (refs 3 and 5), with a point array the generic
    formats drop."""
    from warpmesh.cells.reference import reference_cell

    base = {"triangle6": ("triangle", ((0, 1), (1, 2), (2, 0))),
            "tetra10": ("tetra", ((0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)))}
    linear, mids = base.get(cell_type, (cell_type, ()))
    p = np.asarray(reference_cell(linear).vertices, dtype=np.float64)
    p = np.column_stack([p, np.zeros((len(p), 3 - p.shape[1]))])
    if mids:
        p = np.concatenate([p, [0.5 * (p[a] + p[b]) for a, b in mids]])
    n = len(p)
    pts = np.concatenate([p, p * 0.5 + [3.0, 1.25, -0.5]])  # a second cell, scaled: same orientation
    return wm.Mesh(pts, {cell_type: [list(range(n)), list(range(n, 2 * n))]}, cell_refs={cell_type: [3, 5]},
                   point_data={"temperature": np.linspace(0, 1, 2 * n)})


def _generic():
    """(extension, format, cell type) for every meshio format warpmesh does not curate and
    every cell type it round-trips here."""
    support = format_support()
    out = []
    for ext, name in sorted(meshio_extensions(exclude=tuple(FILE_FORMATS)).items()):
        if name in support:
            out += [(ext, name, c) for c in support[name].cells]
    return out


def test_the_formats_solvers_read_are_there():
    """Not an empty probe: these round-trip a tetrahedral mesh with this project's test
    dependencies (h5py for XDMF and MED, netCDF4 for Exodus)."""
    works = {name for name, s in format_support().items() if "tetra" in s.cells}
    assert {"abaqus", "su2", "xdmf", "med", "exodus", "netgen", "avsucd", "permas", "tetgen"} <= works
    assert {".inp", ".su2", ".xdmf", ".med", ".e", ".vol", ".off"} <= set(file_formats())
    # a mesher's coordinates (17 digits, exponent notation): meshio's Nastran writer asserts
    # 16-character fields, its WKT reader refuses exponents (and hung on a sphere's file)
    assert not format_support()["nastran"].cells and not format_support()["wkt"].cells
    assert ".nas" not in file_formats() and ".wkt" not in file_formats()
    # tetrahedra with their boundary triangles: Abaqus and MED bring both back, Tecplot not
    assert format_support()["abaqus"].mixed and format_support()["med"].mixed
    assert not format_support()["tecplot"].mixed
    assert all(format_support()[name].cells for name in file_formats().values() if name in format_support()
               and name not in FILE_FORMATS.values())


@pytest.mark.parametrize("ext, name, cell_type", _generic())
def test_round_trip(ext, name, cell_type, tmp_path):
    mesh = _mesh_of(cell_type)
    path = tmp_path / f"m{ext}"
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        wm.Mesh.save(mesh, path)
    assert any("temperature" in str(w.message) for w in caught)  # dropped, and said so
    back = wm.load(path)
    assert list(back.cells) == [cell_type]
    np.testing.assert_array_equal(back.cells[cell_type], mesh.cells[cell_type])
    np.testing.assert_allclose(back.points[:mesh.n_points], mesh.points, atol=1e-6)
    if format_support()[name].refs is not None:
        assert back.cell_refs[cell_type].tolist() == [3, 5]
    assert not [f for f in os.listdir(tmp_path) if f.startswith(".")]  # no temporary left


def test_side_files_keep_their_names(tmp_path):
    """XDMF writes its arrays to an .h5 file that the .xdmf names; TetGen a .node and an
    .ele: written in a temporary folder under the final names, then moved out."""
    mesh = _mesh_of("tetra")
    wm.Mesh.save(mesh.replace(point_data={}), tmp_path / "a.xdmf")
    wm.Mesh.save(mesh.replace(point_data={}), tmp_path / "b.node")
    assert sorted(os.listdir(tmp_path)) == ["a.h5", "a.xdmf", "b.ele", "b.node"]
    for name in ("a.xdmf", "b.node", "b.ele"):
        assert wm.load(tmp_path / name).n_cells == 2


def test_a_cell_type_the_format_cannot_hold(tmp_path):
    with pytest.raises(ValueError, match=r"off \(\.off\) files store only \['triangle'\] cells, got \['tetra'\]"):
        wm.Mesh.save(_mesh_of("tetra"), tmp_path / "t.off")
    assert os.listdir(tmp_path) == []


def test_a_format_that_works_for_nothing_says_why(tmp_path):
    broken = [(s.extensions[0], s) for s in format_support().values() if not s.cells]
    if not broken:
        pytest.skip("every meshio format round-trips some cell type with this meshio")
    ext, sup = broken[0]
    with pytest.raises(ValueError, match="does not round-trip any mesh on this installation"):
        wm.Mesh.save(_mesh_of("triangle"), tmp_path / f"t{ext}")


def test_unknown_extension_lists_what_works():
    with pytest.raises(ValueError, match=r"unknown mesh file extension '\.xyz'.*'\.inp'"):
        wm.load("mesh.xyz")


def test_the_probe_tried_every_cell_type():
    """A format that keeps all of them keeps the second-order ones too (the probe builds
    triangle6/tetra10, not only linear cells)."""
    assert set(PROBE_CELLS) <= set(format_support()["xdmf"].cells)


def test_legacy_vtk_with_64_bit_ids():
    """pyvista's own hexbeam.vtk ('vtktypeint64' offsets), which meshio cannot read."""
    examples = pytest.importorskip("pyvista.examples")
    m = wm.load(examples.hexbeamfile)
    assert list(m.cells) == ["hexahedron"] and m.n_cells == 40
    assert np.all(wm.Mesh(m.points, {"hexahedron": m.cells["hexahedron"]}).stats()["volume"] > 0)


def test_the_first_probe_says_why_it_waits(tmp_path):
    """On a new installation the probe takes seconds: one line on stderr says so, once."""
    import subprocess
    import sys

    env = {k: v for k, v in __import__("os").environ.items() if k != "WARPMESH_CACHE_DIR"}
    env["XDG_CACHE_HOME"] = str(tmp_path)  # the rule's second choice (tests/io/test_cache_dir.py)
    code = "from warpmesh.io.formats import format_support; print(len(format_support()))"
    first = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=600)
    second = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=600)
    assert first.returncode == 0 and second.returncode == 0, first.stderr + second.stderr
    assert first.stderr.count("first run only") == 1 and "first run only" not in second.stderr
    assert first.stdout == second.stdout and int(first.stdout) > 10


def _finishes(call, seconds: float = 60.0):
    """``call()``'s result or exception, or a failed test if it runs longer than ``seconds``
    (run on a daemon thread: a reader that loops forever is left spinning, the test fails)."""
    import threading

    out = {}

    def run():
        try:
            out["value"] = call()
        except BaseException as exc:  # noqa: BLE001 -- handed to the caller
            out["error"] = exc

    worker = threading.Thread(target=run, daemon=True)
    worker.start()
    worker.join(seconds)
    assert not worker.is_alive(), f"still reading after {seconds} s"
    return out


def test_cut_and_empty_files_of_every_format_end_as_a_read_error_or_a_mesh(tmp_path):
    """meshio's Tecplot, Kratos and TetGen readers looped forever on a cut or empty file
    (``readline`` at the end of a file returns "" again and again): warpmesh.io.eof_guard."""
    sphere = wm.mesh_surface(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=8)
    tried = []
    for ext, name in sorted(file_formats().items()):
        if ext in (".pvtu",):
            continue  # its pieces beside it: tests/io/test_pvtu.py
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                whole = sphere.save(tmp_path / f"whole{ext}").read_bytes()
        except ValueError:
            whole = b""  # no triangles in this format (TetGen): the empty file only
        cases = [("empty", b"")] + ([("200 bytes", whole[:200]), ("half", whole[:len(whole) // 2])] if whole else [])
        for label, data in cases:
            cut = tmp_path / f"cut{ext}"
            cut.write_bytes(data)
            got = _finishes(lambda: wm.load(cut))
            assert "value" in got or isinstance(got["error"], wm.ReadError), (ext, label, got)
            tried.append(ext)
    assert {".dat", ".mdpa", ".node"} <= set(tried)


@pytest.mark.parametrize("ext", [".vtk", ".msh"])
def test_binary_files_cut_inside_an_array_are_a_read_error(tmp_path, ext):
    """numpy.fromfile returns fewer values, silently, at the end of a cut file: a .vtk cut in
    its cell data loaded with refs read from the wrong bytes (meshio), or with VTK's warning
    (the VTK fallback). Now a ReadError naming the file, at every cut."""
    shape, bounds = wm.example("sphere")
    tets = wm.mesh_domain(shape, bounds, size=0.4)
    whole = tets.save(tmp_path / f"whole{ext}").read_bytes()
    for keep in (0.5, 0.9, 0.99, 0.999):
        cut = tmp_path / f"cut{ext}"
        cut.write_bytes(whole[:int(len(whole) * keep)])
        with pytest.raises(wm.ReadError, match=f"cut{ext}"):
            wm.load(cut)
    back = wm.load(tmp_path / f"whole{ext}")
    assert np.array_equal(back.cells["tetra"], tets.cells["tetra"])
    assert np.array_equal(back.cell_refs["tetra"], tets.cell_refs["tetra"])


def test_a_meshio_writer_that_fails_is_a_write_error_and_leaves_nothing(tmp_path, monkeypatch):
    """meshio's writers fail with assertions from deep inside (Nastran's on a coordinate
    that does not fit 16 characters, which its probe now leaves out): a WriteError naming the
    format, and no file."""
    import meshio._helpers

    def asserting(path, mesh, **kwargs):
        with open(path, "w") as f:
            f.write("half a file")
        assert len("-0.2999999642372131") <= 16

    monkeypatch.setitem(meshio._helpers._writer_map, "abaqus", asserting)
    sphere = wm.mesh_surface(wm.sphere(1.0), bounds=((-1.2,) * 3, (1.2,) * 3), resolution=8)
    with pytest.raises(wm.WriteError, match=r"meshio's abaqus writer failed on this mesh: AssertionError"):
        sphere.save(tmp_path / "a.inp")
    assert isinstance(wm.WriteError("x"), ValueError) and not list(tmp_path.iterdir())


def test_a_format_that_loses_a_block_refuses_a_mesh_of_several(tmp_path):
    """Tecplot wrote tetrahedra without their boundary triangles (meshio printed "Skipping 2D
    cells") and read them back as hexahedra: its probe says mixed=False, so such a mesh is
    refused, naming the format and the types; one cell type is written."""
    shape, bounds = wm.example("sphere")
    tets = wm.mesh_domain(shape, bounds, size=0.5)
    with pytest.raises(ValueError, match=r"tecplot \(.dat\) files here do not bring a mesh of several cell types"):
        tets.save(tmp_path / "a.dat")
    assert not list(tmp_path.iterdir())
    both = tets.save(tmp_path / "a.inp")  # Abaqus keeps both
    assert sorted(wm.load(both).cells) == ["tetra", "triangle"]


def test_netgen_refuses_a_ref_it_would_write_a_line_for_each_index_below(tmp_path):
    """meshio's Netgen writer writes one line per index up to the largest ref: 2**31 filled
    675 MB in 20 s and never returned."""
    square = wm.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], {"triangle": [[0, 1, 2], [1, 3, 2]]},
                     cell_refs={"triangle": [2**31, 5]})
    with pytest.raises(ValueError, match=r"netgen \(.vol\) files list every index up to the largest cell ref"):
        square.save(tmp_path / "a.vol")
    assert not list(tmp_path.iterdir())
    small = wm.Mesh(square.points, square.cells, cell_refs={"triangle": [2, 5]})
    assert wm.load(small.save(tmp_path / "a.vol")).n_cells == 2


def test_msh_refuses_refs_beyond_32_bits(tmp_path):
    """gmsh's physical tags are 32-bit: a ref of 2**31 came back as -2**31, 2**40 as no refs."""
    pts = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]]
    for big in (2**31, 2**40, -(2**31) - 1):
        m = wm.Mesh(pts, {"triangle": [[0, 1, 2], [1, 3, 2]]}, cell_refs={"triangle": [big, 5]})
        with pytest.raises(ValueError, match=f"32-bit integers, got cell ref {big}"):
            m.save(tmp_path / "a.msh")
        assert not list(tmp_path.iterdir())
    ok = wm.Mesh(pts, {"triangle": [[0, 1, 2], [1, 3, 2]]}, cell_refs={"triangle": [2**31 - 1, -5]})
    assert wm.load(ok.save(tmp_path / "a.msh")).cell_refs["triangle"].tolist() == [2**31 - 1, -5]


def test_xdmf_refuses_second_order_blocks_it_cannot_read_back(tmp_path):
    """meshio's XDMF reader failed (KeyError: 38) on the tetra10 + triangle6 file its writer
    made; the first-order pair round-trips."""
    assert format_support()["xdmf"].mixed and not format_support()["xdmf"].mixed_quadratic
    shape, bounds = wm.example("sphere")
    tets = wm.mesh_domain(shape, bounds, size=0.5)
    with pytest.raises(ValueError, match=r"xdmf \(.xdmf\) files here do not .* \(its probe: tetra10 and triangle6\)"):
        tets.to_order(2).save(tmp_path / "p2.xdmf")
    assert sorted(wm.load(tets.save(tmp_path / "p1.xdmf")).cells) == ["tetra", "triangle"]
    assert sorted(wm.load(tets.to_order(2).save(tmp_path / "p2.inp")).cells) == ["tetra10", "triangle6"]


@pytest.mark.parametrize("ext", [".inp", ".post", ".f3grid", ".su2", ".avs", ".mdpa"])
def test_a_text_format_cut_inside_a_line_is_a_read_error(tmp_path, ext):
    """meshio's readers of these stop at the end of the file without a word: an Abaqus file
    cut at 90 % read as 181 of its 648 tetrahedra. Their writers end with a newline, so a last
    line without one is a cut (a cut right after a newline is not seen)."""
    if ext not in file_formats():
        pytest.skip(f"{ext} does not round-trip on this installation")
    shape, bounds = wm.example("sphere")
    tets = wm.mesh_domain(shape, bounds, size=0.4)
    mesh = wm.Mesh(tets.points, {"tetra": tets.cells["tetra"]})
    whole = mesh.save(tmp_path / f"whole{ext}").read_bytes()
    assert wm.load(tmp_path / f"whole{ext}").n_cells == mesh.n_cells
    cut = tmp_path / f"cut{ext}"
    for keep in (0.3, 0.6, 0.9, 0.99):
        data = whole[:int(len(whole) * keep)]
        if data.endswith(b"\n"):
            data = data[:-1]
        cut.write_bytes(data)
        with pytest.raises(wm.ReadError, match="its last line has no newline"):
            wm.load(cut)
