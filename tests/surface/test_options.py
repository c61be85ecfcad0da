"""mesh_surface's options: one self-checking group per pipeline (warpmesh.surface.options),
built from the flat keywords or given as ``options=``, the same meshes either way."""

import dataclasses

import numpy as np
import pytest

import warpmesh as wm
from tests.helpers.meshcheck import check_mesh
from warpmesh.surface.options import AdaptiveOptions, ContinuationOptions, GridOptions, VolumeOptions

BOX = ((-1.0,) * 3, (1.0,) * 3)
PART, PART_BOUNDS = wm.example("part")


def _same(a: wm.Mesh, b: wm.Mesh) -> None:
    assert np.array_equal(a.points, b.points)
    assert np.array_equal(a.triangles, b.triangles)
    assert (a.cell_refs is None) == (b.cell_refs is None)
    if a.cell_refs is not None:
        assert np.array_equal(a.cell_refs["triangle"], b.cell_refs["triangle"])


def _part_volume(n=33):
    """The part sampled at the nodes of the 32-cell grid over its bounds: (volume, spacing, origin)."""
    lo, hi = np.array(PART_BOUNDS, dtype=float)
    axes = [np.linspace(lo[i], hi[i], n) for i in range(3)]
    pts = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    return wm.evaluate(PART, pts).reshape(n, n, n), tuple((hi - lo) / (n - 1)), tuple(lo)


# -- each group checks itself ---------------------------------------------------------------------
@pytest.mark.parametrize("kwargs, err, match", [
    (dict(bounds=None), ValueError, "'bounds'"),
    (dict(bounds=((0, 0, 0), (1, 1))), ValueError, r"'bounds' as \(\(x0, y0, z0\), \(x1, y1, z1\)\)"),
    (dict(bounds=((0, 0), (1, 1))), ValueError, r"'bounds' of shape \(2, 3\), got shape \(2, 2\)"),
    (dict(bounds=((0, 0, np.nan), (1, 1, 1))), ValueError, "finite 'bounds'"),
    (dict(bounds=((0, 0, 0), (0, 1, 1))), ValueError, "non-empty 'bounds'"),
    (dict(bounds="box"), ValueError, "'bounds'"),
    (dict(resolution=0), ValueError, "'resolution'"),
    (dict(resolution=4096), ValueError, "'resolution' <= 2048"),
    (dict(resolution=8.5), TypeError, "'resolution'"),
    (dict(resolution=True), TypeError, "'resolution'"),
    (dict(resolution=(4, 4)), ValueError, "3 ints for 'resolution'"),
    (dict(resolution=1), ValueError, "at least 2 cells"),
    (dict(method="dual"), ValueError, r"Unknown method 'dual'. Pick one of \['mc33', 'mt', 'mc'\]"),
    (dict(root="secant"), ValueError, "Unknown root 'secant'"),
    (dict(root="newton", root_iterations=0), ValueError, "1 <= 'root_iterations' <= 64"),
    (dict(root="bisection", root_iterations=2.5), ValueError, "'root_iterations'"),
    (dict(root_iterations=5), ValueError, "'root_iterations' applies to root='bisection' or 'newton'"),
    (dict(root="newton", gradient="sobel"), ValueError, "Unknown gradient 'sobel'"),
    (dict(gradient="central"), ValueError, "'gradient' applies to root='newton' or normals=True"),
    (dict(cap="no"), TypeError, "expected True or False for 'cap'"),
    (dict(cull=1), TypeError, "expected True or False for 'cull'"),
    (dict(normals="yes"), TypeError, "expected True or False for 'normals'"),
    (dict(evaluator="jit"), ValueError, "Unknown evaluator 'jit'"),
])
def test_grid_options_refuse_bad_values(kwargs, err, match):
    with pytest.raises(err, match=match):
        GridOptions(**{"bounds": BOX, **kwargs})


@pytest.mark.parametrize("kwargs, err, match", [
    (dict(seeds=[("a", "b", "c")]), ValueError, r"'seeds' as \(m, 3\) points"),
    (dict(seeds=[(0.0, 0.0)]), ValueError, r"'seeds' as finite \(m, 3\) points, got shape \(1, 2\)"),
    (dict(seeds=[(0.0, 0.0, np.inf)]), ValueError, "finite"),
    (dict(seeds=np.zeros((0, 3))), ValueError, "'seeds'"),
    (dict(method="dual"), ValueError, "Unknown method"),
    (dict(cull=False), TypeError, "cull"),  # not a field: continuation has nothing to cull
])
def test_continuation_options_refuse_bad_values(kwargs, err, match):
    with pytest.raises(err, match=match):
        ContinuationOptions(**{"bounds": BOX, **kwargs})


@pytest.mark.parametrize("kwargs, err, match", [
    (dict(bounds=None), ValueError, "'bounds'"),
    (dict(max_level=0), ValueError, "1 <= 'max_level' <= 18"),
    (dict(max_level=19), ValueError, "'max_level'"),
    (dict(max_level=5.0), ValueError, "'max_level'"),
    (dict(max_level=9, resolution=512), ValueError, "not both"),
    (dict(resolution=(8, 8, 8)), ValueError, "one integer 'resolution'"),
    (dict(resolution=0), ValueError, "'resolution'"),
    (dict(max_level=5, min_level=6), ValueError, "0 <= 'min_level' <= 5"),
    (dict(tolerance=-1.0), ValueError, "positive finite number for 'tolerance'"),
    (dict(tolerance=float("nan")), ValueError, "'tolerance'"),
    (dict(chord=0.0), ValueError, "'chord'"),
    (dict(angles=(0.1,)), ValueError, r"'angles' as \(eps1, eps2\)"),
    (dict(angles=(0.1, -0.1)), ValueError, "'angles'"),
    (dict(angles=(0.1, 0.1), tolerance=0.02), ValueError, "'tolerance' or 'angles', not both"),
    (dict(bound="hull"), ValueError, "Unknown bound 'hull'"),
    (dict(bound="lipschitz"), ValueError, "'lipschitz'"),
    (dict(lipschitz=1.0), ValueError, "'lipschitz' applies to bound='lipschitz'"),
    (dict(root="secant"), ValueError, "Unknown root"),
    (dict(root="linear", root_iterations=3), ValueError, "'root_iterations' applies"),
    (dict(root="linear", gradient="forward"), ValueError, "'gradient' applies to root='newton', got"),
    (dict(prune=1), TypeError, "'prune'"),
    (dict(features="yes"), TypeError, "'features'"),
    (dict(cap=None), TypeError, "'cap'"),
])
def test_adaptive_options_refuse_bad_values(kwargs, err, match):
    with pytest.raises(err, match=match):
        AdaptiveOptions(**{"bounds": BOX, **kwargs})


@pytest.mark.parametrize("kwargs, err, match", [
    (dict(level=float("nan")), ValueError, "finite number for 'level'"),
    (dict(level=True), ValueError, "'level'"),
    (dict(level="0.5"), ValueError, "'level'"),
    (dict(inside="up"), ValueError, r"Unknown inside 'up'. Pick one of \['above', 'below'\]"),
    (dict(labels="some"), ValueError, "'labels'"),
    (dict(labels=[]), ValueError, "non-empty sequence of integers"),
    (dict(labels=[1.5]), ValueError, "'labels'"),
    (dict(labels=[3, 3]), ValueError, "distinct"),
    (dict(labels="all", level=0.2), ValueError, "'level' does not apply with 'labels'"),
    (dict(labels="all", inside="below"), ValueError, "inside='below' does not apply with 'labels'"),
    (dict(spacing=0.0), ValueError, "'spacing'"),
    (dict(spacing=(1.0, 2.0)), ValueError, "'spacing'"),
    (dict(spacing="a"), ValueError, "'spacing'"),
    (dict(origin=(0.0, 0.0)), ValueError, "'origin'"),
    (dict(origin=(0.0, 0.0, np.nan)), ValueError, "'origin'"),
    (dict(slab_voxels=0), ValueError, "positive integer for 'slab_voxels'"),
    (dict(slab_voxels=True), ValueError, "'slab_voxels'"),
    (dict(slab_voxels=1e6), ValueError, "'slab_voxels'"),
    (dict(method="dual"), ValueError, "Unknown method"),
    (dict(cap="no"), TypeError, "'cap'"),
    (dict(cull=0), TypeError, "'cull'"),
])
def test_volume_options_refuse_bad_values(kwargs, err, match):
    with pytest.raises(err, match=match):
        VolumeOptions(**kwargs)


def test_groups_are_normalised_comparable_values():
    g = GridOptions(bounds=[[-1, -1, -1], [1, 1, 1]], resolution=np.array([8, 4, 4]), cap=np.True_)
    assert g.bounds == BOX and g.resolution == (8, 4, 4) and g.cap is True
    same = GridOptions(bounds=BOX, resolution=(8, 4, 4))
    assert g == same and hash(g) == hash(same)
    assert g.cells.tolist() == [8, 4, 4]
    with pytest.raises(dataclasses.FrozenInstanceError):
        g.method = "mt"
    with pytest.raises(ValueError, match="Unknown method"):
        dataclasses.replace(g, method="dual")  # a changed copy is checked again
    v = VolumeOptions(spacing=0.5, origin=np.zeros(3), labels=np.array([4, 1]), level=None)
    assert (v.spacing, v.origin, v.labels) == ((0.5, 0.5, 0.5), (0.0, 0.0, 0.0), (4, 1))
    assert ContinuationOptions(bounds=BOX, seeds=np.zeros((2, 3))).seeds == ((0.0,) * 3,) * 2
    with pytest.raises(TypeError):
        GridOptions(resolution=8)  # bounds is required


def test_adaptive_levels_and_tolerance_defaults():
    a = AdaptiveOptions(bounds=BOX)
    assert (a.finest_level, a.relative_tolerance, a.root, a.min_level) == (7, 0.02, "newton", None)
    assert AdaptiveOptions(bounds=BOX, resolution=512).finest_level == 9
    assert AdaptiveOptions(bounds=BOX, resolution=100).finest_level == 7
    assert AdaptiveOptions(bounds=BOX, max_level=4).finest_level == 4
    assert AdaptiveOptions(bounds=BOX, chord=1e-3).relative_tolerance is None
    assert AdaptiveOptions(bounds=BOX, angles=(0.1, 0.2)).relative_tolerance is None
    assert AdaptiveOptions(bounds=BOX, chord=1e-3, tolerance=0.05).relative_tolerance == 0.05
    assert AdaptiveOptions(bounds=BOX, bound="lipschitz", lipschitz=2).lipschitz == 2.0


def test_every_field_is_documented_with_its_default():
    for group in (GridOptions, ContinuationOptions, AdaptiveOptions, VolumeOptions):
        doc = group.__doc__
        assert "{parameters}" not in doc
        for f in dataclasses.fields(group):
            assert f"\n    {f.name} : " in doc, (group.__name__, f.name)
        assert group.__name__ in wm.mesh_surface.__doc__
    assert "method : {'mc33', 'mt', 'mc'}, default 'mc33'" in GridOptions.__doc__
    assert "root : {'linear', 'bisection', 'newton'}, default 'newton'" in AdaptiveOptions.__doc__


# -- flat keywords: one group per pipeline, one error for the others' options ---------------------
def test_a_keyword_of_another_pipeline_is_refused_once_with_what_this_one_takes():
    takes = ("GridOptions takes bounds, resolution, method, root, root_iterations, gradient, normals, cap, "
             "evaluator, clearance, cull")
    with pytest.raises(ValueError) as err:
        wm.mesh_surface(wm.sphere(0.5), bounds=BOX, resolution=8, level=0.1, spacing=0.1, tolerance=0.02)
    assert str(err.value) == (
        "'level', 'spacing', 'tolerance' do not apply to a shape on a grid ('level', 'spacing' are options of a "
        "volume; 'tolerance' is an option of a shape with adaptive=True); " + takes)
    with pytest.raises(ValueError, match=r"^'resolution' does not apply to a volume \('resolution' is an option of "
                                         r"every shape pipeline\); VolumeOptions takes level, inside, labels"):
        wm.mesh_surface(np.zeros((4, 4, 4)), resolution=8)
    with pytest.raises(ValueError, match="'seeds' does not apply to a shape on a grid .* covering='continuation'"):
        wm.mesh_surface(wm.sphere(0.5), bounds=BOX, seeds=[(0.5, 0, 0)])
    with pytest.raises(ValueError, match="'method', 'evaluator' do not apply to a shape with adaptive=True"):
        wm.mesh_surface(wm.sphere(0.5), bounds=BOX, adaptive=True, method="mt", evaluator="compiled")


@pytest.mark.parametrize("source, kwargs, name", [
    ("shape", dict(covering="continuation", cull=False), "cull"),
    ("shape", dict(adaptive=True, cull=False), "cull"),
    ("shape", dict(adaptive=True, normals=True), "normals"),
    ("volume", dict(root="newton"), "root"),
    ("volume", dict(normals=True), "normals"),
])
def test_what_a_pipeline_always_does_is_accepted_and_nothing_else(source, kwargs, name):
    """cull=True for continuation, root='linear' for a volume...: what the pipeline does anyway."""
    src = wm.sphere(0.5) if source == "shape" else np.linspace(-1, 1, 64).reshape(4, 4, 4)
    extra = dict(bounds=BOX, resolution=16) if source == "shape" else {}
    with pytest.raises(ValueError, match=f"^'{name}' does not apply to .* always runs with {name}="):
        wm.mesh_surface(src, **extra, **kwargs)
    always = {"cull": True, "normals": False, "root": "linear"}[name]
    wm.mesh_surface(src, **extra, **{**kwargs, name: always})


def test_none_means_not_given_and_unknown_names_are_type_errors():
    a = wm.mesh_surface(wm.sphere(0.5), bounds=BOX, resolution=8)
    b = wm.mesh_surface(wm.sphere(0.5), bounds=BOX, resolution=8, level=None, labels=None, max_level=None,
                        seeds=None, method=None, covering=None)
    _same(a, b)
    with pytest.raises(TypeError, match="unexpected keyword argument 'resolutoin'; a shape on a grid takes bounds"):
        wm.mesh_surface(wm.sphere(0.5), bounds=BOX, resolutoin=8)
    with pytest.raises(TypeError, match="unexpected keyword arguments 'a', 'b'"):
        wm.mesh_surface(np.zeros((4, 4, 4)), a=None, b=1)


def test_selectors():
    with pytest.raises(ValueError, match="Unknown covering 'octree'"):
        wm.mesh_surface(wm.sphere(0.5), bounds=BOX, covering="octree")
    with pytest.raises(ValueError, match="adaptive=True is its own covering-up"):
        wm.mesh_surface(wm.sphere(0.5), bounds=BOX, adaptive=True, covering="continuation")
    with pytest.raises(ValueError, match="a volume's samples are all given"):
        wm.mesh_surface(np.zeros((4, 4, 4)), covering="continuation")
    with pytest.raises(TypeError, match="adaptive=True meshes a Shape"):
        wm.mesh_surface(np.zeros((4, 4, 4)), adaptive=True)
    with pytest.raises(TypeError, match="expected True or False for 'adaptive'"):
        wm.mesh_surface(wm.sphere(0.5), bounds=BOX, adaptive=1)
    with pytest.raises(FileNotFoundError, match="no such image file or DICOM folder: 'sphere'"):
        wm.mesh_surface("sphere", bounds=BOX)  # a string is an image's path


# -- options=: the same meshes as the flat keywords ------------------------------------------------
def test_options_give_the_same_mesh_as_keywords_in_every_pipeline():
    vol, spacing, origin = _part_volume()
    shape, bounds = wm.example("torus")
    pairs = [
        (shape, dict(bounds=bounds, resolution=24, method="mt", root="newton", normals=True, gradient="central"),
         GridOptions(bounds=bounds, resolution=24, method="mt", root="newton", normals=True, gradient="central")),
        (shape, dict(bounds=bounds, resolution=24, covering="continuation", root="bisection", root_iterations=6,
                     seeds=[(1.0, 0.0, 0.35)]),
         ContinuationOptions(bounds=bounds, resolution=24, root="bisection", root_iterations=6,
                             seeds=[(1.0, 0.0, 0.35)])),
        (shape, dict(bounds=bounds, adaptive=True, max_level=5, chord=1e-3, features=False),
         AdaptiveOptions(bounds=bounds, max_level=5, chord=1e-3, features=False)),
        (vol, dict(spacing=spacing, origin=origin, level=0.05, inside="below", method="mc", slab_voxels=5000),
         VolumeOptions(spacing=spacing, origin=origin, level=0.05, inside="below", method="mc", slab_voxels=5000)),
        ((vol > 0).astype(np.uint8) * 7, dict(labels=[7], spacing=spacing), VolumeOptions(labels=[7], spacing=spacing)),
    ]
    for source, keywords, options in pairs:
        flat, grouped = wm.mesh_surface(source, **keywords), wm.mesh_surface(source, options=options)
        _same(flat, grouped)
        check_mesh(grouped)
        if "normals" in keywords:
            assert np.array_equal(flat.point_data["normals"], grouped.point_data["normals"])


def test_options_alone_and_matching_the_source():
    opts = GridOptions(bounds=BOX, resolution=8)
    with pytest.raises(ValueError, match=r"options=GridOptions\(...\) or as keywords, not both: got 'method' too"):
        wm.mesh_surface(wm.sphere(0.5), options=opts, method="mt")
    with pytest.raises(ValueError, match="not both: got 'adaptive'"):
        wm.mesh_surface(wm.sphere(0.5), options=AdaptiveOptions(bounds=BOX, max_level=3), adaptive=True)
    with pytest.raises(ValueError, match="not both: got 'covering'"):
        wm.mesh_surface(wm.sphere(0.5), options=opts, covering="grid")
    with pytest.raises(TypeError, match="unexpected keyword argument 'methd'"):
        wm.mesh_surface(wm.sphere(0.5), options=opts, methd="mt")
    with pytest.raises(TypeError, match="expected GridOptions, ContinuationOptions, AdaptiveOptions, VolumeOptions "
                                        "for 'options', got dict"):
        wm.mesh_surface(wm.sphere(0.5), options={"bounds": BOX})
    with pytest.raises(TypeError, match="GridOptions meshes a shape on a grid: expected a Shape or an expression "
                                        "for 'source', got ndarray"):
        wm.mesh_surface(np.zeros((4, 4, 4)), options=opts)
    with pytest.raises(TypeError, match="VolumeOptions meshes a volume: expected a 3D array for 'source', got Shape"):
        wm.mesh_surface(wm.sphere(0.5), options=VolumeOptions())
    with pytest.raises(FileNotFoundError, match="'sphere'"):
        wm.mesh_surface("sphere", options=opts)  # a string is an image's path
    m = wm.mesh_surface(wm.sphere(0.5), options=opts, device="cpu", level=None)  # None: not given
    assert m.info["device"] == "cpu"


# -- the defaults are those of before --------------------------------------------------------------
# (points, triangles) of the part at resolution 32, meshed by mesh_surface before the options groups
PART_32 = {"grid": (2950, 5912), "continuation": (2950, 5912), "adaptive": (3366, 6744), "volume": (2806, 5624)}


def test_defaults_are_unchanged_on_the_part_at_resolution_32():
    vol, spacing, origin = _part_volume()
    b = PART_BOUNDS
    runs = {  # the group with its defaults; the keywords with the defaults of before spelled out
        "grid": (PART, GridOptions(bounds=b, resolution=32),
                 dict(bounds=b, resolution=32, method="mc33", root="linear", cap=True, cull=True, normals=False,
                      evaluator="auto", gradient="exact")),
        "continuation": (PART, ContinuationOptions(bounds=b, resolution=32),
                         dict(bounds=b, resolution=32, covering="continuation", method="mc33", root="linear",
                              cap=True, normals=False, evaluator="auto")),
        "adaptive": (PART, AdaptiveOptions(bounds=b, resolution=32),
                     dict(bounds=b, adaptive=True, max_level=5, tolerance=0.02, bound="interval", root="newton",
                          gradient="exact", cap=True, prune=True, features=True)),
        "volume": (vol, VolumeOptions(spacing=spacing, origin=origin),
                   dict(spacing=spacing, origin=origin, level=0.0, inside="above", method="mc33", cap=True,
                        cull=True)),
    }
    for name, (source, options, keywords) in runs.items():
        grouped, flat = wm.mesh_surface(source, options=options), wm.mesh_surface(source, **keywords)
        _same(grouped, flat)
        assert (grouped.n_points, len(grouped.triangles)) == PART_32[name], name
        assert grouped.stats()["euler"] == -6  # genus 4


FLOAT_LIMITS = [  # (what, call, the argument the error names)  [issue 19 item 4: were internal errors]
    ("box of 1e-300", lambda: wm.mesh_surface(wm.sphere(0.5), bounds=((0, 0, 0), (1e-300,) * 3), resolution=16),
     "bounds"),
    ("box far from the origin", lambda: wm.mesh_surface(wm.sphere(0.5, center=(1e7, 0, 0)),
                                                        bounds=((1e7 - 1, -1, -1), (1e7 + 1, 1, 1)), resolution=16),
     "bounds"),
    ("adaptive far from the origin", lambda: wm.mesh_surface(wm.sphere(0.5, center=(1e6, 0, 0)),
                                                             bounds=((1e6 - 1, -1, -1), (1e6 + 1, 1, 1)),
                                                             adaptive=True, max_level=7), "bounds"),
    ("spacing 1e300", lambda: wm.mesh_surface(np.ones((4, 4, 4)) - np.eye(4)[:, :, None], spacing=1e300), "spacing"),
    ("spacing 5e-324", lambda: wm.mesh_surface(np.ones((4, 4, 4)) - np.eye(4)[:, :, None], spacing=5e-324),
     "spacing"),
    ("origin 1e17", lambda: wm.mesh_surface(np.ones((4, 4, 4)) - np.eye(4)[:, :, None], origin=(1e17, 0, 0)),
     "origin"),
]


@pytest.mark.parametrize("case", FLOAT_LIMITS, ids=[c[0] for c in FLOAT_LIMITS])
def test_grids_float_cannot_resolve_are_refused_naming_the_argument(case):
    _, call, name = case
    with pytest.raises(ValueError, match=f"'{name}'"):
        call()


def test_grids_near_the_limits_still_mesh():
    far = wm.mesh_surface(wm.sphere(0.5, center=(1e3, 0, 0)), bounds=((1e3 - 1, -1, -1), (1e3 + 1, 1, 1)),
                          resolution=16)
    near = wm.mesh_surface(wm.sphere(0.5), bounds=((-1, -1, -1), (1, 1, 1)), resolution=16)
    assert far.n_cells == near.n_cells and abs(far.stats()["volume"] - near.stats()["volume"]) < 1e-3
    small = wm.mesh_surface(np.pad(np.ones((3, 3, 3)), 1), spacing=1e-9, level=0.5)
    assert small.stats()["volume"] > 0
