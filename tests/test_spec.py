"""The robot as data: Table 2 of the paper follows from geometry, the tree is what the file says."""

from __future__ import annotations

import csv
from importlib.resources import files

import numpy as np
import pytest

from harness.model.load import load_spec
from harness.model.spec import Cylinder
from tests.conftest import MODELS


def table2() -> dict[str, dict[str, float]]:
    text = files("harness.papers.graph_theory_2021").joinpath("reference/kr500_table2_true_parameters.csv").read_text()
    return {row["body"]: {k: float(v) for k, v in row.items() if k != "body"}
            for row in csv.DictReader(text.splitlines())}


@pytest.fixture(scope="module")
def kr500():
    return load_spec(MODELS / "kr500.toml")


@pytest.mark.parametrize("body", ["B1", "B2", "B3", "B4", "B5", "B6"])
def test_table2_reproduced_from_geometry_to_every_printed_digit(kr500, body):
    """Homogeneous steel cylinders (7801 kg/m^3) give Table 2's masses and principal moments,
    printed with 4 decimals: equality after rounding to 4 decimals is 'every printed digit'."""
    paper = table2()[body]
    b = kr500.body(body)
    assert (b.cylinder.length, b.cylinder.radius) == (paper["length_m"], paper["radius_m"])
    assert round(b.mass, 4) == paper["mass_kg"]
    J11, J22, J33 = b.principal_inertia
    assert (round(J11, 4), round(J22, 4), round(J33, 4)) == (
        paper["J11_kgm2"], paper["J22_kgm2"], paper["J33_kgm2"])


def test_cylinder_inertia_matches_integration_over_the_volume():
    """Eq. (24) against an independent computation: quadrature over the solid in cylindrical
    coordinates, Gauss-Legendre in x and r (8 points: exact for the integrands' polynomials, of degree 3 at
    most) and the midpoint rule in phi (exact for cos^2 and sin^2 with more than 2 points): round-off."""
    cyl = Cylinder(length=1.2, radius=0.3, density=7801.0)
    u, w = np.polynomial.legendre.leggauss(8)  # nodes and weights on [-1, 1]
    x, w_x = u * cyl.length / 2, w * cyl.length / 2  # along e1
    r, w_r = (u + 1) * cyl.radius / 2, w * cyl.radius / 2
    n_phi = 16
    phi = (np.arange(n_phi) + 0.5) / n_phi * 2 * np.pi
    X, Rr, P = np.meshgrid(x, r, phi, indexing="ij")
    dm = cyl.density * Rr * np.einsum("i,j->ij", w_x, w_r)[:, :, None] * (2 * np.pi / n_phi)
    Y, Z = Rr * np.cos(P), Rr * np.sin(P)
    numeric = np.array([np.sum(dm * (Y**2 + Z**2)), np.sum(dm * (X**2 + Z**2)), np.sum(dm * (X**2 + Y**2))])
    np.testing.assert_allclose(np.sum(dm), cyl.mass, rtol=1e-13)
    np.testing.assert_allclose(numeric, cyl.principal_inertia, rtol=1e-13)


def test_kr500_layout_is_the_documented_one(kr500):
    assert kr500.joint_names == ["rail", "O1", "O2", "O3", "O4", "O5", "O6"]
    assert kr500.body("carriage").massless
    B1 = kr500.body("B1")
    np.testing.assert_array_equal(B1.R_WB0, [[0, 0, -1], [0, 1, 0], [1, 0, 0]])  # e3(1) = -x
    for name in ["B2", "B3", "B4", "B5", "B6"]:
        np.testing.assert_array_equal(kr500.body(name).R_WB0, np.eye(3))
    # O_i at the inner end of B_i, centre of mass at the geometric centre
    for j in kr500.joints[1:]:
        child = kr500.body(j.child)
        np.testing.assert_allclose(child.p_W_com0 - j.p_W0, child.cylinder.length / 2 * child.R_WB0[:, 0],
                                   atol=1e-15)
    # O2 turns about e2, O4 and O6 about e1, O1 about e1 of B1 (vertical)
    np.testing.assert_array_equal(kr500.joint("O1").axis_W0, [0, 0, 1])
    for name, k in [("O2", 1), ("O3", 1), ("O4", 0), ("O5", 1), ("O6", 0)]:
        j = kr500.joint(name)
        np.testing.assert_array_equal(j.axis_W0, kr500.body(j.child).R_WB0[:, k])


def test_outboard_bodies_follow_the_tree(kr500):
    assert [b.name for b in kr500.outboard_bodies("O3")] == ["B3", "B4", "B5", "B6"]
    assert [b.name for b in kr500.outboard_bodies("rail")] == ["carriage", "B1", "B2", "B3", "B4",
                                                               "B5", "B6"]
