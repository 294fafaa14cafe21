"""The shared least-squares tools: tangent basis, Huber weights, Levenberg-Marquardt, covariance."""

from __future__ import annotations

import numpy as np
import pytest

from ppo_cv.lsq import (
    cross_matrices,
    cross_matrix,
    forward_jacobian,
    forward_jacobian_stacked,
    gauss_newton_covariance,
    huber_weights,
    levenberg_marquardt,
    levenberg_marquardt_batched,
    stacked_jacobian,
    tangent_basis,
)


def test_tangent_basis_is_orthonormal_and_orthogonal_to_n():
    rng = np.random.default_rng(0)
    for n in [np.eye(3)[2], *rng.normal(size=(20, 3))]:
        n = n / np.linalg.norm(n)
        basis = np.vstack([n, tangent_basis(n)])
        np.testing.assert_allclose(basis @ basis.T, np.eye(3), atol=1e-12)


def test_huber_weights_give_the_huber_cost():
    size, scale = np.array([0.0, 0.5, 1.0, 3.0, 10.0]), 1.0
    huber = np.where(size <= scale, size**2, 2 * scale * size - scale**2)
    np.testing.assert_allclose((huber_weights(size, scale) * size) ** 2, huber, atol=1e-12)


def test_levenberg_marquardt_solves_a_nonlinear_fit():
    x = np.linspace(0.0, 2.0, 30)
    y = 2.0 * np.exp(-1.5 * x)

    def residuals(p):
        return p[0] * np.exp(-p[1] * x) - y

    p, J = levenberg_marquardt(residuals, np.array([1.0, 0.5]), 50)
    np.testing.assert_allclose(p, [2.0, 1.5], atol=1e-6)
    np.testing.assert_allclose(J, forward_jacobian(residuals, p, residuals(p)), atol=1e-12)
    assert J[:, 0] == pytest.approx(np.exp(-1.5 * x), abs=1e-5)


def test_tangent_basis_is_the_cross_products_numpy_takes():
    rng = np.random.default_rng(1)
    for n in rng.normal(size=(200, 3)):
        n = n / np.linalg.norm(n)
        a = np.cross(n, np.eye(3)[int(np.argmin(np.abs(n)))])
        a /= np.linalg.norm(a)
        assert np.array_equal(tangent_basis(n), np.array([a, np.cross(n, a)]))


def test_levenberg_marquardt_with_stacked_jacobians_takes_the_same_steps():
    x = np.linspace(0.0, 2.0, 30)
    y = 2.0 * np.exp(-1.5 * x) + 0.01 * np.sin(7 * x)

    def many(P):
        return P[:, :1] * np.exp(-P[:, 1:2] * x) - y

    def one(p):
        return many(p[None])[0]

    start = np.array([1.0, 0.5])
    stacked = forward_jacobian_stacked(many, start, one(start))
    assert np.array_equal(stacked, forward_jacobian(one, start, one(start)))
    assert stacked.flags["C_CONTIGUOUS"]
    p, J = levenberg_marquardt(one, start, 50)
    p_stacked, J_stacked = levenberg_marquardt(one, start, 50, many=many)
    assert np.array_equal(p_stacked, p) and np.array_equal(J_stacked, J)
    np.testing.assert_allclose(p, [2.0, 1.5], atol=0.02)


def test_the_two_stacked_jacobians_are_one_computation():
    x = np.linspace(0.0, 2.0, 30)
    calls = []

    def many(P):
        calls.append(len(P))
        return P[:, :1] * np.exp(-P[:, 1:2] * x) - 2.0 * np.exp(-1.5 * x)

    start = np.array([1.0, 0.5])
    r0, J = stacked_jacobian(many, start)
    known_r0, known_J = stacked_jacobian(many, start, r0=r0)
    given = forward_jacobian_stacked(many, start, r0)
    assert calls == [3, 2, 2]
    assert np.array_equal(r0, many(start[None])[0]) and known_r0 is r0
    assert np.array_equal(known_J, J) and np.array_equal(given, J)
    assert J.flags["F_CONTIGUOUS"] and given.flags["C_CONTIGUOUS"]


def test_batched_levenberg_marquardt_takes_each_problem_to_its_own_minimum():
    x = np.linspace(0.0, 2.0, 30)
    truths = np.array([[2.0, 1.5], [0.5, 0.2], [3.0, 4.0], [1.0, 0.5]])
    y = truths[:, :1] * np.exp(-truths[:, 1:] * x) + 0.01 * np.outer([0, 1, 2, 0], np.sin(7 * x))
    starts = np.array([[1.0, 0.5], [1.0, 0.5], [1.0, 0.5], [1.0, 0.5]])

    def many(P, rows):
        return P[:, :1] * np.exp(-P[:, 1:2] * x) - y[rows]

    found = levenberg_marquardt_batched(many, starts, 50)
    for row in range(len(truths)):
        alone, _ = levenberg_marquardt(lambda p, r=row: many(p[None], [r])[0], starts[row], 50)
        np.testing.assert_allclose(found[row], alone, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(found[:1], truths[:1], atol=0.02)
    np.testing.assert_array_equal(found[3], starts[3])  # already at its minimum: no step lowers it


def test_gauss_newton_covariance_of_a_line_fit():
    # y = a + b x with noise sigma: the textbook covariance sigma^2 (X^T X)^-1
    rng = np.random.default_rng(3)
    x = rng.uniform(-1, 1, 200)
    J = np.column_stack([np.ones_like(x), x])
    cov = gauss_newton_covariance(J, 0.25)
    expected = 0.25 * np.array([[x.size, x.sum()], [x.sum(), x @ x]])
    np.testing.assert_allclose(cov @ expected, 0.25**2 * np.eye(2), atol=1e-12)
    assert gauss_newton_covariance(np.ones((200, 2)), 1.0) is None  # singular J^T J


def test_cross_matrices_give_the_cross_product():
    rng = np.random.default_rng(3)
    v, u = rng.normal(size=(5, 3)), rng.normal(size=(5, 3))
    K = cross_matrices(v)
    assert np.allclose(K @ u[:, :, None], np.cross(v, u)[:, :, None])
    assert np.allclose(K, -np.swapaxes(K, 1, 2))
    assert np.allclose(cross_matrix(v[0]) @ u[0], np.cross(v[0], u[0]))


def test_rotation_increment_is_rodrigues():
    import cv2

    from ppo_cv.lsq import rotation_increment

    for w in (np.array([0.3, -0.2, 0.5]), np.array([1e-9, 0.0, 0.0]), np.zeros(3)):
        np.testing.assert_allclose(rotation_increment(w), cv2.Rodrigues(w)[0], atol=1e-12)


def test_rotation_increments_are_rodrigues_row_by_row():
    import cv2

    from ppo_cv.lsq import rotation_increments

    w = np.vstack([np.random.default_rng(2).normal(0, 0.8, (20, 3)), [1e-13, 0, 0], np.zeros(3)])
    stacked = rotation_increments(w)
    assert stacked.shape == (22, 3, 3)
    for row, R in zip(w, stacked, strict=True):
        np.testing.assert_allclose(R, cv2.Rodrigues(row)[0], atol=1e-12)


def test_row_chunks_cover_every_row_once_in_chunks_of_about_the_budget():
    from ppo_cv.lsq import CHUNK_VALUES, row_chunks

    for count, width in [(96, 581), (144, 256), (7, 30), (5, 10 * CHUNK_VALUES), (0, 50)]:
        chunks = row_chunks(count, width)
        rows = np.concatenate([np.arange(count)[s] for s in chunks] or [np.empty(0, int)])
        assert np.array_equal(rows, np.arange(count))
        assert all(s.stop - s.start >= 1 for s in chunks)
        assert all((s.stop - s.start) * width <= max(CHUNK_VALUES, width) for s in chunks)
    assert len(row_chunks(96, 581)) > 1 and len(row_chunks(7, 581)) == 1


def test_one_rotation_increment_and_cross_matrix_are_the_stacked_ones_to_the_bit():
    from ppo_cv.lsq import rotation_increment, rotation_increments

    rng = np.random.default_rng(5)
    w = rng.normal(size=(300, 3)) * 10.0 ** rng.uniform(-14, 0.5, (300, 1))
    w[::7, 1] = 0.0
    for row in np.vstack([w, np.zeros(3)]):
        assert np.array_equal(rotation_increment(row), rotation_increments(row[None])[0])
        assert np.array_equal(cross_matrix(row), cross_matrices(row[None])[0])
