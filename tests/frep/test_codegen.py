"""Kernels generated per tape structure give the interpreter's values, bit for bit."""

import numpy as np
import pytest

import warpmesh as wm
from warpmesh.frep import codegen
from warpmesh.kernels import opcodes as O
from tests.helpers.meshcheck import check_mesh


def _every_opcode_shape():
    """One expression that uses every opcode (valid domains on [-1, 1]^3)."""
    x, y, z = wm.coords()
    pos = x * x + 1.5
    e = (x + y) - z * 2 + (x * y) / pos + 3 / pos + wm.min(x, y) + wm.max(y, z)
    e = e + wm.min(x, 0.2) + wm.max(z, -0.1) + (1 - y) - x + abs(z) + (y ** 2)
    e = e + wm.sqrt(pos) + wm.sin(x) + wm.cos(y) + wm.exp(z) + wm.log(pos) + x ** 3 + pos ** -2
    e = e + abs(y) ** 1.5 + wm.frep.expr.runion(x, y) + wm.frep.expr.rintersection(y, z) - 0.5
    e = e + (-x) * wm.frep.expr.runion(z, 0.3)  # NEG, and a CONST register
    return e


def test_the_probe_covers_every_opcode():
    ops = {n.op for n in _every_opcode_shape().nodes()}
    assert ops == set(O.NAMES) - O.PRUNE_ONLY, set(O.NAMES) - O.PRUNE_ONLY - ops  # COPY: test_prune.py


@pytest.mark.parametrize("make", [_every_opcode_shape, lambda: wm.example("part")[0],
                                  lambda: wm.example("degree6")[0]])
def test_generated_kernel_matches_the_interpreter(make, device):
    shape = make()
    pts = np.random.default_rng(5).uniform(-1, 1, (50_000, 3))
    interpreted = wm.evaluate(shape, pts, evaluator="interpreter", device=device)
    compiled = wm.evaluate(shape, pts, evaluator="compiled", device=device)
    assert np.array_equal(interpreted, compiled, equal_nan=True)


def test_constants_change_without_a_new_kernel():
    a, b = wm.sphere(1.0).translate((0.1, 0.2, 0.3)), wm.sphere(0.5).translate((0.3, -0.2, 0.5))
    ta, tb = wm.compile_tape(a), wm.compile_tape(b)
    assert codegen.structure_key(ta) == codegen.structure_key(tb)
    pts = np.random.default_rng(1).uniform(-1, 1, (1000, 3))
    wm.evaluate(a, pts, evaluator="compiled")
    assert codegen.is_loaded(tb, "cpu")  # the same kernel serves b, with b's constants
    assert np.array_equal(wm.evaluate(b, pts, evaluator="compiled"), wm.evaluate(b, pts, evaluator="interpreter"))


def test_structure_key_is_computed_once_per_code_array(monkeypatch):
    """The key is the hash of the generated source, remembered per code array: the same key
    as computed afresh, shared by the tapes of other values (one code array), and a tape of
    another structure gets its own."""
    import hashlib

    tape = wm.compile_tape(wm.sphere(wm.param("r", 0.5, lo=0.1, hi=1.0)).translate((0.1, 0.0, 0.0)))
    key = codegen.structure_key(tape)
    assert key == hashlib.sha1(codegen.source(tape).encode()).hexdigest()[:16]
    calls = []
    monkeypatch.setattr(codegen, "source", lambda t: calls.append(t) or "changed")
    assert codegen.structure_key(tape.with_values({"r": 0.75})) == key and calls == []
    other = wm.compile_tape(wm.box((1.0, 1.0, 1.0)) | wm.sphere(0.3))
    assert codegen.structure_key(other) == hashlib.sha1(b"changed").hexdigest()[:16] and calls == [other]


def test_auto_answers_first_with_the_interpreter_then_switches():
    x, y, z = wm.coords()
    shape = wm.Shape(0.7 - wm.sqrt(x * x + 2 * y * y + 3 * z * z) + 0.05 * wm.sin(7 * x))  # a fresh structure
    bounds = ((-1.0,) * 3, (1.0,) * 3)
    first = wm.mesh_surface(shape, bounds=bounds, resolution=256)
    assert first.info["evaluator"] == "interpreter"  # no wait for a compile
    key = (codegen.structure_key(wm.compile_tape(shape)), "cpu")
    assert key not in codegen._pending  # a one-shot run starts no compile ...
    again = wm.mesh_surface(shape, bounds=bounds, resolution=256)
    assert again.info["evaluator"] == "interpreter"  # ... a second one does, in the background
    codegen.wait()
    second = wm.mesh_surface(shape, bounds=bounds, resolution=256)
    assert second.info["evaluator"] == "compiled"
    assert np.array_equal(first.points, second.points)
    assert np.array_equal(first.cells["triangle"], second.cells["triangle"])
    check_mesh(second)


def test_generated_source_is_written_atomically_to_the_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("WARPMESH_CACHE_DIR", str(tmp_path))
    tape = wm.compile_tape(wm.torus(1.0, 0.3))
    src = codegen.source(tape)
    assert "eval_generated_kernel" in src and src.count("\n        r") == len(tape)
    codegen._module(tape, codegen.structure_key(tape) + "x")  # a fresh module name
    files = list(tmp_path.iterdir())
    assert [f.suffix for f in files] == [".py"]  # no temporary file left behind


def test_unknown_evaluator_is_refused():
    with pytest.raises(ValueError, match="evaluator"):
        wm.evaluate(wm.sphere(1.0), np.zeros((2, 3)), evaluator="jit")
    with pytest.raises(ValueError, match="evaluator"):
        wm.mesh_surface(wm.sphere(1.0), bounds=((-1,) * 3, (1,) * 3), resolution=8, evaluator="jit")


def test_an_unwritable_cache_fails_clearly_and_auto_keeps_interpreting(tmp_path, monkeypatch):
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("WARPMESH_CACHE_DIR", str(blocker / "cache"))
    x, y, z = wm.coords()
    shape = wm.Shape(0.6 - wm.sqrt(3 * x * x + y * y + z * z) + 0.01 * wm.cos(9 * y))  # a fresh structure
    pts = np.random.default_rng(2).uniform(-1, 1, (10, 3))
    with pytest.raises(wm.WarpMeshError, match="WARPMESH_CACHE_DIR"):
        wm.evaluate(shape, pts, evaluator="compiled")
    bounds = ((-1.0,) * 3, (1.0,) * 3)
    with pytest.warns(RuntimeWarning, match="compiling"):
        for _ in range(3):
            m = wm.mesh_surface(shape, bounds=bounds, resolution=256)
            codegen.wait()
    assert m.info["evaluator"] == "interpreter"
    check_mesh(m)


def test_evaluator_applies_to_shape_values_only():
    with pytest.raises(ValueError, match="evaluator"):
        wm.mesh_surface(np.arange(64.0).reshape(4, 4, 4), level=3.0, evaluator="compiled")
    with pytest.raises(ValueError, match="evaluator"):
        wm.evaluate(wm.sphere(1.0), np.zeros((2, 3)), gradient=True, evaluator="compiled")
