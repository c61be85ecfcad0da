"""``Mesh`` methods spell out the options of the function they call (no bare ``**options``),
so ``help()`` and completion show them; this keeps the two signatures from drifting."""

from __future__ import annotations

import inspect

import pytest

from warpmesh import mesh as M
from warpmesh.mesh import Mesh

#: method -> the functions it calls (their parameters after the mesh), and what the method
#: leaves out on purpose
PAIRS = {
    "optimize": ([M.optimize], ()),
    "simplify": ([M.simplify], ()),
    "to_order": ([M.to_order], ("stacklevel",)),  # the method passes its caller's
    "renumber": ([M.renumber], ()),
    "color_elements": ([M.color_mesh], ()),
    "transform": ([M.transform], ()),
    "refine": ([M.refine_uniform, M.refine_local], ()),
    "convert": ([M.convert_cells], ()),
    "merge": ([M.merge], ()),
    "crack": ([M.crack], ()),
    "periodic": ([M.periodic], ()),
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
