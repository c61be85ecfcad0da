"""``Mesh`` methods spell out the options of the function they call (no bare ``**options``),
so ``help()`` and completion show them; this keeps the two signatures from drifting."""

from __future__ import annotations

import inspect

import pytest

from warpmesh.mesh import Mesh
from warpmesh.modify.convert_cells import convert_cells
from warpmesh.modify.crack import crack
from warpmesh.modify.merge import merge
from warpmesh.modify.periodic import periodic
from warpmesh.modify.refine_local import refine_local
from warpmesh.modify.refine_uniform import refine_uniform
from warpmesh.modify.transforms import transform
from warpmesh.numbering.coloring import color_mesh
from warpmesh.numbering.high_order import to_order
from warpmesh.numbering.renumber import renumber
from warpmesh.optimize.remesh import optimize, simplify

#: method -> the functions it calls (their parameters after the mesh), and what the method
#: leaves out on purpose
PAIRS = {
    "optimize": ([optimize], ()),
    "simplify": ([simplify], ()),
    "to_order": ([to_order], ("stacklevel",)),  # the method passes its caller's
    "renumber": ([renumber], ()),
    "color_elements": ([color_mesh], ()),
    "transform": ([transform], ()),
    "refine": ([refine_uniform, refine_local], ()),
    "convert": ([convert_cells], ()),
    "merge": ([merge], ()),
    "crack": ([crack], ()),
    "periodic": ([periodic], ()),
}


def _params(fn, skip=()):
    ps = list(inspect.signature(fn).parameters.values())[1:]  # after self / the mesh
    return {p.name: p for p in ps if p.name not in skip}


@pytest.mark.parametrize("name", sorted(PAIRS))
def test_method_spells_out_the_options(name):
    method = _params(getattr(Mesh, name))
    assert not any(p.kind in (p.VAR_KEYWORD, p.VAR_POSITIONAL) for p in method.values()), name
    functions, skip = PAIRS[name]
    if name == "merge":  # merge(a, b, ...) is other.merge's (self, other, ...): the second mesh renamed
        method = {("b" if k == "other" else k): p for k, p in method.items()}
    expected = {}
    for fn in functions:
        expected.update(_params(fn, skip))
    assert set(method) == set(expected), (name, set(method) ^ set(expected))
    for key, p in method.items():
        q = expected[key]
        if len(functions) == 1:  # one target: the same defaults and kinds
            assert p.default == q.default, (name, key, p.default, q.default)
            assert (p.kind == p.KEYWORD_ONLY) == (q.kind == q.KEYWORD_ONLY), (name, key)


def test_no_method_of_mesh_hides_its_options():
    hidden = [n for n, f in vars(Mesh).items() if callable(f) and not n.startswith("_") and n != "replace"
              and any(p.kind == p.VAR_KEYWORD for p in inspect.signature(f).parameters.values())]
    assert hidden == []


def test_refine_refuses_an_option_of_the_other_kind():
    m = Mesh([[0, 0], [1, 0], [0, 1]], {"triangle": [[0, 1, 2]]})
    with pytest.raises(ValueError, match="'max_rounds' applies to local refinement"):
        m.refine(2, max_rounds=3)
    with pytest.raises(ValueError, match="'bounds' and 'tetra_diagonal' apply to uniform refinement"):
        m.refine(max_length=0.5, tetra_diagonal="fixed")
    assert m.refine(max_length=0.5, max_rounds=8).n_cells > 1
