"""Cosine-lobe core (seed 001): lobes, sample sets, weight solvers, basis search.

Truths used: closed forms (a target made of basis lobes, a Lambertian target, R·V in
plane = cos(θo − φ)), LP optimality (no non-negative solution has a lower L1, so neither
NNLS nor clamped least squares can beat it), agreement of two independent LP solvers.
"""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli import lobes as L
from gonio_cli.lobes.basis import select_basis
from gonio_cli.lobes.samples import sample_set, target_values
from gonio_cli.lobes.solve import fit_weight_table, fit_weights
from gonio_cli.lobes.solvers import WARM_SIMPLEX_MAX_SAMPLES, WEIGHT_SOLVERS, WeightSolver
from gonio_cli.errors import FitError, InputError
from gonio_cli.geometry import reflect
from gonio_cli.schemas import Material
from gonio_cli.synthetic import ink_spectra

WL = np.arange(380.0, 781.0, 10.0)

#: HiGHS's default primal feasibility tolerance is 1e-7 (absolute, on rows of size ~1);
#: an exact recovery through it is good to ~1e-7 relative, so 1e-6 is the test's margin.
HIGHS_TOL = 1e-6
#: The simplex solvers reach the same vertex to float64 round-off of ~20-100 pivots
#: (their bases are refactorised and certified, so round-off does not accumulate).
SIMPLEX_TOL = 1e-10
#: The LP solvers that must agree with HiGHS (the reference).
EXACT_LP = ("lp", "lp-simplex")


def gonio_material(ink="red", alpha=0.18):
    rho, c = ink_spectra(ink, WL)
    return Material("goniochromatic", WL, {"alpha": alpha, "rho": rho, "c": c})


def lambertian_material(albedo=0.6):
    z = np.zeros_like(WL)
    return Material("cook-torrance", WL, {"kd": np.full_like(WL, albedo), "ks": z,
                                          "m": np.full_like(WL, 0.3), "f0": z})


# ------------------------------------------------------------------------ the lobes --

def test_cosine_lobe_matches_power_and_clamps():
    c = np.array([1.0, 0.9, 0.5, 1e-3, 0.0, -0.3])
    e = np.array([1.0, 7.5, 100.0])
    got = L.cosine_lobe(c, e)
    want = np.maximum(c, 0.0)[:, None] ** e
    assert got.shape == (6, 3)
    np.testing.assert_allclose(got, want, rtol=1e-12, atol=0)
    assert np.all(got[-2:] == 0.0)          # R·V ≤ 0 gives exactly 0 (seed 001 §3.1)
    assert np.all(got[0] == 1.0)            # the peak is 1 for every exponent


def test_cosine_lobe_extreme_exponents_and_grazing_are_finite():
    c = np.array([1.0, 1.0 - 1e-16, np.cos(np.radians(1.0)), np.cos(np.radians(89.999)),
                  1e-300, 5e-324, 0.0])
    got = L.cosine_lobe(c, np.array([1e-3, 1.0, 1e4]))
    assert np.all(np.isfinite(got)) and np.all((got >= 0) & (got <= 1))
    # cos(1°)^1e4 = exp(1e4 log cos 1°) ≈ 0.218, the exp-log form keeps it exact
    assert got[2, 2] == pytest.approx(np.exp(1e4 * np.log(np.cos(np.radians(1.0)))), rel=1e-12)
    assert got[3, 2] == 0.0 and got[-1].tolist() == [0.0, 0.0, 0.0]
    assert np.isnan(L.cosine_lobe(np.array([np.nan]), np.array([2.0]))).all()


def test_cosine_lobe_broadcasts():
    c = np.array(0.8)
    e = np.array([2.0, 30.0])
    one = L.cosine_lobe(c, e)
    np.testing.assert_array_equal(L.cosine_lobe(np.full(6, 0.8), e), np.tile(one, (6, 1)))
    np.testing.assert_array_equal(L.cosine_lobe(np.full((2, 3), 0.8), e),
                                  np.tile(one, (2, 3, 1)))


def test_reflect_gives_in_plane_rv():
    s = sample_set("seed001", [0.0, 35.0, 70.0])
    np.testing.assert_allclose(s.cos_rv(), np.cos(np.radians(s.view_deg - s.light_deg)),
                               atol=1e-14)
    r = reflect(np.array([[-np.sin(0.3), 0.0, np.cos(0.3)]]))
    np.testing.assert_allclose(r, [[np.sin(0.3), 0.0, np.cos(0.3)]], atol=1e-15)


def test_design_matrix_columns():
    ci, rv = np.array([1.0, 0.5]), np.array([1.0, 0.8])
    M = L.design_matrix(ci, rv, [2.0, 4.0])
    np.testing.assert_allclose(M, [[1, 1, 1, 1, 1], [0.5, 0.5 * 0.64, 0.5 * 0.4096, 0.64, 0.4096]])


@pytest.mark.parametrize("bad", [[], [0.0], [-1.0, 10.0], [np.nan], [np.inf]])
def test_bad_exponents_are_refused(bad):
    with pytest.raises(InputError):
        L.check_exponents(bad)


# --------------------------------------------------------------------- sample sets --

def test_sample_sets():
    s = sample_set("seed001")
    assert 50 <= s.n_samples <= 70                          # seed 001 §4: a few dozen
    assert np.all(np.abs(s.light_deg) <= L.HORIZON_DEG)
    assert set(s.role) == {"diffuse", "directional", "mirror"}
    for k, tv in enumerate(s.view_angle_deg):                 # each view has its mirror
        rows = s.view_index == k
        assert np.any(s.light_deg[rows] == tv) and np.all(s.view_deg[rows] == tv)
    assert sample_set("dense", [40.0]).n_samples > 2 * sample_set("seed001", [40.0]).n_samples
    with pytest.raises(InputError, match="unknown"):
        sample_set("nope")
    with pytest.raises(InputError, match="outside"):
        sample_set("seed001", [90.0])


def test_sample_csv(tmp_path):
    p = tmp_path / "s.csv"
    p.write_text("theta_i_deg,theta_o_deg\n30,30\n20,30\n45,10\n89,10\n")
    s = sample_set(str(p))
    assert s.n_samples == 3 and s.view_angle_deg.tolist() == [10.0, 30.0]
    p.write_text("theta_i_deg,theta_o_deg\n89,10\n")
    with pytest.raises(InputError, match="nothing to fit"):
        sample_set(str(p))
    p.write_text("a,b\n1,2\n")
    with pytest.raises(InputError, match="header"):
        sample_set(str(p))


def test_sample_set_that_sees_no_lobe_is_refused(tmp_path):
    p = tmp_path / "retro.csv"          # light and detector on the same side: R·V < 0
    p.write_text("theta_i_deg,theta_o_deg\n60,-60\n50,-60\n70,-60\n")
    with pytest.raises(FitError, match="no sample sees"):
        fit_weight_table(gonio_material(), [5.0, 50.0], sample_set(str(p)), "xyz")


# ------------------------------------------------------------------- weight solvers --

def random_problems(n=120, seed=7):
    """(M, B) pairs from the real design matrix with random non-negative targets."""
    rng = np.random.default_rng(seed)
    s = sample_set("seed001")
    for _ in range(n):
        m = int(rng.integers(1, 9))
        e = np.sort(np.exp(rng.uniform(0.0, np.log(2e3), m)))
        M = L.design_matrix(s.cos_theta_i(), s.cos_rv(), e)
        kind = rng.integers(3)
        if kind == 0:           # arbitrary non-negative data
            B = rng.random((M.shape[0], 3)) * rng.uniform(0.01, 3.0)
        elif kind == 1:         # a lobe model plus noise
            B = np.abs(M @ rng.random((M.shape[1], 3)) + 0.05 * rng.standard_normal((M.shape[0], 3)))
        else:                   # a microfacet-like peak with a floor
            B = (0.05 + 2.0 * s.cos_rv()[:, None] ** rng.uniform(5, 500)) * rng.random(3)
        yield M, B


def test_weights_non_negative_and_lp_never_worse_than_clamped_lsq():
    for M, B in random_problems():
        fits = {name: fit_weights(M, B, name) for name in WEIGHT_SOLVERS}
        for r in fits.values():
            assert r.weights.shape == (M.shape[1], 3) and np.all(r.weights >= 0)
        lp = fits["highs"].l1
        # LP optimality: every other solver returns a feasible x ≥ 0, so its L1 ≥ the LP's
        # (up to HiGHS's 1e-7 feasibility tolerance, relative to the problem's scale).
        slack = HIGHS_TOL * (1.0 + np.abs(B).sum())
        assert lp <= fits["lsq-clamp"].l1 + slack
        assert lp <= fits["nnls"].l1 + slack
        for name in EXACT_LP:
            assert fits[name].status == "optimal", fits[name].message
            assert fits[name].l1 == pytest.approx(lp, rel=HIGHS_TOL, abs=slack)


def test_clamping_fails_as_seed_001_says():
    """Clamping negative least-squares weights can be far worse than the LP (seed 001 §4)."""
    worse = [fit_weights(M, B, "lsq-clamp").l1 / max(fit_weights(M, B, "highs").l1, 1e-12)
             for M, B in random_problems(30, seed=3)]
    assert max(worse) > 2.0


@pytest.mark.parametrize("solver,tol", [("highs", HIGHS_TOL), ("lp", SIMPLEX_TOL),
                                        ("lp-simplex", SIMPLEX_TOL), ("nnls", SIMPLEX_TOL)])
def test_exact_sum_of_lobes_is_recovered(solver, tol):
    s = sample_set("seed001")
    e = np.array([1.0, 10.0, 100.0, 1000.0])
    M = L.design_matrix(s.cos_theta_i(), s.cos_rv(), e)
    rng = np.random.default_rng(11)
    x = rng.random((M.shape[1], 3))
    x[rng.random(x.shape) < 0.4] = 0.0
    r = fit_weights(M, M @ x, solver)
    np.testing.assert_allclose(r.weights, x, atol=tol * x.max())
    assert r.rms_relative < tol


@pytest.mark.parametrize("solver", ["lp", "highs", "lp-simplex", "nnls"])
@pytest.mark.parametrize("channels", ["spectral", "xyz"])
def test_lambertian_puts_all_weight_on_kd(solver, channels):
    table = fit_weight_table(lambertian_material(0.6), [2.0, 20.0, 200.0],
                               sample_set("seed001", [0.0, 40.0, 80.0]), channels, solver)
    kd = table.diffuse
    want = 0.6 / np.pi if channels == "spectral" else None
    if want is not None:
        np.testing.assert_allclose(kd, want, rtol=HIGHS_TOL)
    else:   # XYZ of a flat 0.6/π: Y = 0.6/π exactly (the conventions' normalisation)
        np.testing.assert_allclose(kd[:, 1], 0.6 / np.pi, rtol=HIGHS_TOL)
    lobes = np.concatenate([table.directional_diffuse.ravel(), table.gloss.ravel()])
    assert np.all(lobes >= 0) and lobes.max() <= HIGHS_TOL * kd.max()
    assert max(table.errors[solver]["rms_relative"]) < HIGHS_TOL


def test_weight_table_of_an_ink():
    mat = gonio_material("green")
    s = sample_set("seed001", [0.0, 30.0, 60.0])
    t = fit_weight_table(mat, [2.0, 8.0, 30.0, 120.0], s, "spectral")
    assert t.diffuse.shape == (3, WL.size) and t.gloss.shape == (3, 4, WL.size)
    assert t.directional_diffuse.shape == (3, 4, WL.size)
    for arr in (t.diffuse, t.directional_diffuse, t.gloss):
        assert np.all(arr >= 0) and np.all(np.isfinite(arr))
    assert list(t.errors) == ["lp"]                         # comparisons only when asked
    assert t.errors["lp"]["status"] == ["optimal"] * 3
    assert max(t.errors["lp"]["rms_relative"]) < 0.1      # ~5 % on a rough (α 0.18) ink
    both = fit_weight_table(mat, [2.0, 8.0, 30.0, 120.0], s, "spectral",
                              compare=tuple(WEIGHT_SOLVERS))
    assert list(both.errors) == list(WEIGHT_SOLVERS)     # the written solver first
    # the same LP: the L1 of the default equals HiGHS's at every view, and it is exact
    np.testing.assert_allclose(both.errors["lp"]["l1"], both.errors["highs"]["l1"],
                               rtol=HIGHS_TOL)
    np.testing.assert_array_equal(both.gloss, t.gloss)


def test_warm_start_reuses_the_basis_across_channels():
    """The LP's solution scales with b (x(λb) = λ x(b), λ > 0), so channels that are
    multiples of the first are optimal in its basis: no pivot after the first channel,
    and the weights scale exactly."""
    from gonio_cli.lobes.simplex import lp_l1_warm

    M, B = next(random_problems(1, seed=2))
    b = B[:, :1]
    X, iterations, status = lp_l1_warm(M, b * np.array([[1.0, 2.0, 0.5, 7.0]]))
    assert status.tolist() == [0, 0, 0, 0]
    assert iterations[0] > 0 and iterations[1:].tolist() == [0, 0, 0]
    np.testing.assert_allclose(X, X[:, :1] * [1.0, 2.0, 0.5, 7.0], rtol=1e-12, atol=1e-15)
    assert fit_weights(M, b, "lp").l1 == pytest.approx(fit_weights(M, b, "highs").l1,
                                                          rel=HIGHS_TOL)


@pytest.mark.parametrize("solver", ["lp", "highs", "lp-simplex"])
def test_time_limit_is_a_status_not_an_error(solver):
    rng = np.random.default_rng(0)
    M, B = rng.random((60, 17)), rng.random((60, 41))
    r = fit_weights(M, B, solver, time_limit_s=1e-9)
    assert r.status == "time_limit" and not r.success
    assert "time limit" in r.message
    assert r.weights.shape == (17, 41) and np.all(r.weights >= 0)
    # x ≥ 0 is feasible, so the L1 is at most that of x = 0 (the residual start)
    assert r.l1 <= np.abs(B).sum() * (1 + 1e-12)


def test_time_limit_in_a_table_is_recorded_per_view():
    """The chosen solver and a comparison stopped by the time limit: the table is still
    made, each view's status says so (what ``gonio lobes fit`` writes)."""
    mat = gonio_material("green")
    s = sample_set("seed001", [0.0, 40.0])
    t = fit_weight_table(mat, [2.0, 30.0], s, "spectral", "lp", compare=("highs",),
                           time_limit_s=1e-9)
    assert t.errors["lp"]["status"] == ["time_limit"] * 2
    assert t.errors["highs"]["status"] == ["time_limit"] * 2
    assert np.all(t.diffuse >= 0)


def test_a_failed_comparison_is_a_note_and_a_failed_choice_an_error(monkeypatch):
    def broken(M, B, time_limit_s):
        return np.zeros((M.shape[1], B.shape[1])), "failed", "no solution (test)"

    monkeypatch.setitem(WEIGHT_SOLVERS, "highs", WeightSolver(broken, "broken"))
    mat = gonio_material("green")
    s = sample_set("seed001", [40.0])
    t = fit_weight_table(mat, [2.0, 30.0], s, "spectral", "lp", compare=("highs",))
    assert t.errors["highs"]["status"] == ["failed"]
    assert t.errors["highs"]["message"] == ["no solution (test)"]
    assert t.errors["lp"]["status"] == ["optimal"]
    with pytest.raises(FitError, match="highs weight solver failed"):
        fit_weight_table(mat, [2.0, 30.0], s, "spectral", "highs")


def test_non_finite_target_is_refused():
    M = np.ones((3, 2))
    with pytest.raises(FitError, match="NaN"):
        fit_weights(M, np.array([[1.0], [np.nan], [0.0]]))


# -------------------------------------------------------------------- basis search --

def test_basis_error_never_rises_with_lobe_count():
    s = sample_set("seed001")
    mats = [gonio_material("red"), gonio_material("blue", 0.08), lambertian_material(0.3),
            Material("torrance-sparrow", WL, {"alpha": 0.3, "f0": np.full_like(WL, 0.04)})]
    targets = [target_values(m, s, "xyz")[0] for m in mats]
    result = select_basis(targets, s, max_lobes=4)
    errors = [step.error for step in result.steps]
    assert [step.n_lobes for step in result.steps] == [1, 2, 3, 4]
    # nnls's residual cannot grow when a column is added and each search starts from the
    # previous lobes, so the sequence is non-increasing up to nnls's round-off (~1e-12).
    assert all(b <= a + 1e-9 for a, b in zip(errors, errors[1:]))
    # a real gain, not a flat line: one lobe cannot hold both a rough and a glossy
    # material; four take the error from 0.39 to 0.21 (the Torrance-Sparrow max remains)
    assert errors[-1] < 0.75 * errors[0]
    for step in result.steps:
        assert np.all(np.diff(step.exponents) >= 0)
        assert np.all((step.exponents >= L.EXPONENT_MIN) & (step.exponents <= L.EXPONENT_MAX))
        assert step.error == pytest.approx(step.max_error + step.mean_error)


def test_basis_bad_options():
    s = sample_set("seed001")
    with pytest.raises(InputError):
        select_basis([], s)
    with pytest.raises(InputError):
        select_basis([np.ones((s.n_samples, 3))], s, max_lobes=0)
    with pytest.raises(InputError):
        select_basis([np.ones((s.n_samples, 3))], s, solver="lsq-clamp")


@pytest.mark.parametrize("solver", EXACT_LP)
def test_simplex_falls_back_to_highs_at_its_iteration_cap(monkeypatch, solver):
    from gonio_cli.lobes import simplex

    M, B = next(random_problems(1, seed=5))
    want = fit_weights(M, B, "highs")
    monkeypatch.setattr(simplex, "MAX_ITER_PER_VARIABLE", 0)   # every channel stops at once
    got = fit_weights(M, B, solver)
    assert "3 channels re-solved by HiGHS" in got.message and got.status == "optimal"
    assert got.l1 == pytest.approx(want.l1, rel=HIGHS_TOL)


class _StoppingOpt:
    """Stands in for nlopt.opt: evaluates the objective once at x0, then raises."""

    error: type = RuntimeError

    def __init__(self, algorithm, n):
        self.f = None

    def set_min_objective(self, f):
        self.f = f

    def optimize(self, x0):
        self.f(np.asarray(x0), None)
        raise self.error("stop (test)")

    def __getattr__(self, name):             # set_lower_bounds, set_xtol_abs, ...
        return lambda *args: None


def test_basis_search_keeps_the_best_point_only_on_roundoff(monkeypatch):
    import nlopt

    s = sample_set("seed001")
    targets = [target_values(gonio_material("red"), s, "xyz")[0]]

    class Roundoff(_StoppingOpt):
        error = nlopt.RoundoffLimited

    monkeypatch.setattr(nlopt, "opt", Roundoff)
    result = select_basis(targets, s, max_lobes=1)
    assert "round-off" in result.steps[0].message and np.isfinite(result.steps[0].error)
    # any other exception (a bug, a bad argument, a forced stop) surfaces
    monkeypatch.setattr(nlopt, "opt", _StoppingOpt)
    with pytest.raises(RuntimeError, match="stop \\(test\\)"):
        select_basis(targets, s, max_lobes=1)


def test_hemisphere_sample_set_covers_the_half_hemisphere_evenly():
    # 200 lights per view, all above the 85° horizon, on the y ≥ 0 half (an isotropic BRDF
    # repeats itself in the other half); uniform in solid angle: mean cos θi of a uniform
    # density on the cap up to 85° is (1 + cos 85°)/2.
    s = sample_set("hemisphere", [0.0, 40.0])
    assert s.n_samples == 2 * L.HEMISPHERE_POINTS
    wi, wo = s.directions()
    np.testing.assert_allclose(np.linalg.norm(wi, axis=1), 1.0, atol=1e-12)
    assert np.all(wi[:, 1] >= 0) and np.all(wi[:, 2] >= np.cos(np.radians(L.HORIZON_DEG)) - 1e-12)
    assert s.cos_theta_i().mean() == pytest.approx((1 + np.cos(np.radians(85.0))) / 2, abs=2e-3)
    np.testing.assert_allclose(wo[s.view_index == 1], [[np.sin(np.radians(40)), 0,
                                                        np.cos(np.radians(40))]] * 200)
    assert s.view(1).directions()[0].shape == (200, 3)


def test_lp_hands_large_sample_sets_to_highs():
    s = sample_set("hemisphere", [40.0])
    M = L.design_matrix(s.cos_theta_i(), s.cos_rv(), [3.0, 30.0])
    B = target_values(gonio_material("green"), s, "xyz")[0]
    assert M.shape[0] > WARM_SIMPLEX_MAX_SAMPLES
    r = fit_weights(M, B, "lp")
    assert r.status == "optimal" and "by HiGHS" in r.message
    assert r.l1 == pytest.approx(fit_weights(M, B, "highs").l1, rel=1e-12)
