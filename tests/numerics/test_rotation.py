"""alight.numerics.rotation: quaternions (x, y, z, w, Hamilton) against SciPy, round trips, the kernels
against their Python twins bit for bit, and wrap_angle's boundaries exactly."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from alight.numerics.rotation import (
    TWO_PI,
    R_to_quat,
    quat_exp,
    quat_log,
    quat_mul,
    quat_to_R,
    quat_to_R_scaled,
    quat_to_rotmat,
    rot_z,
    rotmat_entries,
    rotmat_to_quat,
    unit_quats_to_rotmats,
    wrap_angle,
    wrap_period,
    yaw_of,
    yaw_of_quat,
)


def random_quats(n: int, seed: int = 0) -> np.ndarray:
    """n random quaternions, not normalised, with the awkward ones of Shepperd's method appended:
    half turns about each axis (trace -1) and w = 0."""
    q = np.random.default_rng(seed).normal(size=(n, 4))
    special = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0], [0, 0, 0, 1.0], [0.6, 0.8, 0, 0]])
    return np.vstack([q, special, -special])


QUATS = random_quats(200)


def _old_quat_to_rotmat(q: np.ndarray) -> np.ndarray:
    # the arithmetic the former copies (types.py, rotation_kernels.py) used, kept here as the reference
    x, y, z, w = q.tolist()
    n = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def test_the_rotation_matrix_is_scipys() -> None:
    # SciPy stores quaternions scalar last, as alight does, and normalises them
    for q in QUATS:
        np.testing.assert_allclose(quat_to_rotmat(q), Rotation.from_quat(q).as_matrix(), rtol=0, atol=1e-15)


def test_the_rotation_matrix_is_orthonormal_with_determinant_one() -> None:
    for q in QUATS:
        R = quat_to_rotmat(q)
        np.testing.assert_allclose(R @ R.T, np.eye(3), rtol=0, atol=4e-15)
        assert np.linalg.det(R) == pytest.approx(1.0, abs=4e-15)


def test_the_kernel_its_python_twin_and_the_former_copies_agree_bit_for_bit() -> None:
    for q in QUATS:
        R = np.empty((3, 3))
        quat_to_R(np.ascontiguousarray(q), R)
        assert np.array_equal(R, quat_to_rotmat(q))
        assert np.array_equal(R, _old_quat_to_rotmat(q))


def test_the_scaled_form_rotates_any_nonzero_quaternion() -> None:
    # s = 2 / |q|^2 (the rigid-body model's form) is the rotation of q without normalising it
    for q in QUATS:
        R = np.empty((3, 3))
        quat_to_R_scaled(q[0], q[1], q[2], q[3], 2.0 / float(q @ q), R)
        np.testing.assert_allclose(R, quat_to_rotmat(q), rtol=0, atol=2e-15)


def test_unit_quaternions_in_bulk_are_the_entries_of_each() -> None:
    q = QUATS / np.linalg.norm(QUATS, axis=1, keepdims=True)
    Rs = unit_quats_to_rotmats(q)
    for k in range(q.shape[0]):
        e = rotmat_entries(q[k, 0], q[k, 1], q[k, 2], q[k, 3], 2.0)
        assert np.array_equal(Rs[k], np.array(e).reshape(3, 3))


def test_matrix_to_quaternion_round_trips_up_to_sign_with_w_non_negative() -> None:
    for q in QUATS:
        u = q / np.linalg.norm(q)
        back = rotmat_to_quat(quat_to_rotmat(q))
        assert back[3] >= 0.0
        assert np.linalg.norm(back) == pytest.approx(1.0, abs=1e-15)
        assert min(np.abs(back - u).max(), np.abs(back + u).max()) < 1e-14
        expected = Rotation.from_quat(q).as_quat()
        assert min(np.abs(back - expected).max(), np.abs(back + expected).max()) < 1e-14


def test_matrix_to_quaternion_kernel_and_python_agree_bit_for_bit() -> None:
    for q in QUATS:
        R = quat_to_rotmat(q)
        out = np.empty(4)
        R_to_quat(R, out)
        assert np.array_equal(out, rotmat_to_quat(R))


def test_the_product_is_hamiltons_and_composes_rotations() -> None:
    rng = np.random.default_rng(3)
    for _ in range(50):
        a, b = rng.normal(size=4), rng.normal(size=4)
        a /= np.linalg.norm(a)
        b /= np.linalg.norm(b)
        ab = np.empty(4)
        quat_mul(a, b, ab)
        np.testing.assert_allclose(quat_to_rotmat(ab), quat_to_rotmat(a) @ quat_to_rotmat(b), atol=1e-15)
        expected = (Rotation.from_quat(a) * Rotation.from_quat(b)).as_quat(canonical=False)
        assert min(np.abs(ab - expected).max(), np.abs(ab + expected).max()) < 1e-15
    # i j = k
    k = np.empty(4)
    quat_mul(np.array([1.0, 0, 0, 0]), np.array([0, 1.0, 0, 0]), k)
    assert np.array_equal(k, [0.0, 0.0, 1.0, 0.0])


def test_exp_and_log_are_scipys_rotation_vector_and_inverse() -> None:
    rng = np.random.default_rng(4)
    for phi in [*rng.normal(size=(50, 3)), np.zeros(3), np.array([1e-10, 0, 0])]:
        q = np.empty(4)
        quat_exp(phi, q)
        expected = Rotation.from_rotvec(phi).as_quat()
        assert min(np.abs(q - expected).max(), np.abs(q + expected).max()) < 1e-15
        back = np.empty(3)
        quat_log(q, back)
        if np.linalg.norm(phi) < math.pi:
            np.testing.assert_allclose(back, phi, rtol=0, atol=1e-14)


def test_yaw_of_a_quaternion_is_yaw_of_its_matrix_bit_for_bit() -> None:
    for q in QUATS:
        assert yaw_of_quat(q) == yaw_of(quat_to_rotmat(q))
    for psi in np.linspace(-3.1, 3.1, 25):
        assert yaw_of(rot_z(psi)) == pytest.approx(psi, abs=1e-15)
        assert yaw_of(rot_z(psi)) == pytest.approx(Rotation.from_matrix(rot_z(psi)).as_euler("ZYX")[0])


def test_wrap_angle_boundaries_exactly() -> None:
    pi = math.pi
    assert wrap_angle(pi) == -pi  # [-pi, pi): pi itself is -pi
    assert wrap_angle(-pi) == -pi
    assert wrap_angle(3 * pi) == -pi
    assert wrap_angle(-3 * pi) == -pi
    assert wrap_angle(0.0) == 0.0
    assert wrap_angle(TWO_PI) == 0.0
    assert wrap_angle(-TWO_PI) == 0.0
    below = math.nextafter(pi, 0.0)
    assert -pi <= wrap_angle(below) < pi
    above = math.nextafter(-pi, 0.0)
    assert wrap_angle(above) == above


def test_wrap_angle_stays_in_range_and_is_congruent() -> None:
    a = np.concatenate([np.random.default_rng(5).uniform(-50, 50, 5000), np.arange(-20, 21) * math.pi])
    w = wrap_angle(a)
    assert ((w >= -math.pi) & (w < math.pi)).all()
    k = (a - w) / TWO_PI
    np.testing.assert_allclose(k, np.round(k), rtol=0, atol=1e-13)


def test_wrap_angle_on_floats_arrays_and_in_kernels_agree_bit_for_bit() -> None:
    a = np.concatenate([np.random.default_rng(6).uniform(-20, 20, 500), np.arange(-6, 7) * math.pi])
    w = wrap_angle(a)
    for k in range(a.shape[0]):
        x = float(a[k])
        assert wrap_angle(x) == w[k] == wrap_period(x, TWO_PI)
        assert wrap_angle(x) == (x + math.pi) % (2 * math.pi) - math.pi  # the former copies' arithmetic


def test_wrap_period_folds_a_pad_yaw() -> None:
    quarter = TWO_PI / 4
    assert wrap_period(math.pi / 4, quarter) == -math.pi / 4  # the boundary: [-pi/4, pi/4)
    assert wrap_period(0.3 + 3 * quarter, quarter) == pytest.approx(0.3, abs=1e-15)
    assert wrap_period.py_func(1.0, quarter) == wrap_period(1.0, quarter)


def test_why_the_nfold_detector_keeps_its_own_wrap() -> None:
    """perception/nfold.py wraps to (-pi, pi] by ``a - 2 pi floor((a + pi) / 2 pi)``, the identity on an
    angle already in range; wrap_angle's ``(a + pi) % 2 pi - pi`` rounds such an angle to pi's ulp. The
    marker's yaw would change in its last bits, and with it the zamanakos_sdu missions, so it stays."""
    from alight.perception.nfold import _wrap, _wrap_pi

    # (not rng.uniform(-pi, pi): its draws are -pi + 2 pi u, exactly the numbers that (a + pi) - pi restores)
    a = np.linspace(-3.1, 3.1, 2000)
    assert all(_wrap(x) == x and _wrap_pi(x) == x for x in a)
    assert sum(wrap_angle(float(x)) != x for x in a) > 100  # many are moved by an ulp (722 of 2000)
    assert wrap_angle(0.3) != 0.3
    assert _wrap(math.pi) == _wrap_pi(math.pi) == math.pi and wrap_angle(math.pi) == -math.pi
