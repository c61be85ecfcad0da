"""Image volumes in (issue 23 part 1): ``wm.load_volume`` against each format's own reader,
meshes of rotated and reflected images in world coordinates, images straight into
``mesh_surface`` and the CLI, and one clear error per bad input."""

from __future__ import annotations

import json
import locale
import sys

import numpy as np
import pytest
import pyvista as pv
from pyvista import examples

import warpmesh as wm
from warpmesh.cli.commands import main
from warpmesh.errors import ReadError
from warpmesh.io.images import Volume

nib = pytest.importorskip("nibabel")
sitk = pytest.importorskip("SimpleITK")


def _rotation(axis, angle) -> np.ndarray:
    axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def _vtk_point(img, ijk) -> np.ndarray:
    """VTK's own position of the point (i, j, k) (x fastest)."""
    nx, ny, _ = img.dimensions
    i, j, k = ijk
    return np.asarray(img.GetPoint(i + nx * (j + ny * k)))


# ----------------------------------------------------------------------------- VTK images
def test_frog_vti_reads_back_as_pyvista_reads_it(tmp_path):
    """Point data: the array pyvista reads, reshaped x-fastest, without a copy; VTK's positions."""
    frog = examples.load_frog_tissues()
    path = tmp_path / "frog.vti"
    frog.save(path)
    vol = wm.load_volume(path)
    ref = pv.read(path)
    assert vol.shape == tuple(ref.dimensions) == (500, 470, 136)
    assert np.array_equal(vol.values, ref["MetaImage"].reshape(ref.dimensions, order="F"))
    assert vol.values.dtype == np.uint8 and not vol.values.flags.owndata  # a view of VTK's array
    assert vol.spacing == tuple(ref.spacing) == (1.0, 1.0, 1.5) and vol.origin == tuple(ref.origin)
    assert vol.space is None and vol.axis_aligned
    ijk = np.array([[0, 0, 0], [499, 0, 0], [3, 400, 7], [250, 17, 135]])
    assert np.allclose(vol.world(ijk), [_vtk_point(ref, p) for p in ijk])
    for p in ijk:  # sample (i, j, k) is VTK's point i + nx (j + ny k)
        assert vol.values[tuple(p)] == ref["MetaImage"][p[0] + 500 * (p[1] + 470 * p[2])]


def test_channels_cell_data_sits_at_the_cell_centres(tmp_path):
    channels = examples.load_channels()
    path = tmp_path / "channels.vti"
    channels.save(path)
    vol = wm.load_volume(path)
    ref = pv.read(path)
    assert vol.shape == (250, 250, 100)
    assert np.array_equal(vol.values, ref["facies"].reshape((250, 250, 100), order="F"))
    assert vol.spacing == tuple(ref.spacing) and np.allclose(vol.origin, np.asarray(ref.origin) + 0.5)
    cells = np.array([[0, 0, 0], [249, 3, 99], [17, 200, 50]])
    bounds = [np.reshape(ref.GetCell(i + 250 * (j + 250 * k)).GetBounds(), (3, 2)) for i, j, k in cells]
    assert np.allclose(vol.world(cells), [b.mean(axis=1) for b in bounds])  # VTK's cell (i, j, k)


def test_vti_with_a_direction_matrix(tmp_path):
    rot = _rotation((1, 2, 3), 0.7)
    img = pv.ImageData(dimensions=(6, 7, 8), spacing=(0.5, 1.0, 2.0), origin=(3, -1, 2), direction_matrix=rot)
    img.point_data["v"] = np.arange(img.n_points, dtype=np.float32)
    path = tmp_path / "rot.vti"
    img.save(path)
    vol = wm.load_volume(path)
    assert np.allclose(vol.direction, rot) and not vol.axis_aligned
    ijk = np.array([[5, 0, 0], [1, 6, 7], [2, 3, 4]])
    assert np.allclose(vol.world(ijk), [_vtk_point(img, p) for p in ijk])
    assert np.allclose(vol.affine @ [1, 6, 7, 1], [*_vtk_point(img, (1, 6, 7)), 1])


def test_mesh_surface_takes_an_image_a_path_and_a_volume(tmp_path):
    g = np.arange(20)
    x, y, z = np.meshgrid(g, g, g, indexing="ij")
    img = pv.ImageData(dimensions=(20, 20, 20), spacing=(0.1, 0.2, 0.3), origin=(1, 2, 3))
    f = 6.0 - np.sqrt((x - 9.5) ** 2 + (y - 9.5) ** 2 + (z - 9.5) ** 2)
    img.point_data["f"] = f.ravel(order="F")
    path = tmp_path / "ball.vti"
    img.save(path)
    by_array = wm.mesh_surface(f, spacing=(0.1, 0.2, 0.3), origin=(1, 2, 3))
    expected = by_array.stats()
    for source in (img, path, str(path), wm.load_volume(path)):  # x fastest: meshed as the transpose
        m = wm.mesh_surface(source)
        assert m.n_cells == by_array.n_cells and m.info["space"] is None
        assert np.allclose(np.sort(m.points, axis=0), np.sort(by_array.points, axis=0), atol=1e-6)
        s = m.stats()
        assert s["watertight"] and np.isclose(s["volume"], expected["volume"], rtol=1e-6)
        assert np.isclose(s["area"], expected["area"], rtol=1e-6)
    same = wm.mesh_surface(wm.Volume(f, spacing=(0.1, 0.2, 0.3), origin=(1, 2, 3)))  # C order: the same run
    assert np.array_equal(same.points, by_array.points) and np.array_equal(same.triangles, by_array.triangles)
    from warpmesh.surface.options import VolumeOptions

    m = wm.mesh_surface(img, options=VolumeOptions(level=1.0))
    assert m.stats()["watertight"] and m.stats()["volume"] < by_array.stats()["volume"]


# ----------------------------------------------------------------------------- NIfTI
def _sphere_image(affine, shape, centre, radius) -> np.ndarray:
    """r - |x - c| sampled at affine @ (i, j, k, 1)."""
    ijk = np.stack(np.meshgrid(*map(np.arange, shape), indexing="ij"), axis=-1).reshape(-1, 3)
    world = ijk @ affine[:3, :3].T + affine[:3, 3]
    return (radius - np.linalg.norm(world - centre, axis=1)).reshape(shape).astype(np.float32)


@pytest.mark.parametrize("reflect", [False, True], ids=["rotation", "rotation+reflection"])
def test_nifti_sphere_lands_where_the_affine_puts_it(tmp_path, check_mesh, reflect):
    spacing = np.array([0.9, 1.1, 1.3])
    rot = _rotation((1, -2, 0.5), 0.6) @ (np.diag([-1.0, 1, 1]) if reflect else np.eye(3))
    affine = np.eye(4)
    affine[:3, :3] = rot * spacing
    affine[:3, 3] = (40.0, -25.0, 12.0)
    shape = (34, 30, 26)
    centre_ijk = np.array([16.3, 14.6, 12.2])
    centre = affine[:3, :3] @ centre_ijk + affine[:3, 3]
    radius = 9.0
    path = tmp_path / "ball.nii"
    nib.save(nib.Nifti1Image(_sphere_image(affine, shape, centre, radius), affine), path)
    vol = wm.load_volume(path)
    assert vol.space == "RAS" and isinstance(vol.values, np.memmap)  # uncompressed: a memory map
    assert np.allclose(vol.affine, affine, atol=1e-5) and np.allclose(vol.spacing, spacing, atol=1e-6)
    mesh = wm.mesh_surface(vol, level=0.0)
    check_mesh(mesh)
    s = mesh.stats()
    assert s["euler"] == 2 and s["volume"] > 0 and mesh.info["space"] == "RAS"
    half_voxel = spacing.max() / 2
    r = np.linalg.norm(mesh.points - centre, axis=1)
    assert np.abs(r - radius).max() < half_voxel
    assert np.linalg.norm(mesh.points.mean(axis=0) - centre) < half_voxel
    assert abs(s["volume"] - 4 / 3 * np.pi * radius**3) < 0.02 * 4 / 3 * np.pi * radius**3
    # SimpleITK reads the same file in LPS: to_space("LPS") gives its origin and direction
    ref = sitk.ReadImage(str(path))
    lps = vol.to_space("LPS")
    assert np.allclose(lps.origin, ref.GetOrigin(), atol=1e-4)
    assert np.allclose(lps.direction, np.reshape(ref.GetDirection(), (3, 3)), atol=1e-5)
    assert np.allclose(lps.spacing, ref.GetSpacing(), atol=1e-5)


def test_nifti_gz_and_integer_labels(tmp_path):
    lab = np.zeros((12, 10, 9), dtype=np.int16)
    lab[2:6, 2:8, 2:7], lab[7:11, 2:8, 2:7] = 1, 5
    affine = np.diag([2.0, 1.5, 1.0, 1.0])
    affine[:3, 3] = (-10, 4, 0)
    path = tmp_path / "seg.nii.gz"
    nib.save(nib.Nifti1Image(lab, affine), path)
    vol = wm.load_volume(path)
    assert vol.values.dtype == np.int16 and np.array_equal(vol.values, lab)
    mesh = wm.mesh_surface(path, labels="all")
    assert sorted(set(mesh.cell_refs["triangle"].tolist())) == [1, 5]
    lo = mesh.points.min(axis=0)
    assert np.allclose(lo, [-10 + 2 * 1.5, 4 + 1.5 * 1.5, 1.5], atol=1e-9)  # halfway to the outside sample


# ----------------------------------------------------------------------------- ITK formats and DICOM
def _itk_image(values, spacing, origin, direction):
    img = sitk.GetImageFromArray(np.ascontiguousarray(values.T))  # ITK's (k, j, i) buffer order
    img.SetSpacing(spacing)
    img.SetOrigin(origin)
    img.SetDirection(np.asarray(direction).ravel().tolist())
    return img


@pytest.mark.parametrize("ext", [".nrrd", ".mha", ".mhd"])
def test_itk_files_read_as_simpleitk_reads_them(tmp_path, ext):
    rng = np.random.default_rng(3)
    values = rng.integers(-1000, 2000, size=(9, 7, 5)).astype(np.int16)
    direction = _rotation((0, 1, 1), 0.4)
    path = tmp_path / f"ct{ext}"
    sitk.WriteImage(_itk_image(values, (0.7, 0.8, 2.5), (1.0, -2.0, 30.0), direction), str(path))
    vol = wm.load_volume(path)
    ref = sitk.ReadImage(str(path))
    assert vol.space == "LPS" and np.array_equal(vol.values, values)
    assert np.array_equal(vol.values, sitk.GetArrayFromImage(ref).T) and not vol.values.flags.owndata
    assert vol.spacing == ref.GetSpacing() and vol.origin == ref.GetOrigin()
    assert np.allclose(vol.direction, np.reshape(ref.GetDirection(), (3, 3)))
    for ijk in ([0, 0, 0], [8, 1, 4], [3, 6, 2]):
        assert np.allclose(vol.world([ijk])[0], ref.TransformIndexToPhysicalPoint(ijk))
    if ext == ".nrrd":  # an independent reader: pynrrd's x-fastest array and space directions
        nrrd = pytest.importorskip("nrrd")
        data, header = nrrd.read(str(path))
        assert np.array_equal(vol.values, data)
        assert np.allclose(vol.direction * vol.spacing, np.asarray(header["space directions"]).T)
        assert np.allclose(vol.origin, header["space origin"])


def test_itk_view_outlives_the_image(tmp_path):
    """The values are a view of ITK's buffer, kept alive by the array itself."""
    import gc

    path = tmp_path / "v.mha"
    values = np.arange(4 * 5 * 6, dtype=np.float64).reshape(4, 5, 6)
    sitk.WriteImage(_itk_image(values, (1, 1, 1), (0, 0, 0), np.eye(3)), str(path))
    arr = wm.load_volume(path).values
    gc.collect()
    _ = [np.full(4 * 5 * 6, -1.0) for _ in range(200)]  # reuse freed memory, if any was freed
    assert np.array_equal(arr, values)


def test_dicom_series_folder(tmp_path):
    pydicom = pytest.importorskip("pydicom")
    rng = np.random.default_rng(7)
    values = rng.integers(-500, 1500, size=(16, 12, 6)).astype(np.int16)
    direction = _rotation((0.3, -0.2, 1.0), 0.5)  # columns: row, column and slice directions
    img = _itk_image(values, (0.6, 0.6, 2.0), (-40.0, 25.0, 100.0), direction)
    folder = tmp_path / "series"
    folder.mkdir()
    writer = sitk.ImageFileWriter()
    writer.KeepOriginalImageUIDOn()
    series = "1.2.826.0.1.3680043.2.1125.1.42"
    saved = locale.setlocale(locale.LC_ALL)  # ITK's DICOM writer sets LC_CTYPE to "C" and leaves it: later
    try:  # tests in this process then decoded UTF-8 output (the CLI's help) as ASCII
        for k in range(values.shape[2]):
            s = img[:, :, k]
            for tag, value in (("0020|000e", series), ("0008|0060", "CT"), ("0020|0013", str(k + 1)),
                               ("0020|0032", "\\".join(map(str, img.TransformIndexToPhysicalPoint((0, 0, k))))),
                               ("0020|0037", "\\".join(map(str, direction.T[:2].ravel()))), ("0018|0050", "2.0")):
                s.SetMetaData(tag, value)
            writer.SetFileName(str(folder / f"slice{k:03d}.dcm"))
            writer.Execute(s)
    finally:
        locale.setlocale(locale.LC_ALL, saved)
    encoding = locale.getpreferredencoding(False)
    vol = wm.load_volume(folder)
    reader = sitk.ImageSeriesReader()
    reader.SetFileNames(sitk.ImageSeriesReader.GetGDCMSeriesFileNames(str(folder)))
    ref = reader.Execute()
    assert vol.space == "LPS" and vol.shape == (16, 12, 6)
    assert np.array_equal(vol.values, sitk.GetArrayFromImage(ref).T) and np.array_equal(vol.values, values)
    assert np.allclose(vol.spacing, ref.GetSpacing()) and np.allclose(vol.spacing, (0.6, 0.6, 2.0))
    assert np.allclose(vol.origin, ref.GetOrigin()) and np.allclose(vol.origin, (-40, 25, 100))
    assert np.allclose(vol.direction, np.reshape(ref.GetDirection(), (3, 3))) and np.allclose(vol.direction, direction)
    assert np.allclose(vol.world([[0, 0, 5]])[0], ref.TransformIndexToPhysicalPoint((0, 0, 5)))
    first = pydicom.dcmread(folder / "slice000.dcm")  # rows are j, columns i
    assert np.allclose(first.ImagePositionPatient, vol.origin)
    assert np.array_equal(first.pixel_array.T, values[:, :, 0])
    assert wm.load_volume(folder, name=series).shape == vol.shape
    with pytest.raises(ValueError, match="'name'"):
        wm.load_volume(folder, name="1.2.3")
    assert locale.getpreferredencoding(False) == encoding  # reading leaves the user's locale alone


# ----------------------------------------------------------------------------- numpy
def test_npy_is_memory_mapped_and_npz_carries_its_placement(tmp_path):
    values = np.arange(60, dtype=np.float32).reshape(3, 4, 5)
    np.save(tmp_path / "v.npy", values)
    vol = wm.load_volume(tmp_path / "v.npy")
    assert isinstance(vol.values, np.memmap) and np.array_equal(vol.values, values) and vol.spacing == (1, 1, 1)
    rot = _rotation((0, 0, 1), np.pi / 2)
    np.savez(tmp_path / "v.npz", ct=values, spacing=[1, 2, 3], origin=[4, 5, 6], direction=rot)
    vol = wm.load_volume(tmp_path / "v.npz")
    assert np.array_equal(vol.values, values) and vol.spacing == (1, 2, 3) and vol.origin == (4, 5, 6)
    assert np.allclose(vol.world([[1, 0, 0]]), [[4, 6, 6]])
    np.savez(tmp_path / "two.npz", a=values, b=values + 1)
    with pytest.raises(ValueError, match="name="):
        wm.load_volume(tmp_path / "two.npz")
    assert wm.load_volume(tmp_path / "two.npz", name="b").values[0, 0, 0] == 1


# ----------------------------------------------------------------------------- the command line
def test_cli_meshes_the_frog_labels(tmp_path, capsys):
    frog = examples.load_frog_tissues()
    small = frog.extract_subset((100, 299, 100, 299, 20, 99), rate=(2, 2, 2))  # a sub-sampled block, to stay quick
    small.origin = (3.0, 4.0, 5.0)
    path = tmp_path / "frog.vti"
    small.save(path)
    out = tmp_path / "out.vtu"
    assert main(["mesh", "--volume", str(path), "--labels", "all", "-o", str(out), "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats["watertight"] is True and stats["written"] == str(out)
    mesh = wm.load(out)
    present = set(np.unique(wm.load_volume(path).values).tolist()) - {0}
    assert set(mesh.cell_refs["triangle"].tolist()) == present and len(present) > 3
    lo, hi = np.asarray(small.bounds).reshape(3, 2).T
    assert np.all(mesh.points.min(axis=0) >= lo) and np.all(mesh.points.max(axis=0) <= hi)
    assert main(["mesh", "--volume", str(tmp_path / "nothing.vti")]) == 2
    assert "--volume" in capsys.readouterr().err


def test_cli_places_a_nifti_in_its_world_frame(tmp_path, capsys):
    affine = np.eye(4)
    affine[:3, :3] = _rotation((0, 0, 1), 0.5) * 1.5
    affine[:3, 3] = (10, 20, 30)
    centre = affine[:3, :3] @ [8, 8, 8] + affine[:3, 3]
    path = tmp_path / "ball.nii.gz"
    nib.save(nib.Nifti1Image(_sphere_image(affine, (17, 17, 17), centre, 7.0), affine), path)
    out = tmp_path / "ball.ply"
    assert main(["mesh", "--volume", str(path), "-o", str(out), "--json"]) == 0
    stats = json.loads(capsys.readouterr().out)
    assert stats["space"] == "RAS" and stats["euler"] == 2
    assert np.abs(np.linalg.norm(wm.load(out).points - centre, axis=1) - 7.0).max() < 0.75
    assert main(["mesh", "--volume", str(path), "--simplify", "0.5"]) == 2  # the target field is axis-aligned only
    assert "direction" in capsys.readouterr().err


# ----------------------------------------------------------------------------- bad input
def test_labels_of_floats_must_be_whole_numbers(tmp_path):
    lab = np.zeros((8, 8, 8), dtype=np.float32)
    lab[2:6, 2:6, 2:6] = 3.0
    affine = np.eye(4)
    nib.save(nib.Nifti1Image(lab, affine), tmp_path / "whole.nii")
    mesh = wm.mesh_surface(tmp_path / "whole.nii", labels="all")  # floats holding labels: accepted
    assert set(mesh.cell_refs["triangle"].tolist()) == {3}
    lab[4, 4, 4] = 2.5
    nib.save(nib.Nifti1Image(lab, affine), tmp_path / "frac.nii")
    with pytest.raises(ValueError, match="'labels'.*2.5"):
        wm.mesh_surface(tmp_path / "frac.nii", labels="all")
    with pytest.raises(ValueError, match="'labels'.*whole-number.*2.5"):  # a plain float array: the same
        wm.mesh_surface(lab, labels="all")


def test_labels_not_present(tmp_path):
    lab = np.zeros((8, 8, 8), dtype=np.uint8)
    lab[2:6, 2:6, 2:6] = 1
    np.save(tmp_path / "seg.npy", lab)
    with pytest.raises(ValueError, match="label 7"):
        wm.mesh_surface(tmp_path / "seg.npy", labels=[7])


@pytest.mark.parametrize("name", ["bad.nii", "bad.nii.gz", "bad.vti", "bad.vtk", "bad.mha", "bad.nrrd", "bad.npy",
                                  "bad.npz"])
def test_a_file_that_does_not_parse(tmp_path, name):
    path = tmp_path / name
    path.write_bytes(b"this is not an image\n" * 8)
    with pytest.raises(ReadError, match="bad"):
        wm.load_volume(path)


@pytest.mark.parametrize("name", ["bad.vti", "bad.vtk"])
def test_a_file_that_is_not_vtk_is_refused_quietly(tmp_path, name, capfd):
    """VTK's reader printed a page of C++ errors (parser, pipeline) before pyvista's failure;
    a file that does not start as a VTK file is refused before VTK sees it."""
    path = tmp_path / name
    path.write_bytes(b"this is not an image\n" * 8)
    capfd.readouterr()
    with pytest.raises(ReadError, match="does not start as a VTK file"):
        wm.load_volume(path)
    assert capfd.readouterr().err == ""
    path.write_bytes(b'<?xml version="1.0"?>\n<VTKFile type="ImageData" version="1.0">\n<ImageData WholeExtent=')
    with pytest.raises(ReadError, match="bad.*" + ("Error parsing XML" if name == "bad.vti" else "")):
        wm.load_volume(path)  # a VTK file cut short: VTK's own message, in the exception only
    assert capfd.readouterr().err == ""


def test_a_failed_vtk_read_leaves_the_logging_alone(tmp_path):
    """pyvista logs VTK's errors on the root logger, whose ``basicConfig`` then gave an
    application without handlers a stderr handler for good (in a fresh process: pytest's
    own handlers would hide it)."""
    import subprocess

    path = tmp_path / "cut.vti"
    path.write_bytes(b'<?xml version="1.0"?>\n<VTKFile type="ImageData" version="1.0">\n<ImageData WholeExtent=')
    code = ("import logging, sys, warpmesh as wm\nfrom warpmesh.errors import ReadError\n"
            "try:\n    wm.load_volume(sys.argv[1])\nexcept ReadError as exc:\n    print('refused:', exc)\n"
            "root = logging.getLogger()\nprint('handlers', len(root.handlers), 'filters', len(root.filters))")
    run = subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, encoding="utf-8", timeout=300)
    assert run.returncode == 0, run.stderr
    assert "refused:" in run.stdout and "Error parsing XML" in run.stdout
    assert run.stdout.strip().endswith("handlers 0 filters 0") and run.stderr == ""


def test_a_vti_after_a_byte_order_mark_reads(tmp_path):
    img = pv.ImageData(dimensions=(3, 4, 5))
    img.point_data["v"] = np.arange(60, dtype=np.float32)
    img.save(tmp_path / "plain.vti")
    (tmp_path / "bom.vti").write_bytes(b"\xef\xbb\xbf" + (tmp_path / "plain.vti").read_bytes())
    assert np.array_equal(wm.load_volume(tmp_path / "bom.vti").values, wm.load_volume(tmp_path / "plain.vti").values)


def test_a_mesh_file_is_not_an_image(tmp_path):
    pv.Sphere().save(tmp_path / "ball.vtk")
    with pytest.raises(ValueError, match="expected an image.*PolyData.*warpmesh.load"):
        wm.load_volume(tmp_path / "ball.vtk")


def test_a_folder_without_dicom(tmp_path):
    (tmp_path / "notes.txt").write_text("no images here")
    with pytest.raises(ReadError, match="DICOM"):
        wm.load_volume(tmp_path)


def test_a_2d_image(tmp_path):
    np.save(tmp_path / "flat.npy", np.zeros((5, 5)))
    img = pv.ImageData(dimensions=(5, 6, 1))
    img.point_data["v"] = np.zeros(30)
    img.save(tmp_path / "flat.vti")
    nib.save(nib.Nifti1Image(np.zeros((5, 6), dtype=np.float32), np.eye(4)), tmp_path / "flat.nii")
    sitk.WriteImage(sitk.Image(5, 6, sitk.sitkInt16), str(tmp_path / "flat.mha"))
    for name in ("flat.npy", "flat.vti", "flat.nii", "flat.mha"):
        with pytest.raises(ValueError, match="expected a 3D image") as err:
            wm.load_volume(tmp_path / name)
        assert name in str(err.value)


@pytest.mark.parametrize("module, name", [("nibabel", "v.nii"), ("SimpleITK", "v.nrrd")])
def test_a_missing_reader_names_the_extra(tmp_path, monkeypatch, capsys, module, name):
    (tmp_path / name).write_bytes(b"\0" * 64)
    monkeypatch.setitem(sys.modules, module, None)  # import fails as if not installed
    with pytest.raises(ImportError, match=rf"{module}.*warpmesh\[images\]"):
        wm.load_volume(tmp_path / name)
    with pytest.raises(ImportError, match=r"warpmesh\[images\]"):
        wm.mesh_surface(tmp_path / name)
    assert main(["mesh", "--volume", str(tmp_path / name)]) == 2
    assert "pip install 'warpmesh[images]'" in capsys.readouterr().err


def test_paths_and_arguments(tmp_path):
    with pytest.raises(FileNotFoundError, match="no/such.nii"):
        wm.load_volume("no/such.nii")
    with pytest.raises(FileNotFoundError, match="no/such.vti"):
        wm.mesh_surface("no/such.vti")
    (tmp_path / "v.tiff").write_bytes(b"\0")
    with pytest.raises(ValueError, match="'path'.*unknown extension '.tiff'"):
        wm.load_volume(tmp_path / "v.tiff")
    with pytest.raises(TypeError, match="'path'"):
        wm.load_volume(3)
    (tmp_path / "slice.dcm").write_bytes(b"\0")
    with pytest.raises(ValueError, match="'path'.*folder"):
        wm.load_volume(tmp_path / "slice.dcm")
    vol = Volume(np.random.default_rng(0).random((4, 4, 4)), spacing=2.0)
    with pytest.raises(ValueError, match="'spacing'.*replace"):
        wm.mesh_surface(vol, spacing=1.0, level=0.5)
    from warpmesh.surface.options import VolumeOptions

    with pytest.raises(ValueError, match="'origin'"):
        wm.mesh_surface(vol, options=VolumeOptions(origin=(1, 2, 3)))
    with pytest.raises(ValueError, match="'direction'"):
        Volume(np.zeros((2, 2, 2)), direction=np.ones((3, 3)))
    with pytest.raises(ValueError, match="'values'"):
        Volume(np.zeros((2, 2)))
    with pytest.raises(ValueError, match="space=None"):
        vol.to_space("RAS")
