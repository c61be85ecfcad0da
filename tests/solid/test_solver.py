"""A real solver as the judge: -Δu = 6 on the unit ball, u = 1 - r² (u = 0 on r = 1), solved
with scikit-fem on stuffed tetrahedra of three sizes; the L2 error must fall at the rate of
the elements (P1: 2, P2 on tetrahedra whose boundary nodes lie on the sphere: 3)."""

from __future__ import annotations

import numpy as np
import pytest

import warpmesh as wm

skfem = pytest.importorskip("skfem")
from skfem import Basis, BilinearForm, ElementTetP1, ElementTetP2, Functional, LinearForm, MeshTet  # noqa: E402
from skfem import asm, condense, solve  # noqa: E402
from skfem.helpers import dot, grad  # noqa: E402
from skfem.io.meshio import from_meshio  # noqa: E402


@BilinearForm
def _laplace(u, v, w):
    return dot(grad(u), grad(v))


@LinearForm
def _load(v, w):
    return 6.0 * v


@Functional
def _l2(w):
    return (w["uh"] - (1.0 - (w.x[0] ** 2 + w.x[1] ** 2 + w.x[2] ** 2))) ** 2


def _error(h: float, order: int) -> float:
    shape = wm.sphere(1.0)
    vol = wm.mesh_domain(shape, bounds=((-1.1,) * 3, (1.1,) * 3), size=h)
    if order == 1:
        mesh, element = MeshTet(vol.points.T.copy(), vol.cells["tetra"].T.copy()), ElementTetP1()
    else:
        mesh, element = from_meshio(vol.to_order(2, shape).to_meshio()), ElementTetP2()
    basis = Basis(mesh, element, intorder=6)
    u = solve(*condense(asm(_laplace, basis), asm(_load, basis), D=basis.get_dofs()))
    return float(np.sqrt(_l2.assemble(basis, uh=basis.interpolate(u))))


@pytest.mark.parametrize("order, sizes, rate", [(1, (0.4, 0.2, 0.1), 1.8), (2, (0.45, 0.3, 0.2), 2.7)])
def test_poisson_on_the_ball_converges(order, sizes, rate, capsys):
    errors = np.array([_error(h, order) for h in sizes])
    rates = np.log(errors[:-1] / errors[1:]) / np.log(np.array(sizes[:-1]) / np.array(sizes[1:]))
    with capsys.disabled():
        print(f"\nP{order}: sizes {sizes}, L2 errors {errors.tolist()}, rates {rates.round(2).tolist()}")
    assert (rates >= rate).all(), rates
