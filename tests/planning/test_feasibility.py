"""Input and floor feasibility verdicts against dense sampling and against independent references.

Sampling can miss a violation that lives between two samples, so where a verdict says "infeasible" the
samples are only required to come within a Lipschitz bound of the limit: the thrust |acc - g| changes at
most at the rate max|jerk|, so with spacing h the sampled extremum is within h/2 * max|jerk| of the true
one (likewise the plane distance with max|d'|). Where a verdict says "feasible" there is no slack.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from alight.planning.min_jerk import (
    EndConstraint,
    InputFeasibility,
    floor_feasibility,
    input_feasibility,
    min_jerk_coefficients,
)

F_MIN, F_MAX, W_MAX, MIN_SECTION = 2.81485, 16.33365, 6.0, 0.02
G = np.array([0.0, 0.0, -9.81])
N_CASES = 10_000
N_SAMPLES = 1001


def _cases(rng: np.random.Generator, n: int):
    """Random starts and ends over all three end-constraint modes; a tenth start near free fall so that
    the thrust-low verdict is well represented."""
    p0 = np.array([0.0, 0.0, 5.0]) + rng.normal(0.0, 1.0, (n, 3))
    v0 = rng.normal(0.0, 2.0, (n, 3))
    a0 = rng.normal(0.0, 2.0, (n, 3))
    falling = rng.random(n) < 0.1
    a0[falling] = G + rng.normal(0.0, 1.0, (falling.sum(), 3))
    T = rng.uniform(0.3, 5.0, n)
    pf = p0 + rng.normal(0.0, 6.0, (n, 3))
    vf = rng.normal(0.0, 3.0, (n, 3))
    af = rng.normal(0.0, 3.0, (n, 3))
    alpha, beta, gamma = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))
    modes = rng.integers(0, 3, n)
    for m in EndConstraint:
        sel = modes == m
        al, be, ga = min_jerk_coefficients(p0[sel], v0[sel], a0[sel], T[sel], pf[sel], vf[sel], af[sel], m)
        alpha[sel], beta[sel], gamma[sel] = al, be, ga
    return p0, v0, a0, T, alpha, beta, gamma


def _dense(a0, T, alpha, beta, gamma, n_samples):
    """Thrust f = |acc - g| and |jerk| at n_samples evenly spaced times on [0, T] (ends included)."""
    t = T[:, None] * np.linspace(0.0, 1.0, n_samples)[None, :]
    f2 = np.zeros_like(t)
    j2 = np.zeros_like(t)
    for k in range(3):
        al, be, ga = alpha[:, k : k + 1], beta[:, k : k + 1], gamma[:, k : k + 1]
        acc = a0[:, k : k + 1] + ga * t + be * t**2 / 2 + al * t**3 / 6 - G[k]
        jerk = ga + be * t + al * t**2 / 2
        f2 += acc**2
        j2 += jerk**2
    return np.sqrt(f2), np.sqrt(j2)


def _max_jerk(T, alpha, beta, gamma):
    """Exact bound max_t |jerk(t)| <= sqrt(sum_k max_t jerk_k^2) over [0, T]."""
    total = np.zeros(T.size)
    for k in range(3):
        al, be, ga = alpha[:, k], beta[:, k], gamma[:, k]
        cand = [ga**2, (ga + be * T + al * T**2 / 2) ** 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            te = np.where(al != 0, -be / al, -1.0)
        inside = (te > 0) & (te < T)
        cand.append(np.where(inside, (ga + be * te + al * te**2 / 2) ** 2, 0.0))
        total += np.max(cand, axis=0)
    return np.sqrt(total)


def test_input_verdicts_agree_with_dense_sampling() -> None:
    rng = np.random.default_rng(10)
    p0, v0, a0, T, alpha, beta, gamma = _cases(rng, N_CASES)
    codes = input_feasibility(
        a0, alpha, beta, gamma, T, f_min=F_MIN, f_max=F_MAX, w_max=W_MAX, min_section_s=MIN_SECTION
    )
    counts = np.bincount(codes, minlength=4)
    # every verdict must be well represented, or this test proves little
    assert counts[InputFeasibility.FEASIBLE] > 2000
    assert counts[InputFeasibility.INFEASIBLE_THRUST_HIGH] > 2000
    assert counts[InputFeasibility.INFEASIBLE_THRUST_LOW] > 200
    assert counts[InputFeasibility.INDETERMINABLE] > 50
    for chunk in np.array_split(np.arange(N_CASES), 10):
        f, jn = _dense(a0[chunk], T[chunk], alpha[chunk], beta[chunk], gamma[chunk], N_SAMPLES)
        c = codes[chunk]
        ok = c == InputFeasibility.FEASIBLE
        # proven feasible: no sample outside the limits (float rounding only)
        assert (f[ok] <= F_MAX * (1 + 1e-12)).all()
        assert (f[ok] >= F_MIN * (1 - 1e-12)).all()
        assert (jn[ok] <= W_MAX * f[ok] * (1 + 1e-12)).all()
        # proven infeasible: the samples reach the violated limit within the Lipschitz bound
        slack = (
            0.5 * T[chunk] / (N_SAMPLES - 1) * _max_jerk(T[chunk], alpha[chunk], beta[chunk], gamma[chunk])
        )
        high = c == InputFeasibility.INFEASIBLE_THRUST_HIGH
        low = c == InputFeasibility.INFEASIBLE_THRUST_LOW
        assert (f[high].max(axis=1) > F_MAX - slack[high] - 1e-12).all()
        assert (f[low].min(axis=1) < F_MIN + slack[low] + 1e-12).all()


# ---- an independent transcription of the sheet's recursion (plain recursion, textbook quadratic formula)


def _poly(c, t):
    return sum(ck * t**i for i, ck in enumerate(c))


def _reference_section(a0, al, be, ga, t1, t2):
    if t2 - t1 < MIN_SECTION:
        return InputFeasibility.INDETERMINABLE
    acc = [[a0[k] - G[k], ga[k], be[k] / 2, al[k] / 6] for k in range(3)]
    jerk = [[ga[k], be[k], al[k] / 2] for k in range(3)]
    f_ends = [math.sqrt(sum(_poly(acc[k], t) ** 2 for k in range(3))) for t in (t1, t2)]
    if max(f_ends) > F_MAX:
        return InputFeasibility.INFEASIBLE_THRUST_HIGH
    if min(f_ends) < F_MIN:
        return InputFeasibility.INFEASIBLE_THRUST_LOW
    up2 = lo2 = j2 = 0.0
    for k in range(3):
        times = [t1, t2]
        a, b, c = al[k] / 2, be[k], ga[k]
        if a != 0:
            disc = b * b - 4 * a * c
            if disc >= 0:
                times += [(-b + math.sqrt(disc)) / (2 * a), (-b - math.sqrt(disc)) / (2 * a)]
        elif b != 0:
            times.append(-c / b)
        vals = [_poly(acc[k], t) for t in times if t1 <= t <= t2]
        lo, hi = min(vals), max(vals)
        if max(abs(lo), abs(hi)) > F_MAX:
            return InputFeasibility.INFEASIBLE_THRUST_HIGH
        up2 += max(lo * lo, hi * hi)
        lo2 += 0.0 if lo <= 0 <= hi else min(lo * lo, hi * hi)
        jt = [t1, t2] + ([-be[k] / al[k]] if al[k] != 0 and t1 < -be[k] / al[k] < t2 else [])
        j2 += max(_poly(jerk[k], t) ** 2 for t in jt)
    if math.sqrt(up2) < F_MIN:
        return InputFeasibility.INFEASIBLE_THRUST_LOW
    if math.sqrt(lo2) > F_MAX:
        return InputFeasibility.INFEASIBLE_THRUST_HIGH
    rate = math.inf if lo2 <= 1e-12 else math.sqrt(j2 / lo2)
    if not (F_MIN <= math.sqrt(lo2) and math.sqrt(up2) <= F_MAX) or rate > W_MAX:
        tm = 0.5 * (t1 + t2)
        first = _reference_section(a0, al, be, ga, t1, tm)
        if first == InputFeasibility.FEASIBLE:
            return _reference_section(a0, al, be, ga, tm, t2)
        return first
    return InputFeasibility.FEASIBLE


def test_input_verdicts_agree_with_recursive_reference() -> None:
    rng = np.random.default_rng(11)
    n = 1500
    p0, v0, a0, T, alpha, beta, gamma = _cases(rng, n)
    codes = input_feasibility(
        a0, alpha, beta, gamma, T, f_min=F_MIN, f_max=F_MAX, w_max=W_MAX, min_section_s=MIN_SECTION
    )
    ref = np.array([_reference_section(a0[i], alpha[i], beta[i], gamma[i], 0.0, T[i]) for i in range(n)])
    np.testing.assert_array_equal(codes, ref)
    assert len(set(ref.tolist())) == 4


def test_input_feasible_cases_need_splitting() -> None:
    """A gentle trajectory is feasible on [0, T] at once; the rate bound over a long, wide section is loose,
    so some feasible verdicts only come after splitting. Both kinds appear in the random set."""
    z = np.zeros((1, 3))
    code = input_feasibility(
        np.zeros(3), z, z, z, np.array([2.0]), f_min=F_MIN, f_max=F_MAX, w_max=W_MAX, min_section_s=0.02
    )
    assert code[0] == InputFeasibility.FEASIBLE  # hover
    code = input_feasibility(
        G, z, z, z, np.array([2.0]), f_min=F_MIN, f_max=F_MAX, w_max=W_MAX, min_section_s=0.02
    )
    assert code[0] == InputFeasibility.INFEASIBLE_THRUST_LOW  # free fall
    code = input_feasibility(
        np.zeros(3), z, z, z, np.array([0.01]), f_min=F_MIN, f_max=F_MAX, w_max=W_MAX, min_section_s=0.02
    )
    assert code[0] == InputFeasibility.INDETERMINABLE  # shorter than a section


# ---- floor test


def _floor_cases(rng: np.random.Generator, n: int):
    p0 = np.column_stack([rng.normal(0, 2, n), rng.normal(0, 2, n), rng.uniform(0.55, 4.0, n)])
    v0 = rng.normal(0.0, 2.0, (n, 3))
    a0 = rng.normal(0.0, 2.0, (n, 3))
    T = rng.uniform(0.3, 5.0, n)
    pf = np.column_stack([rng.normal(0, 5, n), rng.normal(0, 5, n), rng.uniform(0.3, 3.0, n)])
    vf = rng.normal(0.0, 2.0, (n, 3))
    al, be, ga = min_jerk_coefficients(p0, v0, a0, T, pf, vf, mode=EndConstraint.POS_VEL)
    return p0, v0, a0, T, al, be, ga


def _distance_poly(p0, v0, a0, al, be, ga, q, nrm):
    """Ascending coefficients (n, 6) of d(t) = n . (pos(t) - q)."""
    return np.column_stack(
        [(p0 - q) @ nrm, v0 @ nrm, a0 @ nrm / 2, ga @ nrm / 6, be @ nrm / 24, al @ nrm / 120]
    )


@pytest.mark.parametrize("tilted", [False, True])
def test_floor_verdicts_agree_with_dense_sampling_and_eigenvalue_roots(tilted: bool) -> None:
    rng = np.random.default_rng(12 + tilted)
    p0, v0, a0, T, al, be, ga = _floor_cases(rng, N_CASES)
    q = np.array([0.3, -0.2, 0.5])
    nrm = np.array([0.2, -0.1, 1.0]) if tilted else np.array([0.0, 0.0, 1.0])
    nrm = nrm / np.linalg.norm(nrm)
    ok = floor_feasibility(p0, v0, a0, al, be, ga, T, point=q, normal=nrm * 3.0)
    c = _distance_poly(p0, v0, a0, al, be, ga, q, nrm)

    # dense sampling
    t = T[:, None] * np.linspace(0.0, 1.0, N_SAMPLES)[None, :]
    d = np.zeros_like(t)
    for k in range(5, -1, -1):
        d = d * t + c[:, k : k + 1]
    dmin = d.min(axis=1)
    dprime_max = sum(abs(k * c[:, k]) * T ** (k - 1) for k in range(1, 6))  # bound on |d'| over [0, T]
    slack = 0.5 * T / (N_SAMPLES - 1) * dprime_max
    assert (dmin[ok] > 0.0).all()
    assert (dmin[~ok] <= slack[~ok] + 1e-12).all()

    # reference: real roots of d' (companion-matrix eigenvalues) inside (0, T)
    dp = c[:, 1:] * np.arange(1, 6)  # ascending coefficients of d'
    lead = dp[:, 4:5]
    comp = np.zeros((N_CASES, 4, 4))
    comp[:, 1:, :3] = np.eye(3)
    comp[:, :, 3] = -dp[:, :4] / lead
    roots = np.linalg.eigvals(comp)
    real = np.abs(roots.imag) <= 1e-7 * (1 + np.abs(roots.real))
    inside = real & (roots.real > 0) & (roots.real < T[:, None])
    r = np.where(inside, roots.real, 0.0)
    dr = np.zeros_like(r)
    for k in range(5, -1, -1):
        dr = dr * r + c[:, k : k + 1]
    d_end = d[:, -1]
    crit = np.where(inside, dr, np.inf).min(axis=1)
    ref_min = np.minimum(np.minimum(c[:, 0], d_end), crit)
    ref_ok = ref_min > 0
    decided = np.abs(ref_min) > 1e-7  # touching within rounding: measure zero, not decided here
    np.testing.assert_array_equal(ok[decided], ref_ok[decided])
    assert decided.mean() > 0.999

    # the interesting regimes are all present: ends above but dipping through, and feasible cases that the
    # Bernstein quick accept cannot prove (so the root cascade decides them)
    ends_above = (c[:, 0] > 0) & (d_end > 0)
    assert (ends_above & ~ok).sum() > 200
    e = c * T[:, None] ** np.arange(6)
    bern = np.column_stack(
        [
            e[:, 0] + e[:, 1] / 5,
            e[:, 0] + 2 * e[:, 1] / 5 + e[:, 2] / 10,
            e[:, 0] + 3 * e[:, 1] / 5 + 3 * e[:, 2] / 10 + e[:, 3] / 10,
            e[:, 0] + 4 * e[:, 1] / 5 + 3 * e[:, 2] / 5 + 2 * e[:, 3] / 5 + e[:, 4] / 5,
        ]
    )
    assert (ok & ~(bern > 0).all(axis=1)).sum() > 200
    assert ok.sum() > 2000
